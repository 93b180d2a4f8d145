//! One height layer's ICP map: keyframe scans in the world frame, matched by point-to-line ICP
//! with a correlative-search fallback, as [`crate::icp_slam`] does, but with the layered
//! mapper's safeguards between the match and the map: a match is kept only along the
//! directions the scan constrains ([`super::degeneracy`]) and only within a gate around the
//! motion prior, and a keyframe is inserted at that corrected pose. (Inside an [`IcpSlam`] the
//! keyframe would go in at the raw match, so a scan that slid along a wall would shift the map.)
//!
//! [`IcpSlam`]: crate::icp_slam::IcpSlam

use crate::correlative::correlative_match;
use crate::icp::{align, IcpConfig, IcpResult};
use crate::icp_slam::{IcpSlamConfig, ScanStatus};
use crate::point_map::{Keyframe, KeyframeMap};
use nalgebra::{Point2, Vector2};
use slamkit_core::Pose2;

/// A scan prepared for matching: base-frame points and normals.
pub struct PreparedScan {
    /// Beam end points in the base frame \[m\].
    pub points: Vec<Point2<f64>>,
    /// Unit normal of each point, where the scan shows a line.
    pub normals: Vec<Option<Vector2<f64>>>,
}

/// The raw outcome of matching a scan against a layer's map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawMatch {
    /// The matched pose (`None`: no alignment reached the minimum goodness).
    pub world_from_base: Option<Pose2>,
    /// How it was found.
    pub status: ScanStatus,
}

/// A layer's keyframe map.
pub struct LayerIcpMap {
    map: KeyframeMap,
    last_keyframe: Option<Pose2>,
    failures: usize,
    scans: usize,
    created_s: f64,
    /// Takes no new keyframe (a saved map localised in).
    frozen: bool,
}

impl LayerIcpMap {
    /// An empty layer map, created at time `created_s` \[s\].
    pub fn new(config: &IcpSlamConfig, created_s: f64) -> Self {
        Self {
            map: KeyframeMap::new(config.map_voxel_m, config.map_keyframes),
            last_keyframe: None,
            failures: 0,
            scans: 0,
            created_s,
            frozen: false,
        }
    }

    /// Adds a keyframe of a saved map as it is.
    pub fn load(&mut self, keyframe: Keyframe) {
        self.last_keyframe = Some(keyframe.world_from_base);
        self.map.insert(keyframe);
    }

    /// From now on the map takes no new keyframe: scans are matched against it only.
    pub fn freeze(&mut self) {
        self.frozen = true;
    }

    /// When the map was created \[s\].
    pub fn created_s(&self) -> f64 {
        self.created_s
    }

    /// The point map.
    pub fn map(&self) -> &KeyframeMap {
        &self.map
    }

    /// Scans matched or inserted in this layer.
    pub fn scans(&self) -> usize {
        self.scans
    }

    /// Aligns `scan` to the map from `guess`: ICP, then a correlative search and ICP again when
    /// ICP's goodness is below `min_goodness`.
    pub fn match_scan(&self, scan: &PreparedScan, guess: &Pose2, c: &IcpSlamConfig) -> RawMatch {
        if self.map.is_empty() {
            return RawMatch {
                world_from_base: None,
                status: ScanStatus::Initialised,
            };
        }
        if scan.points.len() < c.min_scan_points {
            return RawMatch {
                world_from_base: None,
                status: ScanStatus::Skipped,
            };
        }
        let good = |from: &Pose2| {
            self.refine(scan, from, &c.icp)
                .filter(|r| r.goodness >= c.min_goodness)
                .map(|r| r.target_from_source)
        };
        if let Some(pose) = good(guess) {
            return RawMatch {
                world_from_base: Some(pose),
                status: ScanStatus::Matched,
            };
        }
        let recovered = c
            .correlative_fallback
            .then(|| correlative_match(&scan.points, self.map.points(), guess, &c.correlative))
            .and_then(Result::ok)
            .and_then(|coarse| good(&coarse.target_from_source));
        RawMatch {
            world_from_base: recovered,
            status: match recovered {
                Some(_) => ScanStatus::MatchedCorrelative,
                None => ScanStatus::MatchFailed,
            },
        }
    }

    /// ICP alone from `guess`, without the correlative fallback: the alignment with its
    /// goodness, `None` on an empty map or when ICP fails.
    pub fn refine(&self, scan: &PreparedScan, guess: &Pose2, icp: &IcpConfig) -> Option<IcpResult> {
        if self.map.is_empty() {
            return None;
        }
        align(&scan.points, self.map.index(), guess, icp).ok()
    }

    /// Moves the keyframes to new poses: `pose_of(i)` is the new pose of the `i`-th keyframe
    /// inserted, or `None` to keep it.
    pub fn relocate(&mut self, pose_of: impl Fn(usize) -> Option<Pose2>) {
        let last = self.map.keyframes_inserted().checked_sub(1);
        if let Some(pose) = last.and_then(&pose_of) {
            self.last_keyframe = Some(pose);
        }
        self.map.relocate(pose_of);
    }

    /// Records the final pose of a scan given to this layer (`accepted`: fixed by the map, not
    /// only predicted) and inserts the scan as a keyframe when the layer is empty, or the drone
    /// moved or turned far enough since the last keyframe and the pose was accepted (or the
    /// layer failed to match `max_failures_before_insert` scans in a row, so that the map
    /// follows the drone into new ground), unless the map is frozen. Returns true when
    /// inserted.
    pub fn record(
        &mut self,
        scan: &PreparedScan,
        pose: &Pose2,
        accepted: bool,
        c: &IcpSlamConfig,
    ) -> bool {
        self.scans += 1;
        self.failures = if accepted { 0 } else { self.failures + 1 };
        let moved = self.last_keyframe.map_or(true, |kf| {
            let d = kf.inverse() * pose;
            d.translation.vector.norm() >= c.insertion_linear_m
                || d.rotation.angle().abs() >= c.insertion_angular_rad
        });
        let stale = self.failures >= c.max_failures_before_insert.max(1);
        let insert = !self.frozen
            && (self.map.is_empty() || (moved && (accepted || stale)))
            && scan.points.len() >= c.min_scan_points;
        if insert {
            self.map.insert(Keyframe {
                world_from_base: *pose,
                points: scan.points.clone(),
                normals: scan.normals.clone(),
            });
            self.last_keyframe = Some(*pose);
            self.failures = 0;
        }
        insert
    }
}
