//! Layered 2D SLAM for a drone flying through a 3D room with a planar lidar.
//!
//! A planar lidar on a drone sees a different slice of the room at every height: a crate
//! disappears once the drone climbs over it, a table top appears when it flies under. One 2D map
//! for every height would mix those slices. Following the seed method (a drone in simulated
//! rooms with a 2D lidar and up/down range finders), space is cut into horizontal layers
//! (5 cm by default), and each layer holds its own ICP-SLAM map ([`crate::icp_slam`]), created
//! when the drone first enters it and re-used whenever it comes back:
//!
//! * the layer comes from the up and down range finders ([`height`]): a climb changes both
//!   ranges by opposite amounts, flying over or under an obstacle changes their sum;
//! * scans taken while the drone tilts more than `max_tilt_rad` (while accelerating) are not
//!   matched: the tilted scan plane cuts the room at other heights; the pose follows odometry;
//! * the first scan of a new layer is aligned by ICP to the map of the layer the drone comes
//!   from, so that the new map starts where the old one ends (an addition to the seed method,
//!   which started new layers from the odometry pose);
//! * the pose is 3D: x, y and yaw from the layer's map, height from the range finders, roll
//!   and pitch from the flight controller.
//!
//! Each layer's [`IcpSlam`] works in its own frame (identity at the layer's first scan); the
//! layer remembers `world_from_layer`. The prediction of the global pose is handed to a layer
//! as the scan's odometry, chosen so that the layer's own odometry increment lands exactly on
//! the prediction.

pub mod height;
pub mod velocity;

use crate::cloud::scan_points;
use crate::icp::align;
use crate::icp_slam::{IcpSlam, IcpSlamConfig, IcpSlamStats, ScanStatus};
use crate::LidarError;
use height::{HeightConfig, HeightTracker};
use nalgebra::{Point3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use slamkit_core::{LaserScan, Pose2, Pose3, StageTimings};
use std::collections::BTreeMap;
use std::time::Instant;
use velocity::VelocityTracker;

/// Parameters of layered ICP-SLAM.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LayeredSlamConfig {
    /// Height and layer tracking.
    pub height: HeightConfig,
    /// Scans taken while the tilt exceeds this are not matched \[rad\].
    pub max_tilt_rad: f64,
    /// Align the first scan of a new layer to the map of the previous layer.
    pub align_new_layer: bool,
    /// Predict each scan's pose from the scans' odometry; when false (or a scan has none) from
    /// the velocity of the recent matched poses ([`velocity`]), which is the better prior for
    /// the simulated drone's noisy optical-flow odometry.
    pub use_odometry: bool,
    /// The constant-velocity prior averages the motion over this long \[s\].
    pub velocity_window_s: f64,
    /// The ICP-SLAM run in every layer (by default keeping every keyframe, so that a layer's
    /// whole map is there when the drone returns).
    pub slam: IcpSlamConfig,
}

impl Default for LayeredSlamConfig {
    fn default() -> Self {
        Self {
            height: HeightConfig::default(),
            max_tilt_rad: 0.5f64.to_radians(),
            align_new_layer: true,
            use_odometry: false,
            velocity_window_s: 1.0,
            slam: IcpSlamConfig {
                map_keyframes: 0,
                ..IcpSlamConfig::default()
            },
        }
    }
}

impl LayeredSlamConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), LidarError> {
        self.slam.validate()?;
        let tilt = ("max_tilt_rad", self.max_tilt_rad);
        let window = ("velocity_window_s", self.velocity_window_s);
        let bad = self
            .height
            .invalid_field()
            .or_else(|| {
                (!(self.max_tilt_rad.is_finite() && self.max_tilt_rad >= 0.0)).then_some(tilt)
            })
            .or_else(|| {
                (!(self.velocity_window_s.is_finite() && self.velocity_window_s > 0.0))
                    .then_some(window)
            });
        match bad {
            Some((field, value)) => Err(LidarError::InvalidConfig {
                field,
                value: value.to_string(),
                reason: "out of range",
            }),
            None => Ok(()),
        }
    }
}

/// What the drone senses at one scan time.
#[derive(Debug, Clone, Copy)]
pub struct LayerInput<'a> {
    /// The planar scan, with the drone's odometry when it has any.
    pub scan: &'a LaserScan,
    /// Up-looking range \[m\] (`None`: no reading).
    pub up_m: Option<f64>,
    /// Down-looking range \[m\] (`None`: no reading).
    pub down_m: Option<f64>,
    /// Roll of the base \[rad\].
    pub roll_rad: f64,
    /// Pitch of the base \[rad\].
    pub pitch_rad: f64,
}

/// How one scan was used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LayerScanStatus {
    /// Matched (or otherwise handled) by the layer's ICP-SLAM.
    Slam(ScanStatus),
    /// Not matched: the drone tilted too much; the pose follows odometry.
    Tilted,
    /// No height yet (no range reading so far); the pose follows odometry.
    NoHeight,
}

/// The estimate for one scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayeredEstimate {
    /// Estimated 3D pose of the base.
    pub world_from_base: Pose3,
    /// Height layer the scan was assigned to (`None` before the first height).
    pub layer: Option<i64>,
    /// How the scan was used.
    pub status: LayerScanStatus,
}

/// One layer's map.
struct Layer {
    slam: IcpSlam,
    world_from_layer: Pose2,
    /// The odometry last handed to the layer and the pose it answered, in the layer frame.
    last: Option<(Pose2, Pose2)>,
}

/// Counters over a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct LayeredStats {
    /// Scans given to the mapper.
    pub scans_read: usize,
    /// Scans not matched because of tilt.
    pub scans_tilted: usize,
    /// Scans before the first height reading.
    pub scans_without_height: usize,
    /// Layer changes.
    pub layer_switches: usize,
    /// Returns to a layer visited before.
    pub layer_returns: usize,
    /// Obstacle edges seen by the range finders.
    pub obstacle_edges: usize,
}

/// A layer's map in the world frame.
#[derive(Debug, Clone, PartialEq)]
pub struct LayerMap {
    /// Layer index.
    pub layer: i64,
    /// Bottom and top of the layer \[m\].
    pub z_range_m: [f64; 2],
    /// Map points (world frame, at the layer's mid height) \[m\].
    pub points: Vec<Point3<f64>>,
    /// Counters of the layer's ICP-SLAM.
    pub stats: IcpSlamStats,
}

/// Layered ICP-SLAM; feed it scans in time order with [`LayeredIcpSlam::process`].
pub struct LayeredIcpSlam {
    config: LayeredSlamConfig,
    height: HeightTracker,
    layers: BTreeMap<i64, Layer>,
    current: Option<i64>,
    world_from_base: Pose2,
    /// Time of `world_from_base` \[s\].
    last_time_s: Option<f64>,
    last_odometry: Option<Pose2>,
    velocity: VelocityTracker,
    stats: LayeredStats,
    timings: StageTimings,
}

impl LayeredIcpSlam {
    /// A mapper with no layers; the world frame's x, y and yaw are those of the first scan, its
    /// z = 0 the floor under it.
    pub fn new(config: LayeredSlamConfig) -> Result<Self, LidarError> {
        config.validate()?;
        Ok(Self {
            height: HeightTracker::new(config.height.clone()),
            layers: BTreeMap::new(),
            current: None,
            world_from_base: Pose2::identity(),
            last_time_s: None,
            last_odometry: None,
            velocity: VelocityTracker::new(config.velocity_window_s),
            stats: LayeredStats::default(),
            timings: StageTimings::default(),
            config,
        })
    }

    /// Estimates the pose at `input`'s scan and updates the layer maps. Never fails: a scan
    /// that cannot be used keeps its predicted pose and is counted.
    pub fn process(&mut self, input: &LayerInput) -> LayeredEstimate {
        self.stats.scans_read += 1;
        let (roll, pitch) = (input.roll_rad, input.pitch_rad);
        let cos_tilt = (roll.cos() * pitch.cos()).clamp(0.0, 1.0);
        let vertical = |r: Option<f64>| r.map(|v| v * cos_tilt);
        let height = self
            .height
            .update(vertical(input.up_m), vertical(input.down_m));
        let predicted = self.predict(input.scan);
        let tilted = cos_tilt.acos() > self.config.max_tilt_rad;
        let (pose, status) = match height {
            None => {
                self.stats.scans_without_height += 1;
                (predicted, LayerScanStatus::NoHeight)
            }
            Some(h) => {
                self.stats.obstacle_edges += usize::from(h.obstacle_edge);
                if tilted {
                    self.stats.scans_tilted += 1;
                    (predicted, LayerScanStatus::Tilted)
                } else {
                    let start = Instant::now();
                    let (pose, status) = self.match_in_layer(h.layer, input.scan, predicted);
                    self.timings.record_since("layer_slam", start);
                    (pose, LayerScanStatus::Slam(status))
                }
            }
        };
        if matches!(
            status,
            LayerScanStatus::Slam(
                ScanStatus::Matched | ScanStatus::MatchedCorrelative | ScanStatus::Initialised
            )
        ) {
            self.velocity.observe(input.scan.timestamp, pose);
        }
        self.world_from_base = pose;
        self.last_time_s = Some(input.scan.timestamp);
        let z = height.map_or(0.0, |h| h.height_m);
        let yaw = pose.rotation.angle();
        LayeredEstimate {
            world_from_base: Pose3::from_parts(
                Translation3::new(pose.translation.x, pose.translation.y, z),
                UnitQuaternion::from_euler_angles(roll, pitch, yaw),
            ),
            layer: height.map(|h| h.layer),
            status,
        }
    }

    /// The last pose moved by the odometry increment, or by the recent velocity.
    fn predict(&mut self, scan: &LaserScan) -> Pose2 {
        let odometry = scan.odometry.filter(|_| self.config.use_odometry);
        let predicted = match (self.last_odometry, odometry) {
            (Some(prev), Some(cur)) => self.world_from_base * (prev.inverse() * cur),
            _ => {
                let dt = self.last_time_s.map_or(0.0, |t| scan.timestamp - t);
                self.velocity.predict(&self.world_from_base, dt)
            }
        };
        if odometry.is_some() {
            self.last_odometry = odometry;
        }
        renormalised(predicted)
    }

    /// Runs the scan through the map of `layer` from the global `predicted` pose.
    fn match_in_layer(
        &mut self,
        layer: i64,
        scan: &LaserScan,
        predicted: Pose2,
    ) -> (Pose2, ScanStatus) {
        let previous = self.current.replace(layer);
        if previous.is_some_and(|p| p != layer) {
            self.stats.layer_switches += 1;
            if self.layers.contains_key(&layer) {
                self.stats.layer_returns += 1;
            }
        }
        if !self.layers.contains_key(&layer) {
            let start = previous
                .and_then(|p| self.layers.get(&p))
                .filter(|_| self.config.align_new_layer)
                .map_or(predicted, |from| self.align_to(from, scan, &predicted));
            let slam = match IcpSlam::new(self.config.slam.clone()) {
                Ok(slam) => slam,
                // the configuration was validated in `new`
                Err(_) => return (predicted, ScanStatus::Skipped),
            };
            let fresh = Layer {
                slam,
                world_from_layer: renormalised(start),
                last: None,
            };
            self.layers.insert(layer, fresh);
        }
        let Some(entry) = self.layers.get_mut(&layer) else {
            return (predicted, ScanStatus::Skipped);
        };
        feed(entry, scan, &predicted)
    }

    /// `predicted` refined by aligning the scan to another layer's map, when ICP agrees well.
    fn align_to(&self, from: &Layer, scan: &LaserScan, predicted: &Pose2) -> Pose2 {
        let c = &self.config.slam;
        let points = scan_points(scan, c.min_range_m, c.max_range_m);
        let guess = from.world_from_layer.inverse() * predicted;
        match align(&points, from.slam.map().index(), &guess, &c.icp) {
            Ok(res) if res.goodness >= c.min_goodness => {
                from.world_from_layer * res.target_from_source
            }
            _ => *predicted,
        }
    }

    /// The current height layer.
    pub fn current_layer(&self) -> Option<i64> {
        self.current
    }

    /// Counters so far.
    pub fn stats(&self) -> &LayeredStats {
        &self.stats
    }

    /// Per-stage timings so far (`layer_slam`: one scan through its layer's map).
    pub fn timings(&self) -> &StageTimings {
        &self.timings
    }

    /// The map of every layer visited, lowest first, in the world frame.
    pub fn layer_maps(&self) -> Vec<LayerMap> {
        let h = self.config.height.layer_height_m;
        self.layers
            .iter()
            .map(|(&layer, l)| {
                let bottom = layer as f64 * h;
                let z = bottom + h / 2.0;
                let points = l
                    .slam
                    .map()
                    .points()
                    .iter()
                    .map(|p| {
                        let w = l.world_from_layer * p;
                        Point3::new(w.x, w.y, z)
                    })
                    .collect();
                LayerMap {
                    layer,
                    z_range_m: [bottom, bottom + h],
                    points,
                    stats: *l.slam.stats(),
                }
            })
            .collect()
    }

    /// The points of every layer in one cloud (world frame).
    pub fn merged_cloud(&self) -> Vec<Point3<f64>> {
        self.layer_maps()
            .into_iter()
            .flat_map(|m| m.points)
            .collect()
    }
}

/// Hands `scan` to a layer with an odometry reading chosen so that the layer's prediction
/// (its last pose moved by the odometry increment) is `predicted`; returns the world pose.
fn feed(layer: &mut Layer, scan: &LaserScan, predicted: &Pose2) -> (Pose2, ScanStatus) {
    let in_layer = layer.world_from_layer.inverse() * predicted;
    let odometry = renormalised(match layer.last {
        Some((last_odometry, last_pose)) => last_odometry * last_pose.inverse() * in_layer,
        None => in_layer,
    });
    let mut scan = scan.clone();
    scan.odometry = Some(odometry);
    let estimate = layer.slam.process(&scan);
    layer.last = Some((odometry, estimate.world_from_base));
    (
        renormalised(layer.world_from_layer * estimate.world_from_base),
        estimate.status,
    )
}

/// `pose` with its rotation scaled back to unit length. The inverse of a rotation is taken to be
/// its conjugate, so a rotation slightly off unit length stays off in every product; the chain
/// odometry → layer prediction → estimate → next odometry multiplies those errors, which grew
/// from 1e-16 to a collapsed (zero) rotation within a hundred scans before this was applied.
fn renormalised(mut pose: Pose2) -> Pose2 {
    pose.rotation.renormalize();
    pose
}

#[cfg(test)]
mod tests;
