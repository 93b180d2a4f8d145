//! The 2D lidar node (`slamkit ros2 lidar`): `sensor_msgs/LaserScan` and `nav_msgs/Odometry`
//! in (ROS 2's sensor-data QoS: best effort, volatile), `/tf_static` for the laser's mounting;
//! a [`LidarSlam`] session, the one `slamkit lidar` runs on files; out: `nav_msgs/OccupancyGrid`
//! on `/map` and `nav_msgs/MapMetaData` on `/map_metadata` (reliable, transient local, as
//! `map_server` and `slam_toolbox` publish them), the `map → odom` transform on `/tf` (REP 105:
//! `map_from_odom = map_from_base · odom_from_base⁻¹` at the scan's stamp; `map → base` when
//! there is no odometry) and `geometry_msgs/PoseWithCovarianceStamped` on `/pose` for every
//! scan (as `slam_toolbox` does; the covariance is zero: the session does not estimate one).
//!
//! The threads, readers and writers are those every planar lidar node shares
//! ([`crate::scan_node`]).
//!
//! Scans are tied to odometry in publication order ([`crate::pairing`]), so a log played into
//! the node gives the trajectory of the file run. A `std_msgs/String` on the save topic
//! (`/slamkit/save_map`) names a file stem: the map is saved there as `.skmap`, `.pgm` and
//! `.yaml` while the node runs.

use crate::dds::{Discovery, Refusals};
use crate::scan_node::{run_scan_node, ScanSession};
use crate::Ros2Error;
use slamkit_core::{LaserScan, Observation, Pose2, Pose3, StageTimings};
use slamkit_io::bag::scans::Mounting;
use slamkit_map::{OccupancyGrid, OccupancyGridConfig};
use slamkit_slam::record::LidarRecording;
use slamkit_slam::{LidarSlam, Session, SlamError};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// The stage of [`NodeStats::latency`]: a scan from its reader to its published pose.
pub const LATENCY_STAGE: &str = "scan_receive_to_publish";

/// Whether the node builds a map or localises in a saved one (`slam_toolbox`'s `mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeMode {
    /// A new map (or the continuation of a saved one).
    Mapping,
    /// Localisation in a saved map, which is published once and never changes.
    Localization,
}

/// Settings of the lidar node; the defaults are ROS 2's usual names.
#[derive(Debug, Clone, PartialEq)]
pub struct LidarNodeConfig {
    /// DDS domain and discovery.
    pub discovery: Discovery,
    /// The node's name.
    pub node_name: String,
    /// `sensor_msgs/LaserScan` topic.
    pub scan_topic: String,
    /// `nav_msgs/Odometry` topic; `None` for a robot without wheel odometry.
    pub odom_topic: Option<String>,
    /// Static transforms (the laser's mounting).
    pub tf_static_topic: String,
    /// Transforms out.
    pub tf_topic: String,
    /// The map out.
    pub map_topic: String,
    /// The map's metadata out.
    pub map_metadata_topic: String,
    /// The pose out.
    pub pose_topic: String,
    /// The path of every pose out (`nav_msgs/Path`, transient local); `None`: not published
    /// (a long log's path would be sent whole at every scan).
    pub path_topic: Option<String>,
    /// A `std_msgs/String` naming a file stem saves the map there.
    pub save_map_topic: String,
    /// The map frame (REP 105).
    pub map_frame: String,
    /// The odometry frame.
    pub odom_frame: String,
    /// The robot's frame when the odometry names none, and the child of `map` without odometry.
    pub base_frame: String,
    /// Mapping or localisation.
    pub mode: NodeMode,
    /// Seconds between map redraws (`slam_toolbox`'s `map_update_interval`).
    pub map_update_interval_s: f64,
    /// Side of a cell of the published map \[m\] (`resolution`).
    pub resolution_m: f64,
    /// Longest a scan waits for the odometry published after it \[s\].
    pub odometry_wait_s: f64,
    /// Stop once no message came for this long after the first scan \[s\] (a played log's end).
    pub idle_exit_s: Option<f64>,
    /// Record what the node processed to this MCAP file ([`LidarRecording::live`]: every
    /// scan with its pose and `map → base_link`, the map and path now and then and at the
    /// end), as `slamkit lidar --record` records a log.
    pub record: Option<PathBuf>,
}

impl Default for LidarNodeConfig {
    fn default() -> Self {
        Self {
            discovery: Discovery::default(),
            node_name: "slamkit".into(),
            scan_topic: "/scan".into(),
            odom_topic: Some("/odom".into()),
            tf_static_topic: "/tf_static".into(),
            tf_topic: "/tf".into(),
            map_topic: "/map".into(),
            map_metadata_topic: "/map_metadata".into(),
            pose_topic: "/pose".into(),
            path_topic: None,
            save_map_topic: "/slamkit/save_map".into(),
            map_frame: "map".into(),
            odom_frame: "odom".into(),
            base_frame: "base_link".into(),
            mode: NodeMode::Mapping,
            map_update_interval_s: 5.0,
            resolution_m: OccupancyGridConfig::default().resolution_m,
            odometry_wait_s: 0.5,
            idle_exit_s: None,
            record: None,
        }
    }
}

/// Counters and timings of a node run.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct NodeStats {
    /// Scans received.
    pub scans_received: usize,
    /// Odometry messages received.
    pub odometry_received: usize,
    /// Static transform messages received.
    pub tf_static_received: usize,
    /// Range finder messages received (a drone's, both finders).
    pub ranges_received: usize,
    /// IMU messages received (a drone's).
    pub imu_received: usize,
    /// Scans and readings dropped because they came after newer ones had been used (a
    /// drone's, whose sensors are put back in time order).
    pub dropped_out_of_order: usize,
    /// Messages that did not convert (the first few with why).
    pub undecodable: Refusals,
    /// Scans pushed into the session.
    pub scans_processed: usize,
    /// Maps published.
    pub maps_published: usize,
    /// Maps saved on request.
    pub maps_saved: usize,
    /// Per scan, [`LATENCY_STAGE`]: from taking it off the DDS reader to publishing its pose
    /// (it includes the wait for the next odometry reading).
    #[serde(skip)]
    pub latency: StageTimings,
    /// The laser's mounting used for the last scan.
    pub mounting: Option<Mounting>,
}

/// What a node run leaves: the session, every scan it was pushed (in order), the counters.
pub struct LidarNodeRun {
    /// The session, to save its map and trajectory.
    pub session: LidarSlam,
    /// The scans pushed, for the map of the session's poses.
    pub scans: Vec<LaserScan>,
    /// Counters.
    pub stats: NodeStats,
    /// Whether the node built a map or localised in a saved one.
    pub mode: NodeMode,
    /// The recording's file and its messages per topic, when the node recorded its run.
    pub recorded: Option<(PathBuf, BTreeMap<String, u64>)>,
}

/// Runs the lidar node until `stop` is set (or the input has been idle `idle_exit_s`).
///
/// # Errors
/// DDS could not start, a topic or node name is not a valid ROS name, or the map thread's
/// settings are invalid.
pub fn run_lidar_node(
    config: &LidarNodeConfig,
    session: LidarSlam,
    stop: &AtomicBool,
) -> Result<LidarNodeRun, Ros2Error> {
    let recording = config
        .record
        .as_deref()
        .map(LidarRecording::live)
        .transpose()?;
    let session = NodeSession {
        session,
        recording,
        recording_error: None,
    };
    let (s, scans, stats) = run_scan_node(config, None, session, stop)?;
    if let Some(e) = s.recording_error {
        return Err(e.into());
    }
    let recorded = match (s.recording, &config.record) {
        (Some(r), Some(path)) => Some((path.clone(), r.finish(&s.session, &scans)?)),
        _ => None,
    };
    Ok(LidarNodeRun {
        session: s.session,
        scans,
        stats,
        mode: config.mode,
        recorded,
    })
}

/// The lidar session as the node drives it, and its recording.
struct NodeSession {
    session: LidarSlam,
    recording: Option<LidarRecording>,
    /// The first recording error: the recording stops there, and the run fails at its end.
    recording_error: Option<SlamError>,
}

impl ScanSession for NodeSession {
    /// A planar lidar session takes scans only.
    fn reading(&mut self, _: Observation) {}

    fn scan(&mut self, scan: LaserScan, pushed: &[LaserScan]) -> Option<Pose3> {
        let update = self.session.push_scan(scan);
        if let Some(recording) = &mut self.recording {
            if let Err(e) = recording.push(&self.session, pushed, &update) {
                self.recording = None;
                self.recording_error.get_or_insert(e);
            }
        }
        update.pose
    }

    fn live_grid(&self) -> Option<&OccupancyGrid> {
        self.session.particle_grid()
    }

    fn map_poses(&self) -> Vec<Option<Pose2>> {
        self.session.poses()
    }

    fn initial_grid(&self) -> Result<Option<OccupancyGrid>, SlamError> {
        self.session.output_grid(&[]).map(Some)
    }

    fn output_grid(&self, scans: &[LaserScan]) -> Result<OccupancyGrid, SlamError> {
        self.session.output_grid(scans)
    }

    fn save(&self, path: &Path) -> Result<(), SlamError> {
        Session::save(&self.session, path)
    }
}
