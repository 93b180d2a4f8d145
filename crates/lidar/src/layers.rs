//! Layered 2D SLAM for a drone flying through a 3D room with a planar lidar.
//!
//! A planar lidar on a drone sees a different slice of the room at every height: a crate
//! disappears once the drone climbs over it, a table top appears when it flies under. One 2D map
//! for every height would mix those slices. Following the seed method (a drone in simulated
//! rooms with a 2D lidar and up/down range finders), space is cut into horizontal layers
//! (5 cm by default), and each layer holds its own ICP map of keyframe scans ([`layer_map`]),
//! created when the drone first enters it and re-used whenever it comes back:
//!
//! * the layer comes from the up and down range finders ([`height`]): a climb changes both
//!   ranges by opposite amounts, flying over or under an obstacle changes their sum;
//! * scans taken while the drone tilts more than `max_tilt_rad` (while accelerating) are not
//!   matched: the tilted scan plane cuts the room at other heights; the pose follows the
//!   motion prior;
//! * the motion prior is the drone's velocity, a Kalman filter's ([`velocity`]): driven by the
//!   acceleration its tilt shows (which carries it through take-offs and stops), measured by
//!   a downward optical-flow sensor when there is one and by every match along the directions
//!   its scan pins; turning as the IMU's yaw-rate gyro does, less its estimated bias, when
//!   there is one; or the scans' odometry if asked;
//! * with a gyro, the heading is a Kalman filter's over the heading error and the gyro bias
//!   ([`heading`]): each match measures the heading with the information its scan has on it
//!   when the position is free, and a match whose heading the filter finds implausible is
//!   dropped;
//! * on a layer change the scan is first aligned by ICP to the map of the layer the drone comes
//!   from, so that a new map starts where the old one ends and an old one is re-entered from
//!   where the drone is (an addition to the seed method, which started new layers from the
//!   odometry pose);
//! * each scan that its layer's map fixed is also aligned to the oldest maps of the layers a
//!   few centimetres above and below ([`mod@reference`]), a second measurement through the same
//!   gates: walls and pillars are mostly full height, and a map made earlier holds less of the
//!   heading drift that a map started seconds ago shares with the pose (an addition to the
//!   seed method, whose layer maps are independent);
//! * a match corrects the prior only along the directions the scan constrains ([`degeneracy`]:
//!   one wall in range pins the distance to it, not the position along it; with the heading
//!   held by the filter, a pillar's arc pins the position across the line of sight), weighed
//!   against the prior's uncertainty by the velocity filter, and only within a gate around the
//!   prior; keyframes go in at the corrected pose;
//! * each new keyframe is searched against old keyframes near it (of any layer) with a wide
//!   window ([`mod@relocalise`]), and a clearly better, plausible match moves the pose past the
//!   gate, spreading the correction over the keyframes of the drift;
//! * the pose is 3D: x, y and yaw from the layer's map, height from the range finders, roll
//!   and pitch from the flight controller.
//!
//! Every layer map is in the world frame (the first scan's pose), so nothing has to be chained
//! between layers.

pub mod degeneracy;
pub mod heading;
pub mod height;
pub mod kalman;
pub mod layer_map;
pub mod layer_pf;
pub mod reference;
pub mod relocalise;
pub mod saved;
pub mod velocity;

use crate::cloud::{estimate_normals, scan_points};
use crate::error::check_fields;
use crate::icp_slam::{IcpSlamConfig, ScanStatus};
use crate::point_map::Keyframe;
use crate::LidarError;
use degeneracy::{pinned_twist, scan_information, weakest};
use heading::{translation_at_heading, HeadingFilter, HeadingFilterConfig, HeadingUpdate};
use height::{HeightConfig, HeightTracker};
use layer_map::{LayerIcpMap, PreparedScan};
use nalgebra::{Matrix3, Point3, Translation3, UnitQuaternion, Vector2};
use reference::{reference_layers, ReferenceConfig};
use relocalise::{partial_correction, relocalise, share, LoggedKeyframe, Query, RelocaliseConfig};
use serde::{Deserialize, Serialize};
use slamkit_core::{LaserScan, Pose2, Pose3, StageTimings};
use std::collections::BTreeMap;
use std::time::Instant;
use velocity::{
    se2_exp, se2_log, tilt_acceleration, PositionUpdate, VelocityNoise, VelocityTracker,
};

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
    /// the drone's estimated velocity ([`velocity`]), which is the better prior for the
    /// simulated drone's noisy optical-flow odometry.
    pub use_odometry: bool,
    /// Without a gyro, the prior turns at the mean turn rate of the matched poses over this long
    /// \[s\].
    pub velocity_window_s: f64,
    /// Noise of the velocity filter's inputs: the tilt's acceleration, the optical flow
    /// ([`velocity`]).
    pub velocity: VelocityNoise,
    /// A scan match corrects the prediction only along directions in which the scan's
    /// information matrix has at least this eigenvalue (about that many points pinning the
    /// pose; [`degeneracy`]); 0 keeps every match whole. With a gyro the heading is the
    /// [`heading`] filter's and this applies to the position at that heading, which a
    /// pillar's arc pins across the line of sight with 5–15 points (`office` seeds 1–5 at
    /// commit a98a719, median mean error: 0.13 m at 5, 0.32 m at 3, 0.54 m at 10, 0.32 m at 20;
    /// seeds 1–20 with the velocity filter of 5efc158: 0.175 m at 5, 0.185 m at 3, 0.235 m at
    /// 10).
    pub min_constraint: f64,
    /// Normals for that information matrix are fitted to at most this many nearest points,
    /// within `information_normal_radius_m`.
    pub information_neighbours: usize,
    /// ... and within this distance \[m\]: a wall seen from close by, whose points are a few
    /// millimetres apart with a centimetre of range noise, then reads as a line pinning one
    /// direction rather than as clutter pinning two, while a pillar's arc (0.2 m radius) keeps
    /// its curvature and pins the position across it; fitted to the 20 nearest points within
    /// 0.5 m, its normals were the chord's (`office` seeds 1–5 at commit a98a719, median mean
    /// error: 0.13 m at 0.15 m, 0.29 m at 0.2 m, 0.45 m at 0.1 m, where close walls read as
    /// clutter).
    pub information_normal_radius_m: f64,
    /// A match may move the predicted pose by at most this, plus `gate_growth_mps` for every
    /// second since the last accepted match \[m\]; a larger correction is a false match (the
    /// prior is good to millimetres per scan) and the prediction is kept.
    pub gate_m: f64,
    /// Growth of the translation gate with the time since the last accepted match \[m/s\].
    pub gate_growth_mps: f64,
    /// As `gate_m`, for the heading \[rad\].
    pub gate_rad: f64,
    /// Growth of the heading gate with the time since the last accepted match \[rad/s\].
    pub gate_growth_radps: f64,
    /// Older maps of nearby layers as a second measurement of each fixed scan ([`mod@reference`]).
    pub reference: ReferenceConfig,
    /// Re-localisation on old keyframes, past the gate ([`mod@relocalise`]).
    pub relocalise: RelocaliseConfig,
    /// Heading from the gyro and the scans, with the gyro's bias ([`heading`]); used when
    /// the input has a gyro heading.
    pub heading: HeadingFilterConfig,
    /// Scan matching and keyframe insertion in every layer: the ICP, correlative fallback,
    /// range, normal, map and insertion settings of ICP-SLAM (its odometry and loop-closure
    /// settings are not used). By default every keyframe is kept, so that a layer's whole map
    /// is there when the drone returns.
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
            velocity: VelocityNoise::default(),
            min_constraint: 5.0,
            information_neighbours: 50,
            information_normal_radius_m: 0.15,
            gate_m: 0.05,
            gate_growth_mps: 0.1,
            gate_rad: 0.03,
            gate_growth_radps: 0.1,
            reference: ReferenceConfig::default(),
            relocalise: RelocaliseConfig::default(),
            heading: HeadingFilterConfig::default(),
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
        self.relocalise.validate()?;
        let non_negative = |field, value: f64| (field, value, value >= 0.0);
        let checks = [
            non_negative("max_tilt_rad", self.max_tilt_rad),
            (
                "velocity_window_s",
                self.velocity_window_s,
                self.velocity_window_s > 0.0,
            ),
            non_negative("min_constraint", self.min_constraint),
            (
                "information_normal_radius_m",
                self.information_normal_radius_m,
                self.information_normal_radius_m > 0.0,
            ),
            non_negative("gate_m", self.gate_m),
            non_negative("gate_growth_mps", self.gate_growth_mps),
            non_negative("gate_rad", self.gate_rad),
            non_negative("gate_growth_radps", self.gate_growth_radps),
        ];
        check_fields(
            self.height
                .field_checks()
                .into_iter()
                .chain(self.heading.field_checks())
                .chain(self.velocity.field_checks())
                .chain(self.reference.field_checks())
                .chain(checks),
            "out of range",
        )
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
    /// Heading integrated from the IMU's yaw-rate gyro \[rad\] (any origin; only its change
    /// between scans is used), `None` without a gyro.
    pub gyro_yaw_rad: Option<f64>,
    /// Mean body-frame horizontal velocity `(forward, left)` since the previous scan from a
    /// downward optical-flow sensor \[m/s\], `None` without one (or without a reading).
    pub flow_velocity_mps: Option<Vector2<f64>>,
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
    /// The planar pose without the re-localisations' corrections: a path with no jumps, whose
    /// increments are the motion between scans (odometry for another filter).
    pub smooth_world_from_base: Pose2,
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
    /// Matched scans that left some direction unconstrained (kept from the prediction there).
    pub scans_degenerate: usize,
    /// Matches rejected: moving the prediction farther than the gate, or by more than the
    /// heading and velocity filters find plausible.
    pub matches_rejected: usize,
    /// Poses moved onto old keyframes past the gate ([`mod@relocalise`]).
    pub relocalisations: usize,
    /// Fixed poses moved by an older map of a nearby layer ([`mod@reference`]).
    pub reference_fixes: usize,
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
    /// Scans given to the layer's map (matched, failed or inserted).
    pub scans: usize,
    /// Keyframes inserted into the layer's map.
    pub keyframes: usize,
}

/// The filter updates worked out for one match: the heading's (with a gyro) and the
/// position's, applied only to the match that is kept.
type Updates = (Option<HeadingUpdate>, PositionUpdate);

/// Layered ICP-SLAM; feed it scans in time order with [`LayeredIcpSlam::process`].
pub struct LayeredIcpSlam {
    config: LayeredSlamConfig,
    height: HeightTracker,
    layers: BTreeMap<i64, LayerIcpMap>,
    current: Option<i64>,
    world_from_base: Pose2,
    /// Time of `world_from_base` \[s\].
    last_time_s: Option<f64>,
    last_odometry: Option<Pose2>,
    /// Gyro heading of the last scan \[rad\].
    last_gyro_yaw: Option<f64>,
    /// Heading error and gyro bias, while the input has a gyro.
    heading: HeadingFilter,
    velocity: VelocityTracker,
    /// Time of the last accepted match \[s\].
    last_match_s: Option<f64>,
    /// Every keyframe inserted, in time order, for re-localisation.
    keyframe_log: Vec<LoggedKeyframe>,
    /// Time of the last re-localisation \[s\].
    last_relocalised_s: Option<f64>,
    /// Product of every re-localisation's correction (corrected = this · smooth).
    corrections: Pose2,
    /// The keyframes of a saved map the mapper started in ([`saved`]): the first ones of
    /// `keyframe_log`, never moved.
    loaded: saved::Loaded,
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
            last_gyro_yaw: None,
            heading: HeadingFilter::new(config.heading.clone()),
            velocity: VelocityTracker::new(config.velocity.clone(), config.velocity_window_s),
            last_match_s: None,
            keyframe_log: Vec::new(),
            last_relocalised_s: None,
            corrections: Pose2::identity(),
            loaded: saved::Loaded::default(),
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
        let accel = tilt_acceleration(roll, pitch);
        let predicted = self.predict(input, &accel);
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
                    let (pose, status, accepted) =
                        self.match_in_layer(h.layer, input.scan, predicted);
                    self.timings.record_since("layer_slam", start);
                    if accepted {
                        self.velocity.observe(input.scan.timestamp, pose);
                        self.last_match_s = Some(input.scan.timestamp);
                    }
                    (pose, LayerScanStatus::Slam(status))
                }
            }
        };
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
            smooth_world_from_base: renormalised(self.corrections.inverse() * pose),
        }
    }

    /// The last pose moved by the odometry increment, or by the optical flow's velocity, or by
    /// the recent velocity and the acceleration `accel` the tilt shows; turning as the gyro
    /// heading did when there is one.
    fn predict(&mut self, input: &LayerInput, accel: &Vector2<f64>) -> Pose2 {
        let scan = input.scan;
        let odometry = scan.odometry.filter(|_| self.config.use_odometry);
        let gyro_yaw = input.gyro_yaw_rad.filter(|y| y.is_finite());
        let dt = self.last_time_s.map_or(0.0, |t| scan.timestamp - t);
        let turn = self
            .last_gyro_yaw
            .zip(gyro_yaw)
            .map(|(prev, cur)| self.heading.predict(cur - prev, dt));
        self.last_gyro_yaw = gyro_yaw;
        let flow = input
            .flow_velocity_mps
            .filter(|v| v.iter().all(|c| c.is_finite()));
        let from = self.world_from_base;
        if let Some(v) = flow {
            self.velocity.measure_flow(&v);
        }
        let predicted = match (self.last_odometry, odometry) {
            (Some(prev), Some(cur)) => {
                self.velocity.unknown_position();
                from * (prev.inverse() * cur)
            }
            _ => self.velocity.advance(&from, dt, accel, turn),
        };
        if odometry.is_some() {
            self.last_odometry = odometry;
        }
        renormalised(predicted)
    }

    /// Runs the scan through the map of `layer` from the `predicted` pose; returns the pose, how
    /// it was found and whether a map fixed it. On a layer change the scan is first aligned to
    /// the map of the layer the drone comes from, which starts a new layer where the old one
    /// ends and re-enters an old layer from where the drone really is. Every correction of
    /// `predicted` is kept only along the directions the scan constrains, and only within the
    /// gate.
    fn match_in_layer(
        &mut self,
        layer: i64,
        scan: &LaserScan,
        predicted: Pose2,
    ) -> (Pose2, ScanStatus, bool) {
        let previous = self.current.replace(layer);
        let switched_from = previous.filter(|p| *p != layer);
        if switched_from.is_some() {
            self.stats.layer_switches += 1;
            self.stats.layer_returns += usize::from(self.layers.contains_key(&layer));
        }
        let c = &self.config.slam;
        let (prepared, information) = self.prepare(scan);
        let aligned = switched_from
            .filter(|_| self.config.align_new_layer)
            .and_then(|p| self.layers.get(&p))
            .and_then(|from| {
                self.accept(
                    from.match_scan(&prepared, &predicted, c).world_from_base,
                    &predicted,
                    &information,
                    scan.timestamp,
                )
            });
        let guess = aligned.map_or(predicted, |a| a.0);
        let entry = self
            .layers
            .entry(layer)
            .or_insert_with(|| LayerIcpMap::new(&self.config.slam, scan.timestamp));
        let raw = entry.match_scan(&prepared, &guess, &self.config.slam);
        let matched = raw
            .world_from_base
            .and_then(|pose| self.accept(Some(pose), &predicted, &information, scan.timestamp));
        let fixed = matched.or(aligned).map(|(pose, updates)| {
            self.apply(updates);
            self.reference_fix(layer, &prepared, &information, pose, scan.timestamp)
        });
        let matched = matched.map(|m| m.0);
        if raw.world_from_base.is_some() && matched.is_none() {
            self.stats.matches_rejected += 1;
        }
        let status = match (raw.status, matched) {
            (ScanStatus::Matched | ScanStatus::MatchedCorrelative, None) => ScanStatus::MatchFailed,
            (status, _) => status,
        };
        if fixed.is_some() && weakest(&information) < self.config.min_constraint {
            self.stats.scans_degenerate += 1;
        }
        let pose = renormalised(fixed.unwrap_or(guess));
        let inserted = self.layers.get_mut(&layer).is_some_and(|entry| {
            entry.record(&prepared, &pose, fixed.is_some(), &self.config.slam)
        });
        if !inserted {
            return (pose, status, fixed.is_some());
        }
        let query = Query {
            scan: &prepared,
            information: &information,
            pose,
            layer,
            layer_height_m: self.config.height.layer_height_m,
            time_s: scan.timestamp,
        };
        let found = self
            .config
            .relocalise
            .enabled
            .then(|| relocalise(&self.keyframe_log, &query, &self.config.relocalise))
            .flatten();
        let index = self
            .layers
            .get(&layer)
            .map_or(0, |l| l.map().keyframes_inserted().saturating_sub(1));
        self.keyframe_log.push(LoggedKeyframe {
            layer,
            index,
            time_s: scan.timestamp,
            keyframe: Keyframe {
                world_from_base: pose,
                points: prepared.points,
                normals: prepared.normals,
            },
        });
        match found {
            Some(found) => {
                let anchor = self
                    .last_relocalised_s
                    .map_or(found.anchor_s, |t| t.max(found.anchor_s));
                self.correct(&pose, &found.world_from_base, anchor, scan.timestamp);
                (found.world_from_base, status, true)
            }
            None => (pose, status, fixed.is_some()),
        }
    }

    /// `pose`, which the layer's own map fixed, moved by an alignment to an older map of a
    /// nearby layer ([`mod@reference`]): the first one that puts `min_goodness` of the scan on its
    /// map is kept if it passes the gate and the filters' innovation gates, as a match does.
    fn reference_fix(
        &mut self,
        layer: i64,
        scan: &PreparedScan,
        information: &Matrix3<f64>,
        pose: Pose2,
        t_s: f64,
    ) -> Pose2 {
        let c = &self.config.reference;
        if !c.enabled {
            return pose;
        }
        let created = self.layers.iter().map(|(&k, map)| (k, map.created_s()));
        let references =
            reference_layers(created, layer, t_s, self.config.height.layer_height_m, c);
        let found = references.iter().find_map(|k| {
            self.layers[k]
                .refine(scan, &pose, &self.config.slam.icp)
                .filter(|r| r.goodness >= c.min_goodness)
        });
        let Some(found) = found else {
            return pose;
        };
        let information = information * found.goodness;
        match self.accept(Some(found.target_from_source), &pose, &information, t_s) {
            Some((moved, updates)) => {
                self.apply(updates);
                self.stats.reference_fixes += 1;
                moved
            }
            None => pose,
        }
    }

    /// Applies a kept match's filter updates.
    fn apply(&mut self, (heading, position): Updates) {
        if let Some(update) = heading {
            self.heading.apply(&update);
        }
        self.velocity.apply(&position);
    }

    /// The scan's points with ICP's normals, and its information matrix
    /// ([`degeneracy::scan_information`]) from normals fitted over `information_neighbours`.
    fn prepare(&self, scan: &LaserScan) -> (PreparedScan, Matrix3<f64>) {
        let c = &self.config.slam;
        let points = scan_points(scan, c.min_range_m, c.max_range_m);
        let normals = estimate_normals(
            &points,
            c.normal_neighbours,
            c.normal_radius_m,
            c.normal_max_flatness,
        );
        let information_normals = estimate_normals(
            &points,
            self.config.information_neighbours,
            self.config.information_normal_radius_m,
            c.normal_max_flatness,
        );
        let information = scan_information(&points, &information_normals);
        (PreparedScan { points, normals }, information)
    }

    /// Moves the pose `from` of time `now_s` to `to`, and with it every keyframe and recent
    /// pose since `anchor_s` by its share of the correction ([`relocalise::share`]).
    fn correct(&mut self, from: &Pose2, to: &Pose2, anchor_s: f64, now_s: f64) {
        let moved = |t: f64, p: &Pose2| {
            renormalised(partial_correction(from, to, share(t, anchor_s, now_s)) * p)
        };
        let mut by_layer: BTreeMap<i64, BTreeMap<usize, Pose2>> = BTreeMap::new();
        let mine = self.keyframe_log.iter_mut().skip(self.loaded.count);
        for k in mine.filter(|k| k.time_s > anchor_s) {
            k.keyframe.world_from_base = moved(k.time_s, &k.keyframe.world_from_base);
            by_layer
                .entry(k.layer)
                .or_default()
                .insert(k.index, k.keyframe.world_from_base);
        }
        for (layer, poses) in by_layer {
            if let Some(map) = self.layers.get_mut(&layer) {
                map.relocate(|i| poses.get(&i).copied());
            }
        }
        self.velocity.relocate(moved);
        self.corrections = renormalised(partial_correction(from, to, 1.0) * self.corrections);
        self.last_relocalised_s = Some(now_s);
        self.stats.relocalisations += 1;
    }

    /// A raw match, if it is within the gate around `predicted` at time `t_s`, kept along the
    /// directions the scan constrains (`information`), with the heading filter's update when
    /// there is a gyro. The gate applies to the raw match: a match that slid far along an
    /// unconstrained direction is not trusted in the others.
    fn accept(
        &self,
        raw: Option<Pose2>,
        predicted: &Pose2,
        information: &Matrix3<f64>,
        t_s: f64,
    ) -> Option<(Pose2, Updates)> {
        let raw = raw?;
        if !self.within_gate(predicted, &raw, t_s) {
            return None;
        }
        let min = self.config.min_constraint;
        let eps = se2_log(&(predicted.inverse() * raw));
        let (t, heading_rad, heading_update) = if self.last_gyro_yaw.is_none() {
            let kept = pinned_twist(&eps, information, min);
            (kept.xy(), kept.z, None)
        } else {
            let update = self.heading.update(eps.z, information)?;
            let t = translation_at_heading(&eps, information, update.heading_rad);
            (t, update.heading_rad, Some(update))
        };
        let h = &self.config.heading;
        let position = self.velocity.position_update(
            &t,
            information,
            min,
            h.scan_sigma_m,
            h.max_innovation_sigma,
        )?;
        let pose = predicted * se2_exp(&position.translation.push(heading_rad));
        Some((pose, (heading_update, position)))
    }

    /// True when `pose` is within the gate around `predicted` at time `t_s`.
    fn within_gate(&self, predicted: &Pose2, pose: &Pose2, t_s: f64) -> bool {
        let c = &self.config;
        let since = self.last_match_s.map_or(0.0, |last| (t_s - last).max(0.0));
        let d = predicted.inverse() * pose;
        d.translation.vector.norm() <= c.gate_m + c.gate_growth_mps * since
            && d.rotation.angle().abs() <= c.gate_rad + c.gate_growth_radps * since
    }

    /// Every keyframe inserted so far, in time order, with its layer (poses as moved by the
    /// re-localisations): what a saved map of the layers holds.
    pub fn keyframes(&self) -> &[LoggedKeyframe] {
        &self.keyframe_log
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
                    .map()
                    .points()
                    .iter()
                    .map(|p| Point3::new(p.x, p.y, z))
                    .collect();
                LayerMap {
                    layer,
                    z_range_m: [bottom, bottom + h],
                    points,
                    scans: l.scans(),
                    keyframes: l.map().keyframes_inserted(),
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

/// `pose` with its rotation scaled back to unit length. The inverse of a rotation is taken to be
/// its conjugate, so a rotation slightly off unit length stays off in every product; a chain of
/// predictions from estimates from predictions multiplies those errors (they once grew from
/// 1e-16 to a collapsed, zero rotation within a hundred scans).
fn renormalised(mut pose: Pose2) -> Pose2 {
    pose.rotation.renormalize();
    pose
}

#[cfg(test)]
mod tests;
