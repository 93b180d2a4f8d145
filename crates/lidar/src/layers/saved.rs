//! Starting the layered mapper in the layers of a saved map, once the drone has been found in
//! it: to localise (the saved layers take no new keyframe; a layer the map lacks is mapped as
//! usual, so the drone keeps a map where it flies outside the saved one) or to continue it
//! (every layer takes keyframes).
//!
//! The saved keyframes are never moved: they are the reference the new ones are corrected
//! against ([`mod@super::relocalise`] spreads its corrections over the keyframes of this run only).
//! Their times are moved onto this run's clock, to end `min_age_s` before the start (plus a
//! second), so that re-localisation and the reference layers take them as old maps at once and
//! a recording whose clock restarted at zero works as one stamped with wall time.

use super::layer_map::LayerIcpMap;
use super::relocalise::LoggedKeyframe;
use super::LayeredIcpSlam;
use crate::cloud::estimate_normals;
use crate::point_map::Keyframe;
use nalgebra::Point2;
use slamkit_core::Pose2;

/// Standard deviation of each velocity component of a drone found mid-flight \[m/s\]: an
/// indoor drone's cruise speed.
const UNKNOWN_SPEED_MPS: f64 = 1.0;

/// One keyframe of a saved layer map.
#[derive(Debug, Clone, PartialEq)]
pub struct SavedLayerKeyframe {
    /// The layer it belongs to.
    pub layer: i64,
    /// Time of its scan, on the clock of the run that saved it \[s\].
    pub time_s: f64,
    /// Its pose in the map's frame.
    pub world_from_base: Pose2,
    /// Its scan points in its base frame \[m\].
    pub points: Vec<Point2<f64>>,
}

/// The saved keyframes a mapper holds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Loaded {
    /// How many: the first ones of [`LayeredIcpSlam::keyframes`].
    pub count: usize,
    /// Added to their times to put them on this run's clock \[s\].
    pub time_shift_s: f64,
}

impl LayeredIcpSlam {
    /// Loads the saved keyframes `saved` into a mapper that has taken no scan yet (taken in
    /// time order, each layer's in the order it was built), the drone at `world_from_base` in
    /// the map's frame at `time_s`, the time of the scan it was found with (which
    /// [`LayeredIcpSlam::process`] takes next). `frozen`: localisation, the saved layers take
    /// no keyframe.
    pub fn start_in_saved_map(
        &mut self,
        mut saved: Vec<SavedLayerKeyframe>,
        world_from_base: Pose2,
        time_s: f64,
        frozen: bool,
    ) {
        let slam = self;
        saved.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        let time_shift_s = saved.last().map_or(0.0, |newest| {
            time_s - slam.config.relocalise.min_age_s - 1.0 - newest.time_s
        });
        let c = &slam.config.slam;
        for k in saved {
            let t = k.time_s + time_shift_s;
            let normals = estimate_normals(
                &k.points,
                c.normal_neighbours,
                c.normal_radius_m,
                c.normal_max_flatness,
            );
            let keyframe = Keyframe {
                world_from_base: k.world_from_base,
                points: k.points,
                normals,
            };
            let layer = slam
                .layers
                .entry(k.layer)
                .or_insert_with(|| LayerIcpMap::new(c, t));
            layer.load(keyframe.clone());
            slam.keyframe_log.push(LoggedKeyframe {
                layer: k.layer,
                index: layer.map().keyframes_inserted() - 1,
                time_s: t,
                keyframe,
            });
        }
        if frozen {
            slam.layers.values_mut().for_each(LayerIcpMap::freeze);
        }
        slam.loaded = Loaded {
            count: slam.keyframe_log.len(),
            time_shift_s,
        };
        slam.world_from_base = world_from_base;
        slam.last_time_s = Some(time_s);
        // the fix is a match; the drone may be flying at any speed a drone flies
        slam.last_match_s = Some(time_s);
        slam.velocity.unknown_velocity(UNKNOWN_SPEED_MPS);
    }

    /// The saved keyframes the mapper started with ([`LayeredIcpSlam::start_in_saved_map`]).
    pub fn loaded(&self) -> Loaded {
        self.loaded
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layers::{LayerInput, LayeredSlamConfig};
    use crate::sim_scan::SegmentWorld;

    fn input(scan: &slamkit_core::LaserScan) -> LayerInput<'_> {
        LayerInput {
            scan,
            up_m: Some(1.5),
            down_m: Some(1.0),
            roll_rad: 0.0,
            pitch_rad: 0.0,
            gyro_yaw_rad: None,
            flow_velocity_mps: None,
        }
    }

    /// A map of a room made by one run, then a second run found at a known pose in it: a
    /// frozen map takes no keyframe and tracks the drone; a continued one takes keyframes
    /// and keeps the saved ones where they were.
    #[test]
    fn a_saved_map_tracks_the_drone_and_is_frozen_or_continued() {
        let world = SegmentWorld::room();
        let pose_at = |i: usize| Pose2::new([0.03 * i as f64, 0.02 * i as f64].into(), 0.0);
        let scan_at = |i: usize, t: f64| {
            let mut scan = world.scan(&pose_at(i), 360, 1.5 * std::f64::consts::PI, 8.0);
            scan.timestamp = t;
            // the drone stops and starts with no tilt, which no drone can: odometry follows it
            scan.odometry = Some(pose_at(i));
            scan
        };
        let config = LayeredSlamConfig {
            use_odometry: true,
            ..LayeredSlamConfig::default()
        };
        let mut first = LayeredIcpSlam::new(config.clone()).unwrap();
        for i in 0..30 {
            first.process(&input(&scan_at(i, 0.1 * i as f64)));
        }
        let saved: Vec<SavedLayerKeyframe> = first
            .keyframes()
            .iter()
            .map(|k| SavedLayerKeyframe {
                layer: k.layer,
                time_s: k.time_s,
                world_from_base: k.keyframe.world_from_base,
                points: k.keyframe.points.clone(),
            })
            .collect();
        assert!(saved.len() >= 2);
        for frozen in [true, false] {
            // the second run's clock restarts at zero; it is found at scan 10's pose
            let mut second = LayeredIcpSlam::new(config.clone()).unwrap();
            second.start_in_saved_map(saved.clone(), pose_at(10), 0.0, frozen);
            assert_eq!(second.loaded().count, saved.len());
            assert!(second.keyframes().iter().all(|k| k.time_s < -30.0));
            for (n, i) in (10..30).enumerate() {
                let estimate = second.process(&input(&scan_at(i, 0.1 * n as f64)));
                let error = (estimate.world_from_base.translation.vector.xy()
                    - pose_at(i).translation.vector)
                    .norm();
                assert!(error < 0.02, "frozen {frozen}, scan {i}: {error} m");
            }
            let kept = second.keyframes()[..saved.len()]
                .iter()
                .zip(&saved)
                .all(|(k, s)| k.keyframe.world_from_base == s.world_from_base);
            assert!(kept, "saved keyframes moved");
            assert_eq!(second.keyframes().len() == saved.len(), frozen);
        }
    }
}
