//! [`LidarSlam`]: 2D lidar SLAM as an online session, and localisation in or continuation of a
//! saved map.
//!
//! Three ways to start:
//! * [`LidarSlam::new`]: map from scratch, by ICP-SLAM ([`slamkit_lidar::icp_slam`]: scan-to-map
//!   ICP, keyframes, loop closure, pose graph) or a Rao-Blackwellised particle filter
//!   ([`slamkit_lidar::rbpf`]).
//! * [`LidarSlam::localise`]: localisation only in a saved map. The start pose is unknown: a
//!   global search ([`slamkit_lidar::global_search`]) finds the robot in the map, then every
//!   scan is matched by ICP against the whole map, which never changes. After
//!   `lost_after_failures` scans in a row that do not match, the robot is lost and the global
//!   search runs again.
//! * [`LidarSlam::resume`]: continue a saved map: the robot is found as in localisation, then
//!   ICP-SLAM goes on from there, its new keyframes chained to the old map and joined to the
//!   rest of it by loop closure.
//!
//! Scans from a source (a log, a bag, a driver) go in as [`Observation::Scan`]; odometry comes
//! with each scan (`LaserScan::odometry`), as in CARMEN logs and `scan`+`odom` pairs in ROS.
//! [`preflight`] checks a log and the settings before a run (no usable scan; the particle
//! maps' memory).

pub mod map;
pub mod preflight;
pub mod run_report;

use crate::map_file::{MapFile, MapFileError};
use crate::odometry_gate::{OdometryGate, OdometryGateConfig};
use crate::session::{MapChange, Session, TrackingStatus, Update};
use crate::SlamError;
pub use map::{LidarMap, MapKeyframe, MapScan};
use serde::{Deserialize, Serialize};
use slamkit_core::pose::pose2_to_pose3;
use slamkit_core::{LaserScan, Observation, Pose2, StageTimings, Trajectory};
use slamkit_lidar::global_search::{GlobalOutcome, GlobalSearch, GlobalSearchConfig};
use slamkit_lidar::icp_slam::{IcpSlam, IcpSlamConfig, LocaliseOptions, ScanStatus};
use slamkit_lidar::motion::{is_finite_pose, ScanOdometry};
use slamkit_lidar::particles::moved_enough;
use slamkit_lidar::pose_graph::Edge;
use slamkit_lidar::rbpf::{interpolate_poses, Rbpf, RbpfConfig};
use slamkit_map::{OccupancyGrid, OccupancyGridConfig};
use std::path::Path;
use std::time::Instant;

/// The mapping method of a new map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LidarMethod {
    /// ICP-SLAM with loop closure.
    Icp,
    /// Rao-Blackwellised particle filter.
    Rbpf,
}

/// Settings of a [`LidarSlam`] session.
///
/// Basic (what a new robot needs): `icp.min_range_m` / `icp.max_range_m` (the lidar's usable
/// ranges), `icp.use_odometry` (false without wheel odometry), `icp.map_voxel_m` (map
/// resolution). The rest is advanced; the defaults are neutral.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LidarSlamConfig {
    /// How a new map is built.
    pub method: LidarMethod,
    /// ICP-SLAM, and the scan matching of localisation and continuation.
    pub icp: IcpSlamConfig,
    /// The particle filter.
    pub rbpf: RbpfConfig,
    /// Finding the robot in a saved map.
    pub global_search: GlobalSearchConfig,
    /// While the robot is not found, the search is tried again once odometry says it moved
    /// this far since the last try \[m\] (a new view may settle what the last left
    /// ambiguous; each search costs tenths of a second on a building-sized map)...
    pub search_after_m: f64,
    /// ...or turned this much \[rad\]...
    pub search_after_rad: f64,
    /// ...or, when the scans carry no odometry, every this many scans.
    pub search_every_scans: usize,
    /// Matching in a saved map.
    pub localise: LocaliseOptions,
    /// Localisation: after this many scans in a row without a match the robot is lost.
    pub lost_after_failures: usize,
    /// Odometry jumps the robot cannot have made are taken as no motion (basic: the robot's
    /// top speed).
    pub odometry_gate: OdometryGateConfig,
}

impl Default for LidarSlamConfig {
    fn default() -> Self {
        Self {
            method: LidarMethod::Icp,
            icp: IcpSlamConfig::default(),
            rbpf: RbpfConfig::default(),
            global_search: GlobalSearchConfig::default(),
            search_after_m: 0.5,
            search_after_rad: 0.5,
            search_every_scans: 20,
            localise: LocaliseOptions::default(),
            lost_after_failures: 10,
            odometry_gate: OdometryGateConfig::default(),
        }
    }
}

impl LidarSlamConfig {
    /// A session's settings as a shell builds them: the defaults with the profile's `[lidar]`
    /// table (a built-in name or a `.toml` file), then the file `config` laid over the method's
    /// part for a new map (ICP-SLAM's for [`LidarMethod::Icp`], the particle filter's for
    /// [`LidarMethod::Rbpf`], as the batch runs took them) or over the whole session's
    /// (`[icp]`, `[global_search]`, `[localise]`, ...) in a saved map.
    ///
    /// # Errors
    /// [`SlamError::Config`] for an unknown profile or a field of either file that is unknown
    /// or of the wrong type.
    pub fn from_files(
        method: LidarMethod,
        in_saved_map: bool,
        profile: Option<&str>,
        config: Option<&Path>,
    ) -> Result<Self, SlamError> {
        use crate::profile::file_over;
        let mut settings = crate::profile::settings(Self::default(), "lidar", profile, None)?;
        if in_saved_map {
            return file_over(settings, config);
        }
        settings.method = method;
        match method {
            LidarMethod::Icp => settings.icp = file_over(settings.icp, config)?,
            LidarMethod::Rbpf => settings.rbpf = file_over(settings.rbpf, config)?,
        }
        Ok(settings)
    }
}

/// Counters of a session.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct LidarSessionStats {
    /// Scans received.
    pub scans: usize,
    /// Observations of kinds this session does not use (IMU, images, ...).
    pub ignored: usize,
    /// Global searches run (localisation and continuation).
    pub global_searches: usize,
    /// Searches whose best pose was matched as well by a distinct one.
    pub ambiguous_searches: usize,
    /// Times the robot was found in the map.
    pub fixes: usize,
    /// Times localisation lost the robot.
    pub losses: usize,
    /// Index of the scan of the first fix.
    pub first_fix_scan: Option<usize>,
    /// Odometry readings the robot cannot have driven, taken as no motion
    /// ([`crate::odometry_gate`]).
    pub odometry_rejected: usize,
}

/// Scan counts of a session.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct FrameCounts {
    /// Scans matched (filter updates for the particle filter).
    pub processed: usize,
    /// Scans not used: too few usable points, the particle filter waiting for motion, or the
    /// robot not found yet in a saved map.
    pub skipped: usize,
    /// Scans whose match failed; their pose is a prediction.
    pub failed: usize,
}

/// A view of a new ICP-SLAM map as it grows ([`LidarSlam::live_map`]).
#[derive(Debug, Clone, Copy)]
pub struct LiveMap<'a> {
    /// Every keyframe at its current pose, in the order made.
    pub keyframes: &'a [slamkit_lidar::point_map::Keyframe],
    /// The scan of each keyframe.
    pub scans: &'a [LaserScan],
    /// The pose graph's edges, in the order added.
    pub edges: &'a [Edge],
}

/// Inserts scans at their poses (`world_from_base`) into a fresh occupancy grid.
pub fn grid_of_scans<'a>(
    scans: impl IntoIterator<Item = (&'a LaserScan, Pose2)>,
    config: OccupancyGridConfig,
) -> Result<OccupancyGrid, SlamError> {
    let mut grid = OccupancyGrid::new(config)?;
    for (scan, pose) in scans {
        grid.insert_scan(scan, &(pose * scan.base_from_laser))?;
    }
    Ok(grid)
}

/// A 2D lidar session: SLAM, or localisation in / continuation of a saved map.
///
/// ```
/// use slamkit_core::{Observation, Pose2};
/// use slamkit_lidar::sim_scan::SegmentWorld;
/// use slamkit_slam::{LidarSlam, LidarSlamConfig, Session, TrackingStatus};
///
/// let world = SegmentWorld::room();
/// let mut slam = LidarSlam::new(LidarSlamConfig::default(), Pose2::identity())?;
/// let mut last = None;
/// for i in 0..20 {
///     let mut scan = world.scan(&Pose2::new([0.05 * i as f64, 0.0].into(), 0.0), 361, 4.7, 20.0);
///     scan.timestamp = 0.1 * i as f64;
///     last = slam.push(Observation::Scan(scan));
/// }
/// let update = last.expect("a scan always gives an update");
/// assert_eq!(update.status, TrackingStatus::Tracking);
/// let x = update.pose.expect("tracking").translation.vector.x;
/// assert!((x - 0.95).abs() < 0.02, "{x}");
/// # Ok::<(), slamkit_slam::SlamError>(())
/// ```
pub struct LidarSlam {
    config: LidarSlamConfig,
    mode: Mode,
    /// Every scan's time and online pose.
    online: Vec<(f64, Option<Pose2>)>,
    /// Each scan's odometry reading, when it has one.
    odometry: Vec<Option<Pose2>>,
    gate: OdometryGate,
    stats: LidarSessionStats,
    timings: StageTimings,
}

enum Mode {
    /// A new map by ICP-SLAM; `scans` holds each keyframe's scan.
    Icp {
        slam: Box<IcpSlam>,
        scans: Vec<LaserScan>,
    },
    /// A new map by the particle filter; it keeps every scan to save the best particle's map.
    Rbpf(Box<ParticleRun>),
    /// Localisation in, or continuation of, a saved map.
    InMap(Box<InMap>),
}

struct ParticleRun {
    filter: Rbpf,
    /// Scan-to-scan ICP odometry once a scan came without wheel odometry, and the odometry
    /// pose it started from.
    scan_odometry: Option<(ScanOdometry, Pose2)>,
    /// Odometry pose of every scan (wheel or scan-to-scan).
    poses: Vec<Pose2>,
    scans: Vec<LaserScan>,
}

struct InMap {
    map: LidarMap,
    /// The map's keyframes as the matchers use them (points and normals), computed once.
    keyframes: Vec<slamkit_lidar::point_map::Keyframe>,
    search: GlobalSearch,
    /// Continue mapping once found, rather than localise.
    extend: bool,
    /// The matcher once the robot is found, and the index of its first scan.
    tracker: Option<(Box<IcpSlam>, usize)>,
    /// Scans since the last global search, and the odometry of its scan.
    since_search: Option<(usize, Option<Pose2>)>,
    /// The scans of the keyframes the tracker added (continuation).
    new_scans: Vec<LaserScan>,
}

impl LidarSlam {
    /// A session building a new map, the robot starting at `initial_pose` (the map frame's
    /// origin is where the robot starts when this is the identity).
    pub fn new(config: LidarSlamConfig, initial_pose: Pose2) -> Result<Self, SlamError> {
        config.odometry_gate.validate().map_err(SlamError::Config)?;
        let mode = match config.method {
            LidarMethod::Icp => Mode::Icp {
                slam: Box::new(IcpSlam::starting_at(config.icp.clone(), initial_pose)?),
                scans: Vec::new(),
            },
            LidarMethod::Rbpf => Mode::Rbpf(Box::new(ParticleRun {
                filter: Rbpf::new(config.rbpf.clone())?,
                scan_odometry: None,
                poses: Vec::new(),
                scans: Vec::new(),
            })),
        };
        Ok(Self::with_mode(config, mode))
    }

    /// A session localising in `map`, which it never changes; the start pose is found by
    /// global search.
    pub fn localise(config: LidarSlamConfig, map: LidarMap) -> Result<Self, SlamError> {
        Self::in_map(config, map, false)
    }

    /// A session continuing `map`: the robot is found in it by global search, then mapping
    /// goes on from there.
    pub fn resume(config: LidarSlamConfig, map: LidarMap) -> Result<Self, SlamError> {
        Self::in_map(config, map, true)
    }

    fn in_map(config: LidarSlamConfig, map: LidarMap, extend: bool) -> Result<Self, SlamError> {
        config.odometry_gate.validate().map_err(SlamError::Config)?;
        if map.keyframes.is_empty() {
            return Err(SlamError::Map("the map holds no keyframe".into()));
        }
        let start = Instant::now();
        let keyframes = map.matcher_keyframes(&config.icp);
        let search = GlobalSearch::new(&keyframes, config.global_search.clone())?;
        let mut timings = StageTimings::default();
        timings.record_since("prepare_map", start);
        let mode = Mode::InMap(Box::new(InMap {
            map,
            keyframes,
            search,
            extend,
            tracker: None,
            since_search: None,
            new_scans: Vec::new(),
        }));
        let mut session = Self::with_mode(config, mode);
        session.timings = timings;
        Ok(session)
    }

    fn with_mode(config: LidarSlamConfig, mode: Mode) -> Self {
        Self {
            gate: OdometryGate::new(config.odometry_gate.clone()),
            config,
            mode,
            online: Vec::new(),
            odometry: Vec::new(),
            stats: LidarSessionStats::default(),
            timings: StageTimings::default(),
        }
    }

    /// Takes one scan; returns the update it gives.
    pub fn push_scan(&mut self, mut scan: LaserScan) -> Update {
        let index = self.stats.scans;
        self.stats.scans += 1;
        scan.odometry = self
            .gate
            .filter(scan.timestamp, scan.odometry.filter(is_finite_pose));
        self.stats.odometry_rejected = self.gate.rejected();
        self.odometry.push(scan.odometry);
        let timestamp = scan.timestamp;
        let (pose, status, map) = match &mut self.mode {
            Mode::Icp { slam, scans } => {
                let before = slam.keyframes().len();
                let closures = slam.stats().loop_closures;
                let est = slam.process(&scan);
                let added = slam.keyframes().len() - before;
                if added > 0 {
                    scans.push(scan);
                }
                let closed = slam.stats().loop_closures - closures;
                let change = MapChange {
                    keyframes_added: added,
                    loop_closures: closed,
                    map_moved: closed > 0,
                };
                (Some(est.world_from_base), icp_status(est.status), change)
            }
            Mode::Rbpf(run) => run.push(index, scan, &self.config),
            Mode::InMap(in_map) => in_map.push(
                index,
                scan,
                &self.config,
                &mut self.stats,
                &mut self.timings,
            ),
        };
        self.online.push((timestamp, pose));
        Update {
            timestamp,
            pose: pose.map(|p| pose2_to_pose3(&p)),
            status,
            map,
        }
    }

    /// Every scan's pose as the session now knows it (`None` where it has none): for a new
    /// ICP-SLAM map, the poses follow the optimised keyframes; for the particle filter, the
    /// best particle's path (between its updates, odometry); in a saved map, the poses found
    /// online, and the scans before the first fix placed by odometry from it when the scans
    /// carry odometry.
    pub fn poses(&self) -> Vec<Option<Pose2>> {
        match &self.mode {
            Mode::Icp { slam, .. } => slam.poses().into_iter().map(Some).collect(),
            Mode::Rbpf(run) => {
                let poses = interpolate_poses(&run.filter.best_updates(), &run.poses);
                poses.into_iter().map(Some).collect()
            }
            Mode::InMap(in_map) => {
                let mut poses: Vec<Option<Pose2>> = self.online.iter().map(|(_, p)| *p).collect();
                if let Some((tracker, first)) = &in_map.tracker {
                    for (pose, slot) in tracker.poses().iter().zip(poses.iter_mut().skip(*first)) {
                        *slot = Some(*pose);
                    }
                }
                backfill_by_odometry(&mut poses, &self.odometry);
                poses
            }
        }
    }

    /// [`LidarSlam::poses`] with the scans' times, the scans without a pose left out.
    pub fn trajectory(&self) -> Trajectory {
        let mut trajectory = Trajectory::new();
        for ((t, _), pose) in self.online.iter().zip(self.poses()) {
            if let Some(pose) = pose {
                trajectory.push(*t, pose2_to_pose3(&pose));
            }
        }
        trajectory
    }

    /// The occupancy grid that shows the session's map, given every scan it was pushed in
    /// order: the saved map's when localising (it is not changed), the particle filter's best
    /// map, or every scan at its estimated pose (ICP-SLAM, continuation).
    pub fn output_grid(&self, scans: &[LaserScan]) -> Result<OccupancyGrid, SlamError> {
        if let Mode::InMap(in_map) = &self.mode {
            if !in_map.extend {
                return in_map.map.grid(OccupancyGridConfig::default());
            }
        }
        if let Some(grid) = self.particle_grid() {
            return Ok(grid.clone());
        }
        let posed = scans
            .iter()
            .zip(self.poses())
            .filter_map(|(scan, pose)| Some((scan, pose?)));
        grid_of_scans(posed, OccupancyGridConfig::default())
    }

    /// True for a session continuing a saved map ([`Self::resume`]).
    pub fn continues_a_map(&self) -> bool {
        matches!(&self.mode, Mode::InMap(in_map) if in_map.extend)
    }

    /// The particle filter's best map, when the session runs one.
    pub fn particle_grid(&self) -> Option<&OccupancyGrid> {
        match &self.mode {
            Mode::Rbpf(run) => run.filter.best_map(),
            _ => None,
        }
    }

    /// Scans matched, skipped (too few usable points, or before the robot was found in a
    /// saved map) and failed (no match; pose predicted), so far.
    pub fn frame_counts(&self) -> FrameCounts {
        let scans = self.stats.scans;
        match &self.mode {
            Mode::Icp { slam, .. } => {
                let s = slam.stats();
                FrameCounts {
                    processed: s.scans_processed,
                    skipped: s.scans_skipped,
                    failed: s.matches_failed,
                }
            }
            Mode::Rbpf(run) => {
                let s = run.filter.stats();
                FrameCounts {
                    processed: s.updates,
                    skipped: s.scans_skipped,
                    failed: 0,
                }
            }
            Mode::InMap(in_map) => {
                let (processed, failed) = in_map.tracker.as_ref().map_or((0, 0), |(t, _)| {
                    (t.stats().scans_processed, t.stats().matches_failed)
                });
                FrameCounts {
                    processed,
                    skipped: scans - processed,
                    failed,
                }
            }
        }
    }

    /// The map as it stands: keyframes at their current poses and the pose graph.
    pub fn map(&self) -> LidarMap {
        match &self.mode {
            Mode::Icp { slam, scans } => {
                let mut map = map_of(slam, &[], scans);
                map.scans = map_scans(&self.online, slam.anchors(), 0);
                map
            }
            Mode::Rbpf(run) => run.map(&self.config),
            Mode::InMap(in_map) => match (&in_map.tracker, in_map.extend) {
                (Some((tracker, first)), true) => {
                    let mut map = map_of(tracker, &in_map.map.keyframes, &in_map.new_scans);
                    map.scans = in_map.map.scans.clone();
                    map.scans
                        .extend(map_scans(&self.online, tracker.anchors(), *first));
                    map
                }
                _ => in_map.map.clone(),
            },
        }
    }

    /// The map as it stands as a map file, its header noting how it was made; what
    /// [`Session::save`] writes (build it once to write it to several places).
    pub fn map_file(&self) -> Result<MapFile, MapFileError> {
        let notes = serde_json::json!({
            "method": match (&self.mode, self.config.method) {
                (Mode::InMap(m), _) if m.extend => "icp (continued)",
                (Mode::InMap(_), _) => "loaded",
                (_, LidarMethod::Icp) => "icp",
                (_, LidarMethod::Rbpf) => "rbpf",
            },
            "scans": self.stats.scans,
        });
        self.map().to_new_file(notes)
    }

    /// The growing parts of a new ICP-SLAM map, which only ever gain keyframes and edges (the
    /// keyframes' poses change when loop closure optimises the graph): what
    /// [`crate::map_updates::UpdateOutbox`] sends incrementally. `None` for the particle filter
    /// (its map is drawn from the best particle at the end) and in a saved map.
    pub fn live_map(&self) -> Option<LiveMap<'_>> {
        match &self.mode {
            Mode::Icp { slam, scans } => Some(LiveMap {
                keyframes: slam.keyframes(),
                scans,
                edges: slam.graph().edges(),
            }),
            _ => None,
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> LidarSessionStats {
        self.stats
    }

    /// The settings in use.
    pub fn config(&self) -> &LidarSlamConfig {
        &self.config
    }

    /// Counters of the mapper or matcher underneath, as JSON (ICP-SLAM's or the particle
    /// filter's).
    pub fn method_stats(&self) -> serde_json::Value {
        let json = |v: Result<serde_json::Value, serde_json::Error>| v.unwrap_or_default();
        match &self.mode {
            Mode::Icp { slam, .. } => json(serde_json::to_value(slam.stats())),
            Mode::Rbpf(run) => json(serde_json::to_value(run.filter.stats())),
            Mode::InMap(in_map) => in_map
                .tracker
                .as_ref()
                .map(|(t, _)| json(serde_json::to_value(t.stats())))
                .unwrap_or_default(),
        }
    }

    /// Per-stage timings so far (the session's own and the method's).
    pub fn timings(&self) -> StageTimings {
        let mut all = self.timings.clone();
        match &self.mode {
            Mode::Icp { slam, .. } => all.merge(slam.timings()),
            Mode::Rbpf(run) => all.merge(run.filter.timings()),
            Mode::InMap(in_map) => {
                if let Some((t, _)) = &in_map.tracker {
                    all.merge(t.timings());
                }
            }
        }
        all
    }
}

impl Session for LidarSlam {
    fn push(&mut self, observation: Observation) -> Option<Update> {
        match observation {
            Observation::Scan(scan) => Some(self.push_scan(scan)),
            _ => {
                self.stats.ignored += 1;
                None
            }
        }
    }

    fn save(&self, path: &Path) -> Result<(), SlamError> {
        self.map_file()
            .and_then(|f| f.save(path))
            .map_err(|source| SlamError::MapFile {
                path: path.to_path_buf(),
                source,
            })
    }
}

impl ParticleRun {
    fn push(
        &mut self,
        index: usize,
        scan: LaserScan,
        config: &LidarSlamConfig,
    ) -> (Option<Pose2>, TrackingStatus, MapChange) {
        // Wheel odometry while every scan has had it (the batch run's rule, online); from the
        // first scan without, scan-to-scan ICP odometry continues from the last pose.
        let wheel = scan.odometry.filter(is_finite_pose);
        let use_wheel = config.rbpf.use_odometry && self.scan_odometry.is_none();
        let odometry = match (wheel, use_wheel) {
            (Some(pose), true) => pose,
            _ => {
                let last = self.poses.last().copied().unwrap_or_else(Pose2::identity);
                let (icp, base) = self.scan_odometry.get_or_insert_with(|| {
                    (ScanOdometry::new(config.rbpf.scan_odometry.clone()), last)
                });
                *base * icp.push(&scan)
            }
        };
        let step = self.filter.process(index, &scan, &odometry);
        self.poses.push(odometry);
        self.scans.push(scan);
        // The best particle's last update, without walking its ancestry (which grows with
        // every update: walking it at every scan made the session quadratic in the log).
        let best = self.filter.best_pose();
        let pose = best.and_then(|(at, pose)| {
            let then = self.poses.get(at)?;
            Some(pose * (then.inverse() * odometry))
        });
        let status = match step {
            slamkit_lidar::rbpf::RbpfStep::Skipped => TrackingStatus::Predicted,
            _ if pose.is_none() => TrackingStatus::Initialising,
            _ => TrackingStatus::Tracking,
        };
        let updated = step == slamkit_lidar::rbpf::RbpfStep::Updated;
        let change = MapChange {
            keyframes_added: usize::from(updated),
            loop_closures: 0,
            map_moved: updated,
        };
        (pose, status, change)
    }

    /// The best particle's path as keyframes: a scan wherever the robot moved or turned as far
    /// as ICP-SLAM's keyframe rule asks, chained by the path's increments.
    fn map(&self, config: &LidarSlamConfig) -> LidarMap {
        let poses = interpolate_poses(&self.filter.best_updates(), &self.poses);
        let icp = &config.icp;
        let mut map = LidarMap::default();
        let mut last: Option<Pose2> = None;
        for (scan, pose) in self.scans.iter().zip(&poses) {
            map.scans.push(map::MapScan {
                timestamp: scan.timestamp,
                keyframe: map.keyframes.len().checked_sub(1),
                keyframe_from_base: last.map_or(*pose, |l| l.inverse() * pose),
            });
            let far = last.map_or(true, |l| {
                moved_enough(
                    &(l.inverse() * pose),
                    icp.insertion_linear_m,
                    icp.insertion_angular_rad,
                )
            });
            if !far || icp.scan_points(scan).len() < icp.min_scan_points {
                continue;
            }
            if let Some(l) = last {
                let to = map.keyframes.len();
                map.edges.push(Edge {
                    from: to - 1,
                    to,
                    from_from_to: l.inverse() * pose,
                    information: icp.loop_closure.edge_information(),
                    robust_scale: None,
                });
            }
            map.keyframes.push(MapKeyframe {
                world_from_base: *pose,
                scan: LaserScan {
                    odometry: None,
                    ..scan.clone()
                },
            });
            if let Some(newest) = map.scans.last_mut() {
                newest.keyframe = Some(map.keyframes.len() - 1);
                newest.keyframe_from_base = Pose2::identity();
            }
            last = Some(*pose);
        }
        map
    }
}

impl InMap {
    fn push(
        &mut self,
        index: usize,
        scan: LaserScan,
        config: &LidarSlamConfig,
        stats: &mut LidarSessionStats,
        timings: &mut StageTimings,
    ) -> (Option<Pose2>, TrackingStatus, MapChange) {
        if let Some((tracker, _)) = &mut self.tracker {
            let before = tracker.keyframes().len();
            let closures = tracker.stats().loop_closures;
            let est = tracker.process(&scan);
            let added = tracker.keyframes().len() - before;
            if added > 0 {
                self.new_scans.push(scan);
            }
            let closed = tracker.stats().loop_closures - closures;
            let change = MapChange {
                keyframes_added: added,
                loop_closures: closed,
                map_moved: closed > 0,
            };
            let lost = !self.extend && tracker.failures_in_a_row() >= config.lost_after_failures;
            if lost {
                stats.losses += 1;
                self.tracker = None;
                self.since_search = None;
                return (None, TrackingStatus::Lost, change);
            }
            return (Some(est.world_from_base), icp_status(est.status), change);
        }
        let waiting = (None, TrackingStatus::Initialising, MapChange::default());
        let odometry = scan.odometry.filter(is_finite_pose);
        let due = match self.since_search {
            None => true,
            Some((_, Some(then))) if odometry.is_some() => odometry.is_some_and(|now| {
                moved_enough(
                    &(then.inverse() * now),
                    config.search_after_m,
                    config.search_after_rad,
                )
            }),
            Some((n, _)) => n + 1 >= config.search_every_scans.max(1),
        };
        if !due {
            if let Some((n, _)) = &mut self.since_search {
                *n += 1;
            }
            return waiting;
        }
        self.since_search = Some((0, odometry));
        let points = config.icp.scan_points(&scan);
        if points.len() < config.icp.min_scan_points {
            return waiting;
        }
        let start = Instant::now();
        stats.global_searches += 1;
        let outcome = self.search.search(&points);
        timings.record_since("global_search", start);
        let fix = match outcome {
            GlobalOutcome::Found(fix) => fix,
            GlobalOutcome::Ambiguous { .. } => {
                stats.ambiguous_searches += 1;
                return waiting;
            }
            GlobalOutcome::NotFound(_) => return waiting,
        };
        stats.fixes += 1;
        stats.first_fix_scan.get_or_insert(index);
        let keyframes = self.keyframes.clone();
        let tracker = if self.extend {
            let edges = self.map.edges.clone();
            IcpSlam::resume(config.icp.clone(), keyframes, edges, fix.world_from_base)
        } else {
            IcpSlam::localise_only(
                config.icp.clone(),
                keyframes,
                fix.world_from_base,
                config.localise.clone(),
            )
        };
        let Ok(mut tracker) = tracker else {
            return waiting;
        };
        // The fixing scan is matched once more by the tracker, from the fix.
        let est = tracker.process(&scan);
        self.tracker = Some((Box::new(tracker), index));
        (
            Some(est.world_from_base),
            icp_status(est.status),
            MapChange::default(),
        )
    }
}

/// The tracking status of an ICP-SLAM scan status.
pub(crate) fn icp_status(status: ScanStatus) -> TrackingStatus {
    match status {
        ScanStatus::Initialised
        | ScanStatus::Matched
        | ScanStatus::MatchedCorrelative
        | ScanStatus::Unmoved => TrackingStatus::Tracking,
        ScanStatus::MatchFailed | ScanStatus::Skipped => TrackingStatus::Predicted,
    }
}

/// The map of an ICP-SLAM run whose first keyframes are `old` (a resumed map's) and the rest
/// were made from `new_scans`: keyframes at their optimised poses and every graph edge.
fn map_of(slam: &IcpSlam, old: &[MapKeyframe], new_scans: &[LaserScan]) -> LidarMap {
    let scans = old
        .iter()
        .map(|kf| &kf.scan)
        .chain(new_scans.iter())
        .map(|scan| LaserScan {
            odometry: None,
            ..scan.clone()
        });
    LidarMap {
        keyframes: slam
            .keyframes()
            .iter()
            .zip(scans)
            .map(|(kf, scan)| MapKeyframe {
                world_from_base: kf.world_from_base,
                scan,
            })
            .collect(),
        edges: slam.graph().edges().to_vec(),
        scans: Vec::new(),
    }
}

/// The scans from `first` on, following the keyframes `anchors` name.
fn map_scans(
    online: &[(f64, Option<Pose2>)],
    anchors: &[(Option<usize>, Pose2)],
    first: usize,
) -> Vec<map::MapScan> {
    online
        .iter()
        .skip(first)
        .zip(anchors)
        .map(
            |((timestamp, _), (keyframe, keyframe_from_base))| map::MapScan {
                timestamp: *timestamp,
                keyframe: *keyframe,
                keyframe_from_base: *keyframe_from_base,
            },
        )
        .collect()
}

/// Places the scans before the first known pose by odometry from it, as long as the scans
/// carry odometry back to it.
fn backfill_by_odometry(poses: &mut [Option<Pose2>], odometry: &[Option<Pose2>]) {
    let Some(first) = poses.iter().position(Option::is_some) else {
        return;
    };
    let (Some(Some(anchor)), Some(Some(anchor_odometry))) =
        (poses.get(first).copied(), odometry.get(first).copied())
    else {
        return;
    };
    for i in (0..first).rev() {
        match odometry.get(i).copied().flatten() {
            Some(o) => poses[i] = Some(anchor * (anchor_odometry.inverse() * o)),
            None => return,
        }
    }
}
