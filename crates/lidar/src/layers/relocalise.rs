//! Re-localisation on old maps: a loop closure for the layered mapper.
//!
//! The drone climbs or descends on most legs of a flight, so it keeps entering layers it has
//! not mapped, or mapped long ago elsewhere; every new layer map starts from the pose the
//! mapper holds, and drift (mostly heading, a few hundredths of a radian) gathers along that
//! chain of maps. The gate that keeps a slid match out of the pose (a few centimetres around
//! the motion prior) also keeps the old maps from pulling the pose back once the drift is
//! larger than it. Here, each time a keyframe goes in, the scan is searched against the old
//! keyframes (older than `min_age_s`, of layers within `max_height_gap_m`) near its pose with a
//! wide correlative window (Olson, "Real-time correlative scan matching", ICRA 2009) refined by
//! point-to-line ICP, as ICP-SLAM's loop closure ([`crate::icp_slam::loop_closure`]) does, and a
//! clearly good match (correlative score, ICP goodness, a turn within what the gyro can have
//! drifted), kept only along the directions the scan constrains ([`super::degeneracy`]), moves
//! the pose however far it is.
//!
//! The correction is spread, as a pose graph whose drift grew evenly in time would spread it:
//! every keyframe inserted since the anchor (the newest old keyframe matched, or the last
//! re-localisation if later) moves by the share of the correction its time gives it, turning
//! about the current position, so the maps built during the drift line up with the old ones.

use super::degeneracy::remap;
use super::layer_map::PreparedScan;
use crate::cloud::voxel_downsample;
use crate::correlative::{correlative_match, CorrelativeConfig};
use crate::error::check_fields;
use crate::icp::{align, IcpConfig};
use crate::nn::{GridIndex, NearestNeighbours};
use crate::point_map::{index_keyframes, Keyframe};
use crate::LidarError;
use nalgebra::{Matrix3, Point2, Vector2};
use serde::{Deserialize, Serialize};
use slamkit_core::Pose2;

/// Re-localisation parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RelocaliseConfig {
    /// Search old maps at all.
    pub enabled: bool,
    /// Keyframes at least this old are "old" \[s\].
    pub min_age_s: f64,
    /// Old keyframes of layers at most this far above or below the current one are searched
    /// (0: the current layer only) \[m\].
    pub max_height_gap_m: f64,
    /// Old keyframes within this distance of the pose are searched \[m\].
    pub search_radius_m: f64,
    /// The submap holds at most this many old keyframes, oldest first.
    pub max_keyframes: usize,
    /// Voxel for thinning the scan before the correlative search \[m\].
    pub search_voxel_m: f64,
    /// Window of the correlative search around the pose.
    pub correlative: CorrelativeConfig,
    /// Lowest correlative score (mean likelihood) of a match, in \[0, 1\].
    pub min_score: f64,
    /// Fine alignment.
    pub icp: IcpConfig,
    /// Lowest ICP goodness (fraction of scan points on the map) of a match, in \[0, 1\].
    pub min_goodness: f64,
    /// The correction is kept along directions in which the scan's information matrix has at
    /// least this eigenvalue; a scan whose strongest direction is below it is not used
    /// (`office` seeds 1–20 at commit 5efc158, ICP median of the mean errors: 0.175 m at 20,
    /// 0.190 m at 10; 0.207 m with re-localisation off).
    pub min_constraint: f64,
    /// A scan point is on the old map when it is within this distance of a map point \[m\].
    pub overlap_distance_m: f64,
    /// The corrected pose must put at least this much more of the scan on the old map than the
    /// pose had (a match that is as good where the pose was is an ambiguous view, a row of
    /// boxes), as a fraction of the scan's points.
    pub min_gain: f64,
    /// Corrections that turn the pose by more than this are false matches (the heading drifts by
    /// hundredths of a radian: the gyro's turn is the prior) \[rad\].
    pub max_turn_rad: f64,
    /// Corrections that move the pose by more than this, plus `max_drift_mps` for every second
    /// since the newest old keyframe matched, are false matches (a row of desks, a corridor of
    /// shelves: the same view a desk further on) \[m\].
    pub max_shift_m: f64,
    /// Growth of that bound with time: the fastest drift expected \[m/s\].
    pub max_drift_mps: f64,
    /// Corrections smaller than this (translation \[m\], and heading / 10 \[rad\]) are left to
    /// the ordinary matching.
    pub min_correction_m: f64,
}

impl Default for RelocaliseConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            min_age_s: 30.0,
            max_height_gap_m: 3.0,
            search_radius_m: 3.0,
            max_keyframes: 20,
            search_voxel_m: 0.05,
            correlative: CorrelativeConfig {
                linear_window_m: 1.0,
                angular_window_rad: 0.15,
                resolution_m: 0.05,
                sigma_m: 0.05,
                ..CorrelativeConfig::default()
            },
            min_score: 0.5,
            icp: IcpConfig::default(),
            min_goodness: 0.8,
            min_constraint: 20.0,
            overlap_distance_m: 0.05,
            min_gain: 0.1,
            max_turn_rad: 0.1,
            max_shift_m: 0.1,
            max_drift_mps: 0.01,
            min_correction_m: 0.03,
        }
    }
}

impl RelocaliseConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), LidarError> {
        self.icp.validate()?;
        let unit = |v: f64| (0.0..=1.0).contains(&v);
        let non_negative = [
            ("min_age_s", self.min_age_s),
            ("max_height_gap_m", self.max_height_gap_m),
            ("search_radius_m", self.search_radius_m),
            ("search_voxel_m", self.search_voxel_m),
            ("min_constraint", self.min_constraint),
            ("max_turn_rad", self.max_turn_rad),
            ("max_shift_m", self.max_shift_m),
            ("max_drift_mps", self.max_drift_mps),
            ("min_correction_m", self.min_correction_m),
        ]
        .map(|(field, value)| (field, value, value >= 0.0));
        let bounded = [
            ("min_score", self.min_score, unit(self.min_score)),
            ("min_goodness", self.min_goodness, unit(self.min_goodness)),
            ("min_gain", self.min_gain, unit(self.min_gain)),
            (
                "overlap_distance_m",
                self.overlap_distance_m,
                self.overlap_distance_m > 0.0,
            ),
        ];
        check_fields(non_negative.into_iter().chain(bounded), "out of range")
    }
}

/// A keyframe of some layer, with its time.
#[derive(Debug, Clone, PartialEq)]
pub struct LoggedKeyframe {
    /// Layer the keyframe belongs to.
    pub layer: i64,
    /// Its index among the keyframes of that layer (insertion order).
    pub index: usize,
    /// Time of its scan \[s\].
    pub time_s: f64,
    /// The keyframe (pose in the world frame).
    pub keyframe: Keyframe,
}

/// The scan being re-localised.
pub struct Query<'a> {
    /// The scan's points and normals.
    pub scan: &'a PreparedScan,
    /// The scan's information matrix ([`super::degeneracy::scan_information`]).
    pub information: &'a Matrix3<f64>,
    /// The mapper's pose of the scan.
    pub pose: Pose2,
    /// The scan's layer.
    pub layer: i64,
    /// Layer thickness \[m\].
    pub layer_height_m: f64,
    /// Time of the scan \[s\].
    pub time_s: f64,
}

/// An accepted re-localisation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relocalisation {
    /// The corrected pose of the scan.
    pub world_from_base: Pose2,
    /// Time of the newest old keyframe matched \[s\].
    pub anchor_s: f64,
}

/// Matches the query scan against the old keyframes of `log` near it; `Some` when the match is
/// clearly good and moves the pose by at least `min_correction_m`.
pub fn relocalise(
    log: &[LoggedKeyframe],
    query: &Query,
    config: &RelocaliseConfig,
) -> Option<Relocalisation> {
    if query.information.symmetric_eigen().eigenvalues.max() < config.min_constraint {
        return None;
    }
    let old = old_keyframes(log, query, config);
    let anchor_s = old
        .iter()
        .map(|k| k.time_s)
        .fold(f64::NEG_INFINITY, f64::max);
    let keyframes: Vec<Keyframe> = old.iter().map(|k| k.keyframe.clone()).collect();
    let target: Vec<Point2<f64>> = keyframes
        .iter()
        .flat_map(|k| k.points.iter().map(|p| k.world_from_base * p))
        .collect();
    if target.is_empty() {
        return None;
    }
    let source = voxel_downsample(&query.scan.points, config.search_voxel_m);
    let coarse = correlative_match(&source, &target, &query.pose, &config.correlative)
        .ok()
        .filter(|c| c.score >= config.min_score)?;
    let index = index_keyframes(&keyframes, config.search_voxel_m.max(0.01));
    let fine = align(
        &query.scan.points,
        &index,
        &coarse.target_from_source,
        &config.icp,
    )
    .ok()
    .filter(|r| r.goodness >= config.min_goodness)?;
    let kept = remap(
        &query.pose,
        &fine.target_from_source,
        query.information,
        config.min_constraint,
    );
    plausible(query, &kept, &index, anchor_s, config).then_some(Relocalisation {
        world_from_base: kept,
        anchor_s,
    })
}

/// The old keyframes to match against: at least `min_age_s` old, of layers within
/// `max_height_gap_m`, within `search_radius_m`; the oldest `max_keyframes` of them (the oldest
/// maps hold the least drift).
fn old_keyframes<'a>(
    log: &'a [LoggedKeyframe],
    query: &Query,
    config: &RelocaliseConfig,
) -> Vec<&'a LoggedKeyframe> {
    let here = query.pose.translation.vector;
    let mut old: Vec<&LoggedKeyframe> = log
        .iter()
        .filter(|k| {
            let gap = (k.layer - query.layer).abs() as f64 * query.layer_height_m;
            let distance = (k.keyframe.world_from_base.translation.vector - here).norm();
            k.time_s <= query.time_s - config.min_age_s
                && gap <= config.max_height_gap_m + 1e-9
                && distance <= config.search_radius_m
        })
        .collect();
    old.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    old.truncate(config.max_keyframes);
    old
}

/// True when moving the query's pose to `corrected` puts `min_gain` more of the scan on the
/// old map (`index`), turns it by at most `max_turn_rad`, shifts it by no more than the drift
/// since `anchor_s` allows, and by at least `min_correction_m`.
fn plausible(
    query: &Query,
    corrected: &Pose2,
    index: &GridIndex,
    anchor_s: f64,
    config: &RelocaliseConfig,
) -> bool {
    let on_map = |pose: &Pose2| overlap(&query.scan.points, index, pose, config.overlap_distance_m);
    let d = query.pose.inverse() * corrected;
    let (shift, turn) = (d.translation.vector.norm(), d.rotation.angle().abs());
    let max_shift_m = config.max_shift_m + config.max_drift_mps * (query.time_s - anchor_s);
    on_map(corrected) - on_map(&query.pose) >= config.min_gain
        && turn <= config.max_turn_rad
        && shift <= max_shift_m
        && shift.max(turn * 10.0) >= config.min_correction_m
}

/// The fraction of `points` (base frame) that lie within `distance_m` of a point of `map` when
/// the base is at `pose`.
fn overlap(points: &[Point2<f64>], map: &GridIndex, pose: &Pose2, distance_m: f64) -> f64 {
    let near = points
        .iter()
        .filter(|p| map.nearest_within(&(pose * *p), distance_m).is_some())
        .count();
    near as f64 / points.len().max(1) as f64
}

/// The world-frame correction (new pose = correction · old pose) that takes `from` to `to`,
/// in part: `fraction` of its turn, about `from`'s position, and of its shift.
pub fn partial_correction(from: &Pose2, to: &Pose2, fraction: f64) -> Pose2 {
    let p = from.translation.vector;
    let turn = (to.rotation * from.rotation.inverse()).angle();
    let shift = to.translation.vector - p;
    Pose2::new(p + shift * fraction, 0.0)
        * Pose2::new(Vector2::zeros(), turn * fraction)
        * Pose2::new(-p, 0.0)
}

/// The share of a correction made at `now_s` that a pose of time `t_s` takes when the drift
/// grew evenly from `anchor_s`: 0 at the anchor and before, 1 at `now_s`.
pub fn share(t_s: f64, anchor_s: f64, now_s: f64) -> f64 {
    if now_s <= anchor_s {
        return 1.0;
    }
    ((t_s - anchor_s) / (now_s - anchor_s)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::super::degeneracy::scan_information;
    use super::*;
    use crate::cloud::{estimate_normals, scan_points};
    use crate::sim_scan::SegmentWorld;

    fn prepared(world: &SegmentWorld, pose: &Pose2) -> PreparedScan {
        let scan = world.scan(pose, 360, 1.5 * std::f64::consts::PI, 6.0);
        let points = scan_points(&scan, 0.1, 6.0);
        let normals = estimate_normals(&points, 8, 0.3, 0.3);
        PreparedScan { points, normals }
    }

    #[test]
    fn a_drifted_pose_is_moved_onto_the_old_map_a_plausible_distance_only() {
        let world = SegmentWorld::room();
        // the old map: keyframes along a pass at t = 0..5 s
        let log: Vec<LoggedKeyframe> = (0..6)
            .map(|k| {
                let pose = Pose2::new(Vector2::new(-2.0 + 0.5 * f64::from(k), -1.5), 0.1);
                let scan = prepared(&world, &pose);
                LoggedKeyframe {
                    layer: 10,
                    index: k as usize,
                    time_s: f64::from(k),
                    keyframe: Keyframe {
                        world_from_base: pose,
                        points: scan.points,
                        normals: scan.normals,
                    },
                }
            })
            .collect();
        // back 95 s later, a layer above, 0.4 m and 0.04 rad off
        let truth = Pose2::new(Vector2::new(-0.8, -1.2), 0.5);
        let scan = prepared(&world, &truth);
        let information = scan_information(&scan.points, &scan.normals);
        let drifted = truth * Pose2::new(Vector2::new(0.3, -0.25), 0.04);
        let query = |pose: Pose2, time_s: f64, layer: i64| Query {
            scan: &scan,
            information: &information,
            pose,
            layer,
            layer_height_m: 0.05,
            time_s,
        };
        let config = RelocaliseConfig::default();
        let found = relocalise(&log, &query(drifted, 100.0, 12), &config).unwrap();
        let error = truth.inverse() * found.world_from_base;
        assert!(error.translation.vector.norm() < 0.02, "{error}");
        assert!(error.rotation.angle().abs() < 0.005, "{error}");
        assert_eq!(found.anchor_s, 5.0);
        // the right pose needs no correction
        assert!(relocalise(&log, &query(truth, 100.0, 12), &config).is_none());
        // 0.4 m off 10 s after the old pass is more than the drift allows: a false match
        assert!(relocalise(&log, &query(drifted, 15.0, 12), &config).is_none());
        // too recent to be old, or too far above
        assert!(relocalise(&log, &query(drifted, 20.0, 12), &config).is_none());
        let high = (config.max_height_gap_m / 0.05) as i64 + 11;
        assert!(relocalise(&log, &query(drifted, 100.0, high), &config).is_none());
    }

    #[test]
    fn a_partial_correction_turns_about_the_current_position() {
        let from = Pose2::new(Vector2::new(2.0, 1.0), 0.3);
        let to = Pose2::new(Vector2::new(2.4, 0.7), 0.25);
        let full = partial_correction(&from, &to, 1.0) * from;
        assert!((full.translation.vector - to.translation.vector).norm() < 1e-12);
        assert!((full.rotation.angle() - to.rotation.angle()).abs() < 1e-12);
        // nothing at share 0; half the turn and shift at 0.5
        let none = partial_correction(&from, &to, 0.0) * from;
        assert!((none.translation.vector - from.translation.vector).norm() < 1e-12);
        let half = partial_correction(&from, &to, 0.5) * from;
        assert!((half.translation.vector - Vector2::new(2.2, 0.85)).norm() < 1e-12);
        assert!((half.rotation.angle() - 0.275).abs() < 1e-12);
        assert_eq!(share(5.0, 10.0, 20.0), 0.0);
        assert_eq!(share(15.0, 10.0, 20.0), 0.5);
        assert_eq!(share(25.0, 10.0, 20.0), 1.0);
    }
}
