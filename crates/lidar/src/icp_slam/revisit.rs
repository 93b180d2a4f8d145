//! Keeping ICP-SLAM's map bounded on ground already mapped: a scan due to become a keyframe
//! that lies within the insertion distance and angle of an existing keyframe (so that keyframe
//! already stands for its view) is matched against that keyframe's neighbourhood; when the
//! match agrees with the tracked pose to `max_correction_m` / `max_correction_rad`, the scan is
//! localised against the keyframe instead of added. The keyframe then anchors the scans that
//! follow and the next new keyframe's chain edge, and joins the local map, so a robot driving
//! the same corridors for an hour tracks against the keyframes of its first pass and the map
//! stops growing. A larger disagreement is drift: the scan becomes a keyframe and loop closure
//! corrects it, as before. This is the rule the visual SLAM uses (issue 20,
//! `cull_redundant_keyframes`): a redundant keyframe is never made, so nothing has to be
//! removed from the pose graph.

use crate::cloud::voxel_downsample;
use crate::error::check_fields;
use crate::icp::{align, IcpConfig};
use crate::point_map::{index_keyframes, Keyframe};
use crate::LidarError;
use nalgebra::Point2;
use serde::{Deserialize, Serialize};
use slamkit_core::Pose2;

/// Settings of localisation on ground already mapped.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RevisitConfig {
    /// Localise against an existing keyframe instead of adding one nearby.
    pub enabled: bool,
    /// The match against the keyframe's neighbourhood may move the tracked pose this far
    /// \[m\]...
    pub max_correction_m: f64,
    /// ...and turn it this much \[rad\]; more is drift for loop closure.
    pub max_correction_rad: f64,
    /// The keyframe's neighbourhood: this many keyframes on each side of it.
    pub submap_half_keyframes: usize,
    /// Lowest ICP goodness of the match, in \[0, 1\].
    pub min_goodness: f64,
}

impl Default for RevisitConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            // Relations error of `slamkit lidar LOG --method icp`, Intel / ACES / MIT CSAIL:
            // 0.0156 / 0.0387 / 0.0278 m without this rule; 0.0162 / 0.0379 / 0.0274 m at
            // 5 cm / 2°; 0.0158 / 0.0383 / 0.0274 m at 3 cm / 1° (docs/experiments/lidar-memory.md).
            max_correction_m: 0.03,
            max_correction_rad: 1f64.to_radians(),
            submap_half_keyframes: 10,
            min_goodness: 0.8,
        }
    }
}

impl RevisitConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), LidarError> {
        let checks = [
            (
                "revisit.max_correction_m",
                self.max_correction_m,
                self.max_correction_m >= 0.0,
            ),
            (
                "revisit.max_correction_rad",
                self.max_correction_rad,
                self.max_correction_rad >= 0.0,
            ),
            (
                "revisit.min_goodness",
                self.min_goodness,
                (0.0..=1.0).contains(&self.min_goodness),
            ),
        ];
        check_fields(checks, "out of range")
    }
}

/// A scan localised against an existing keyframe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Revisit {
    /// The keyframe.
    pub keyframe: usize,
    /// The scan's pose from the match \[world\].
    pub world_from_base: Pose2,
}

/// Where the keyframes are spaced and how the match runs: ICP-SLAM's insertion distance and
/// angle, map voxel, scan voxel and ICP settings.
pub struct Spacing<'a> {
    /// Keyframes are this far apart \[m\]...
    pub linear_m: f64,
    /// ...or turned this much \[rad\].
    pub angular_rad: f64,
    /// Voxel of the matched neighbourhood \[m\].
    pub map_voxel_m: f64,
    /// Voxel the scan is thinned to \[m\].
    pub scan_voxel_m: f64,
    /// The match.
    pub icp: &'a IcpConfig,
}

/// The keyframe of `keyframes` nearest to a scan at `pose` (`points` in the base frame, due
/// to become a keyframe) within the keyframe spacing, when the scan matches the keyframe's
/// neighbourhood within `config`'s goodness and correction; `None` otherwise.
pub fn localise_in_map(
    keyframes: &[Keyframe],
    points: &[Point2<f64>],
    pose: &Pose2,
    spacing: &Spacing,
    config: &RevisitConfig,
) -> Option<Revisit> {
    if !config.enabled || spacing.linear_m <= 0.0 || spacing.angular_rad <= 0.0 {
        return None;
    }
    let closeness = |step: &Pose2| {
        step.translation.vector.norm() / spacing.linear_m
            + step.rotation.angle().abs() / spacing.angular_rad
    };
    let (keyframe, _) = keyframes
        .iter()
        .enumerate()
        .map(|(i, kf)| (i, kf.world_from_base.inverse() * pose))
        .filter(|(_, step)| {
            step.translation.vector.norm() < spacing.linear_m
                && step.rotation.angle().abs() < spacing.angular_rad
        })
        .min_by(|a, b| closeness(&a.1).total_cmp(&closeness(&b.1)))?;
    let first = keyframe.saturating_sub(config.submap_half_keyframes);
    let last = (keyframe + config.submap_half_keyframes + 1).min(keyframes.len());
    let submap = index_keyframes(keyframes.get(first..last)?, spacing.map_voxel_m);
    let source = voxel_downsample(points, spacing.scan_voxel_m);
    let fit = align(&source, &submap, pose, spacing.icp).ok()?;
    let correction = pose.inverse() * fit.target_from_source;
    (fit.goodness >= config.min_goodness
        && correction.translation.vector.norm() <= config.max_correction_m
        && correction.rotation.angle().abs() <= config.max_correction_rad)
        .then_some(Revisit {
            keyframe,
            world_from_base: fit.target_from_source,
        })
}
