//! [`DroneSlam`]: the drone's online session, layered 2D lidar SLAM
//! ([`slamkit_lidar::layers`]) with up/down range finders, the flight controller's attitude and
//! gyro, and optionally a downward optical-flow sensor, plus an optional particle filter on
//! the layered increments ([`particle_filter`]).
//!
//! The session takes [`Observation`]s in time order: a [`Observation::Range`],
//! [`Observation::Imu`] or [`Observation::Flow`] is stored, and each [`Observation::Scan`] is
//! matched with what was stored: the latest range pair and attitude at the scan's time, and the
//! mean flow velocity over the interval since the previous scan ([`readings`]). A reading
//! stamped with a scan's time must come before the scan
//! ([`time_ordered`](slamkit_core::observation::time_ordered) puts it there). Each scan is
//! answered with an [`Update`]: the 3D pose (x, y, yaw from the layer's map, height from the
//! range finders, roll and pitch from the attitude), how it was found, and the keyframes and
//! re-localisations it added.
//!
//! Configuration ([`DroneSlamConfig`]): the basic settings for a new drone are the range
//! finders' mounting and the layer height (`layers.height`), the tilt above which scans are
//! not matched (`layers.max_tilt_rad`) and the lidar's usable ranges (`layers.slam.min_range_m`,
//! `max_range_m`); the rest is advanced and documented on [`LayeredSlamConfig`].
//!
//! The map frame is the first scan's x, y and heading (or the initial pose given), with z = 0
//! at the floor under it. The session never reads ground truth.

pub mod demo;
pub mod grids;
pub mod in_map;
pub mod kidnapped;
pub mod layer_choice;
pub mod map;
pub mod particle_filter;
pub mod readings;
pub mod run_report;
pub mod simulated;

use crate::odometry_gate::{OdometryGate, OdometryGateConfig};
use crate::session::{MapChange, Session, TrackingStatus, Update};
use crate::SlamError;
use nalgebra::Point3;
use particle_filter::DronePf;
use serde::{Deserialize, Serialize};
use slamkit_core::observation::RangePair;
use slamkit_core::pose::pose2_to_pose3;
use slamkit_core::{LaserScan, Observation, Pose2, Pose3, StageTimings, Trajectory};
use slamkit_lidar::layers::{
    LayerMap, LayerScanStatus, LayeredEstimate, LayeredIcpSlam, LayeredSlamConfig, LayeredStats,
};
use slamkit_lidar::motion::is_finite_pose;
use slamkit_lidar::rbpf::RbpfConfig;
use std::collections::BTreeMap;
use std::path::Path;

/// Settings of a [`DroneSlam`] session.
///
/// Basic (what a new drone needs): `layers.height` (`layer_height_m`, the range finders'
/// mounting offsets `up_offset_m` / `down_offset_m`), `layers.slam.min_range_m` /
/// `layers.slam.max_range_m` (the lidar's usable ranges), `layers.max_tilt_rad` (scans taken
/// at steeper tilts are not matched), `layers.slam.map_voxel_m` (map resolution), and
/// `particle_filter` to run the particle filter too. The rest is advanced.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DroneSlamConfig {
    /// Layered ICP-SLAM (range finders, tilt, matching, filters).
    pub layers: LayeredSlamConfig,
    /// The particle filter on the layered increments; `None` (the default): not run. A
    /// drone's tuning is [`particle_filter::drone_pf_config`].
    pub particle_filter: Option<RbpfConfig>,
    /// Finding the drone in a saved map ([`DroneSlam::localise`], [`DroneSlam::resume`]).
    pub in_map: in_map::InMapConfig,
    /// Jumps in the scans' odometry faster than the drone flies are taken as no motion and
    /// counted ([`crate::odometry_gate`]).
    pub odometry_gate: OdometryGateConfig,
}

impl DroneSlamConfig {
    /// A drone session's settings as a shell builds them: the defaults, the profile's `[drone]`
    /// table (a built-in name or a `.toml` file), then the file `config`. With `particles`,
    /// the particle filter runs too: a drone's tuning ([`particle_filter::drone_pf_config`])
    /// with that many particles, unless a `[particle_filter]` table of the files sets its own;
    /// `seed`, when given, is the filter's seed either way.
    ///
    /// # Errors
    /// [`SlamError::Config`] for an unknown profile or a field of either file that is unknown
    /// or of the wrong type.
    pub fn from_files(
        particles: Option<usize>,
        seed: Option<u64>,
        profile: Option<&str>,
        config: Option<&Path>,
    ) -> Result<Self, SlamError> {
        let mut settings = crate::profile::settings(Self::default(), "drone", profile, config)?;
        if let (Some(particles), None) = (particles, &settings.particle_filter) {
            settings.particle_filter = Some(RbpfConfig {
                particles,
                ..particle_filter::drone_pf_config(seed.unwrap_or(RbpfConfig::default().seed))
            });
        }
        if let (Some(pf), Some(seed)) = (settings.particle_filter.as_mut(), seed) {
            pf.seed = seed;
        }
        Ok(settings)
    }
}

/// What the session made of one scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanRecord {
    /// Time of the scan \[s\].
    pub timestamp: f64,
    /// The layered estimate, in the frame of the first scan (see [`DroneSlam::map_from_world`]).
    pub estimate: LayeredEstimate,
    /// The range pair the scan was matched with.
    pub range: Option<RangePair>,
}

/// The drone's online SLAM session.
///
/// ```
/// use slamkit_core::observation::{ImuSample, RangePair};
/// use slamkit_core::{LaserScan, Observation, Pose2};
/// use slamkit_slam::drone::{DroneSlam, DroneSlamConfig};
/// use slamkit_slam::TrackingStatus;
///
/// let mut session = DroneSlam::new(DroneSlamConfig::default())?;
/// let range = RangePair { timestamp: 0.0, up_m: Some(1.5), down_m: Some(1.0) };
/// let imu = ImuSample { timestamp: 0.0, roll_rad: 0.0, pitch_rad: 0.0, gyro_yaw_rad: Some(0.0) };
/// assert!(session.push(Observation::Range(range)).is_none()); // stored for the next scan
/// assert!(session.push(Observation::Imu(imu)).is_none());
/// // a scan in a 4 m wide corridor-like ring of walls
/// let scan = LaserScan {
///     timestamp: 0.0,
///     angle_min_rad: -std::f64::consts::PI,
///     angle_increment_rad: std::f64::consts::TAU / 360.0,
///     ranges_m: (0..360).map(|i| 2.0 + 0.5 * (i as f64 * 0.05).sin()).collect(),
///     max_range_m: 10.0,
///     odometry: None,
///     base_from_laser: Pose2::identity(),
/// };
/// let update = session.push(Observation::Scan(scan)).expect("a scan gives an update");
/// assert_eq!(update.status, TrackingStatus::Tracking);
/// let z = update.pose.expect("a pose").translation.z;
/// assert!(z > 0.9 && z < 1.2, "height from the down range finder: {z}");
/// assert_eq!(session.scans().len(), 1);
/// # Ok::<(), slamkit_slam::SlamError>(())
/// ```
pub struct DroneSlam {
    config: DroneSlamConfig,
    map_from_world: Pose2,
    slam: LayeredIcpSlam,
    readings: readings::Readings,
    pf: Option<DronePf>,
    /// The particle filter's best pose at the last scan (frame of the first scan).
    pf_pose: Option<Pose3>,
    scans: Vec<ScanRecord>,
    ignored: usize,
    /// In a saved map, until the drone is found in it.
    search: Option<in_map::Search>,
    /// The saved map the session started in; its keyframes never move.
    saved: Option<map::DroneMap>,
    /// How it was found (in a saved map).
    in_map_stats: Option<in_map::InMapStats>,
    /// Scans before the drone was found in a saved map (they have no record).
    unplaced: usize,
    /// Localisation in a saved map: the map is not changed.
    frozen: bool,
    gate: OdometryGate,
}

impl DroneSlam {
    /// A session starting at the map frame's origin.
    pub fn new(config: DroneSlamConfig) -> Result<Self, SlamError> {
        Self::with_initial_pose(config, Pose2::identity())
    }

    /// A session whose first scan is at `map_from_first` (x, y, heading in the map frame; the
    /// height is always measured from the floor).
    pub fn with_initial_pose(
        config: DroneSlamConfig,
        map_from_first: Pose2,
    ) -> Result<Self, SlamError> {
        let pf = config
            .particle_filter
            .clone()
            .map(DronePf::new)
            .transpose()?;
        config.odometry_gate.validate().map_err(SlamError::Config)?;
        Ok(Self {
            gate: OdometryGate::new(config.odometry_gate.clone()),
            slam: LayeredIcpSlam::new(config.layers.clone())?,
            config,
            map_from_world: map_from_first,
            readings: readings::Readings::default(),
            pf,
            pf_pose: None,
            scans: Vec::new(),
            ignored: 0,
            search: None,
            saved: None,
            in_map_stats: None,
            unplaced: 0,
            frozen: false,
        })
    }

    /// A session localising in `map`, which it never changes: the drone's start is unknown
    /// and found by a global search ([`in_map`]); layers the map lacks are mapped for the
    /// session's own use and not saved.
    ///
    /// # Errors
    /// [`SlamError`] for an invalid configuration, a map without keyframes, or one whose layers
    /// are of another height than the session's.
    pub fn localise(config: DroneSlamConfig, map: map::DroneMap) -> Result<Self, SlamError> {
        Self::in_map(config, map, true)
    }

    /// A session continuing `map`: the drone is found in it by a global search, then mapping
    /// goes on in its layers (the saved keyframes stay where they are).
    ///
    /// # Errors
    /// As [`DroneSlam::localise`].
    pub fn resume(config: DroneSlamConfig, map: map::DroneMap) -> Result<Self, SlamError> {
        Self::in_map(config, map, false)
    }

    fn in_map(
        config: DroneSlamConfig,
        map: map::DroneMap,
        frozen: bool,
    ) -> Result<Self, SlamError> {
        let search = in_map::Search::new(map.clone(), &config.layers, config.in_map.clone())?;
        let mut session = Self::new(config)?;
        session.search = Some(search);
        session.saved = Some(map);
        session.frozen = frozen;
        Ok(session)
    }

    /// A session with `config` fed every one of `observations` (in time order), calling
    /// `on_scan` after each scan: a whole recording or simulated flight at once.
    pub fn from_observations(
        config: DroneSlamConfig,
        observations: impl IntoIterator<Item = Observation>,
        mut on_scan: impl FnMut(),
    ) -> Result<Self, SlamError> {
        let mut session = Self::new(config)?;
        for observation in observations {
            if session.push(observation).is_some() {
                on_scan();
            }
        }
        Ok(session)
    }

    /// Takes one observation (in time order); returns an update for a scan, `None` for a
    /// reading stored for the next scan or an observation this session does not use.
    pub fn push(&mut self, observation: Observation) -> Option<Update> {
        match observation {
            Observation::Scan(mut scan) => {
                let odometry = scan.odometry.filter(is_finite_pose);
                scan.odometry = self.gate.filter(scan.timestamp, odometry);
                Some(self.scan(&scan))
            }
            Observation::Range(r) => {
                self.readings.range(r);
                None
            }
            Observation::Imu(i) => {
                self.readings.imu(i);
                None
            }
            Observation::Flow(f) => {
                self.readings.flow(f);
                None
            }
            Observation::Odometry(_) | Observation::Rgbd(_) | Observation::Stereo(_) => {
                self.ignored += 1;
                None
            }
        }
    }

    fn scan(&mut self, scan: &LaserScan) -> Update {
        let (input, range) = self.readings.input(scan);
        if let Some(search) = &mut self.search {
            let found = search.find(&input);
            self.in_map_stats = Some(search.stats);
            let Some(fix) = found else {
                self.unplaced += 1;
                return Update {
                    timestamp: scan.timestamp,
                    pose: None,
                    status: TrackingStatus::Initialising,
                    map: MapChange::default(),
                };
            };
            let saved = search.saved();
            self.slam
                .start_in_saved_map(saved, fix, scan.timestamp, self.frozen);
            self.search = None;
            if let Some(stats) = &mut self.in_map_stats {
                stats.found_at_scan = Some(self.unplaced);
            }
        }
        let keyframes = self.slam.keyframes().len();
        let relocalisations = self.slam.stats().relocalisations;
        let estimate = self.slam.process(&input);
        if let Some(pf) = &mut self.pf {
            self.pf_pose = pf.push(scan, &estimate);
        }
        self.scans.push(ScanRecord {
            timestamp: scan.timestamp,
            estimate,
            range,
        });
        let moved = self.slam.stats().relocalisations - relocalisations;
        Update {
            timestamp: scan.timestamp,
            pose: Some(self.to_map(&estimate.world_from_base)),
            status: tracking_status(&estimate.status),
            map: MapChange {
                keyframes_added: self.slam.keyframes().len() - keyframes,
                loop_closures: moved,
                map_moved: moved > 0,
            },
        }
    }

    fn to_map(&self, world_from_base: &Pose3) -> Pose3 {
        pose2_to_pose3(&self.map_from_world) * world_from_base
    }

    /// The settings.
    pub fn config(&self) -> &DroneSlamConfig {
        &self.config
    }

    /// The map frame seen from the frame of the first scan, in which [`ScanRecord::estimate`],
    /// [`Self::layered`] and [`particle_filter::DronePf`] give their poses.
    pub fn map_from_world(&self) -> Pose3 {
        pose2_to_pose3(&self.map_from_world)
    }

    /// Every scan so far, in order.
    pub fn scans(&self) -> &[ScanRecord] {
        &self.scans
    }

    /// The layered estimates of every scan so far (frame of the first scan).
    pub fn estimates(&self) -> Vec<LayeredEstimate> {
        self.scans.iter().map(|s| s.estimate).collect()
    }

    /// The pose estimated at every scan so far, in the map frame.
    pub fn trajectory(&self) -> Trajectory {
        let mut trajectory = Trajectory::new();
        for s in &self.scans {
            trajectory.push(s.timestamp, self.to_map(&s.estimate.world_from_base));
        }
        trajectory
    }

    /// The layered mapper (its maps, keyframes, counters and timings; frame of the first scan).
    pub fn layered(&self) -> &LayeredIcpSlam {
        &self.slam
    }

    /// Counters of the layered mapper.
    pub fn stats(&self) -> &LayeredStats {
        self.slam.stats()
    }

    /// Per-stage timings of the layered mapper.
    pub fn timings(&self) -> &StageTimings {
        self.slam.timings()
    }

    /// The map of every layer visited, lowest first, in the map frame.
    pub fn layer_maps(&self) -> Vec<LayerMap> {
        let map_from_world = self.map_from_world();
        self.slam
            .layer_maps()
            .into_iter()
            .map(|m| LayerMap {
                points: m.points.iter().map(|p| map_from_world * p).collect(),
                ..m
            })
            .collect()
    }

    /// The points of every layer's map in one cloud, in the map frame.
    pub fn merged_cloud(&self) -> Vec<Point3<f64>> {
        self.layer_maps()
            .into_iter()
            .flat_map(|m| m.points)
            .collect()
    }

    /// The particle filter, when configured.
    pub fn particle_filter(&self) -> Option<&DronePf> {
        self.pf.as_ref()
    }

    /// The particle filter's best pose at the last scan, in the map frame: its best particle's
    /// at its last update moved by the layered increments since (`None` without a particle
    /// filter or before its first usable scan).
    pub fn pf_pose(&self) -> Option<Pose3> {
        self.pf_pose.map(|p| self.to_map(&p))
    }

    /// The particle filter's trajectory over every scan so far, smoothed through its best
    /// particle's ancestry, in the map frame; `None` without a particle filter.
    pub fn pf_trajectory(&self) -> Option<Trajectory> {
        let pf = self.pf.as_ref()?;
        let mut trajectory = Trajectory::new();
        for (s, pose) in self.scans.iter().zip(pf.trajectory(&self.estimates())) {
            trajectory.push(s.timestamp, self.to_map(&pose));
        }
        Some(trajectory)
    }

    /// Observations of kinds this session does not use (odometry, images), ignored.
    pub fn ignored(&self) -> usize {
        self.ignored
    }

    /// Odometry readings taken as no motion: jumps faster than `odometry_gate` allows.
    pub fn odometry_rejected(&self) -> usize {
        self.gate.rejected()
    }

    /// In a saved map: how the search for the drone went (`None` for a new map).
    pub fn in_map_stats(&self) -> Option<in_map::InMapStats> {
        self.in_map_stats
    }

    /// Scans pushed before the drone was found in a saved map; [`Self::scans`] begins after
    /// them.
    pub fn unplaced_scans(&self) -> usize {
        self.unplaced
    }

    /// The map as it stands, in the map frame: the layers' keyframes. Localising, the saved
    /// map as loaded (the layers the map lacks, mapped for the session's own use, are left
    /// out); continuing, the saved keyframes with the new ones.
    pub fn map(&self) -> map::DroneMap {
        let mut map = match &self.saved {
            Some(saved) => saved.clone(),
            None => map::DroneMap {
                config: self.config.clone(),
                layers: BTreeMap::new(),
            },
        };
        if self.frozen || self.search.is_some() {
            return map;
        }
        let new = self.slam.keyframes().iter().skip(self.slam.loaded().count);
        for k in new {
            map.layers
                .entry(k.layer)
                .or_default()
                .push(map::SavedKeyframe {
                    time_s: k.time_s,
                    map_from_base: self.map_from_world * k.keyframe.world_from_base,
                    points: k.keyframe.points.clone(),
                });
        }
        map
    }
}

impl Session for DroneSlam {
    fn push(&mut self, observation: Observation) -> Option<Update> {
        DroneSlam::push(self, observation)
    }

    /// Writes the layers' keyframes (one section per layer) and the settings
    /// ([`DroneSlam::map`]).
    fn save(&self, path: &Path) -> Result<(), SlamError> {
        self.map()
            .to_map_file()
            .and_then(|file| file.save(path))
            .map_err(|source| SlamError::MapFile {
                path: path.to_path_buf(),
                source,
            })
    }
}

/// How far to trust the pose of a scan used as `status` says.
fn tracking_status(status: &LayerScanStatus) -> TrackingStatus {
    match status {
        LayerScanStatus::NoHeight => TrackingStatus::Initialising,
        LayerScanStatus::Tilted => TrackingStatus::Predicted,
        LayerScanStatus::Slam(s) => crate::lidar::icp_status(*s),
    }
}

#[cfg(test)]
mod tests;
