//! The drone node (`slamkit ros2 drone`): the [`DroneSlam`] session `slamkit lidar LOG --ranges`
//! runs on a recorded flight (layered 2D lidar SLAM, the layer chosen by the up and down
//! range finders), on live topics: `sensor_msgs/LaserScan` (`/scan`), the two finders'
//! `sensor_msgs/Range` (`/range_up`, `/range_down`), `sensor_msgs/Imu` (`/imu`) and, where
//! the drone has it, `nav_msgs/Odometry`, all with ROS 2's sensor-data QoS; the laser's
//! mounting from `/tf_static` ([`crate::drone_readings`] says how ranges and the IMU are read).
//!
//! Out, as the lidar node publishes them ([`crate::scan_node`]): the current layer's map on
//! `/map` and `/map_metadata` (reliable, transient local; the grid's origin `z` is the layer's
//! floor, and a layer change republishes it at once), `/tf`, `/pose` and `/path` for every
//! scan, and the layer's index on `/slamkit/layer` (`std_msgs/Int32`, the layer `k` spanning
//! `k · layer_height_m` to `(k + 1) · layer_height_m` above the floor under the first scan).
//!
//! Frames (REP 105): the map frame is the first scan's x, y and heading with z = 0 at the floor
//! under it. With odometry the node publishes `map → odom` in the ground plane
//! (`planar(map_from_base) · odom_from_base⁻¹`, the odometry taken as planar, as the bag
//! reader takes it; the height and tilt stay with the odometry's `odom → base_link`); without,
//! `map → base_link` in 3D: x, y and yaw from the layer's map, the height from the range
//! finders, roll and pitch from the IMU.

use crate::lidar_node::{LidarNodeConfig, NodeMode, NodeStats};
use crate::lidar_run::{set_mode, LidarNodeRequest};
use crate::scan_node::{run_scan_node, DroneTopics, ScanSession};
use crate::Ros2Error;
use serde_json::{json, Value};
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{LaserScan, Observation, Pose2, Pose3};
use slamkit_io::carmen::CarmenLog;
use slamkit_lidar::layers::LayerScanStatus;
use slamkit_map::{OccupancyGrid, OccupancyGridConfig};
use slamkit_slam::drone::map::DroneMap;
use slamkit_slam::profile::settings;
use slamkit_slam::{DroneSlam, DroneSlamConfig, Session, SlamError};
use std::path::Path;
use std::sync::atomic::AtomicBool;

/// Settings of the drone node.
#[derive(Debug, Clone, PartialEq)]
pub struct DroneNodeConfig {
    /// The scan, odometry, transform, map and pose topics, the frames, the mode and the map
    /// updates, as for the lidar node (here without odometry and with `/path` by default).
    pub lidar: LidarNodeConfig,
    /// The range finders, the IMU and the layer topic.
    pub drone: DroneTopics,
}

impl Default for DroneNodeConfig {
    fn default() -> Self {
        Self {
            lidar: LidarNodeConfig {
                odom_topic: None,
                path_topic: Some("/path".into()),
                ..LidarNodeConfig::default()
            },
            drone: DroneTopics::default(),
        }
    }
}

impl DroneNodeConfig {
    /// One line on what the node reads and publishes, for the person starting it.
    ///
    /// ```
    /// use slamkit_ros2::DroneNodeConfig;
    /// assert_eq!(
    ///     DroneNodeConfig::default().describe(),
    ///     "/scan + /range_up + /range_down + /imu (no odometry) -> /map, map->base_link on \
    ///      /tf, /pose, /path, /slamkit/layer"
    /// );
    /// ```
    pub fn describe(&self) -> String {
        let (l, d) = (&self.lidar, &self.drone);
        let child = if l.odom_topic.is_some() {
            &l.odom_frame
        } else {
            &l.base_frame
        };
        format!(
            "{} + {} + {} + {} ({}) -> {}, {}->{} on {}, {}, {}, {}",
            l.scan_topic,
            d.range_up_topic,
            d.range_down_topic,
            d.imu_topic.as_deref().unwrap_or("no IMU"),
            l.odom_topic.as_deref().unwrap_or("no odometry"),
            l.map_topic,
            l.map_frame,
            child,
            l.tf_topic,
            l.pose_topic,
            l.path_topic.as_deref().unwrap_or("no path"),
            d.layer_topic
        )
    }
}

/// The drone session as the node drives it: the map it publishes is the current layer's.
struct NodeSession {
    session: DroneSlam,
    grid: OccupancyGridConfig,
}

impl NodeSession {
    /// The layer of the last scan.
    fn current_layer(&self) -> Option<i64> {
        self.session.scans().last().and_then(|r| r.estimate.layer)
    }
}

impl ScanSession for NodeSession {
    fn reading(&mut self, observation: Observation) {
        self.session.push(observation);
    }

    fn scan(&mut self, scan: LaserScan, _: &[LaserScan]) -> Option<Pose3> {
        self.session
            .push(Observation::Scan(scan))
            .and_then(|u| u.pose)
    }

    /// The scans matched in the current layer, at their poses in the map frame.
    fn map_poses(&self) -> Vec<Option<Pose2>> {
        let layer = self.current_layer();
        let map_from_world = self.session.map_from_world();
        let mut poses = vec![None; self.session.unplaced_scans()];
        poses.extend(self.session.scans().iter().map(|r| {
            let e = &r.estimate;
            let matched = matches!(e.status, LayerScanStatus::Slam(_)) && e.layer == layer;
            matched.then(|| pose3_to_pose2(&(map_from_world * e.world_from_base)))
        }));
        poses
    }

    fn map_height_m(&self) -> f64 {
        let height = self.session.config().layers.height.layer_height_m;
        self.current_layer().map_or(0.0, |l| l as f64 * height)
    }

    fn layer(&self) -> Option<i64> {
        self.current_layer()
    }

    fn initial_grid(&self) -> Result<Option<OccupancyGrid>, SlamError> {
        Ok(None)
    }

    /// The current layer's grid.
    fn output_grid(&self, scans: &[LaserScan]) -> Result<OccupancyGrid, SlamError> {
        let frame = self.session.map_from_world();
        let mut grids = self.session.layer_grids(scans, &frame, &self.grid)?;
        self.current_layer()
            .and_then(|l| grids.layers.remove(&l))
            .map(|l| l.grid)
            .ok_or_else(|| SlamError::Config("no scan matched in a height layer yet".into()))
    }

    fn save(&self, path: &Path) -> Result<(), SlamError> {
        Session::save(&self.session, path)
    }
}

/// What a drone node run leaves: the session, every scan it was pushed (in order), the
/// counters.
pub struct DroneNodeRun {
    /// The session, to save its map and trajectory.
    pub session: DroneSlam,
    /// The scans pushed, for the layers' maps at the session's poses.
    pub scans: Vec<LaserScan>,
    /// Counters.
    pub stats: NodeStats,
    /// Whether the node built a map or localised in a saved one.
    pub mode: NodeMode,
}

/// Runs the drone node until `stop` is set (or the input has been idle `idle_exit_s`).
///
/// # Errors
/// DDS could not start, a topic or node name is not a valid ROS name, or the map settings
/// are invalid.
pub fn run_drone_node(
    config: &DroneNodeConfig,
    session: DroneSlam,
    stop: &AtomicBool,
) -> Result<DroneNodeRun, Ros2Error> {
    let grid = OccupancyGridConfig {
        resolution_m: config.lidar.resolution_m,
        ..OccupancyGridConfig::default()
    };
    let session = NodeSession { session, grid };
    let (session, scans, stats) = run_scan_node(&config.lidar, Some(&config.drone), session, stop)?;
    Ok(DroneNodeRun {
        session: session.session,
        scans,
        stats,
        mode: config.lidar.mode,
    })
}

/// The drone node's settings and its session, ready for [`run_drone_node`].
pub struct DroneNodeSetup {
    /// The node's settings.
    pub node: DroneNodeConfig,
    /// The session: a new map, a continued one, or localisation in a saved one.
    pub session: DroneSlam,
    /// Parameters of the file that slamkit does not use (a caller may warn about them).
    pub ignored_params: Vec<String>,
}

impl LidarNodeRequest {
    /// The drone node's settings (defaults, then the parameter file, then this request) and
    /// its session, chosen as for the lidar node ([`LidarNodeRequest::setup`]); the profile's
    /// and settings file's `[drone]` settings.
    ///
    /// # Errors
    /// [`Ros2Error::Config`] for a bad parameter file or setting, or localisation without a
    /// map; [`Ros2Error::Slam`] for a profile, settings file or saved map that does not load.
    pub fn drone_setup(&self) -> Result<DroneNodeSetup, Ros2Error> {
        if self.record.is_some() {
            return Err(Ros2Error::Config(
                "the drone node does not record (the lidar and camera nodes do)".into(),
            ));
        }
        let defaults = DroneNodeConfig::default();
        let mut node = DroneNodeConfig {
            lidar: self.node_config(defaults.lidar),
            ..defaults
        };
        let (params, localize) = self.params_and_map(&node.lidar.node_name)?;
        let mut config: DroneSlamConfig = settings(
            DroneSlamConfig::default(),
            "drone",
            self.profile.as_deref(),
            self.config.as_deref(),
        )?;
        params.apply(&mut node.lidar, &mut config.layers.slam.max_range_m)?;
        params.apply_drone(&mut node.drone);
        set_mode(&mut node.lidar.mode, localize.is_some())?;
        let session = match (&localize, &self.continue_map) {
            (Some(path), _) => DroneSlam::localise(config, DroneMap::load(path)?)?,
            (None, Some(path)) => DroneSlam::resume(config, DroneMap::load(path)?)?,
            (None, None) => DroneSlam::new(config)?,
        };
        Ok(DroneNodeSetup {
            node,
            session,
            ignored_params: params.ignored().into_iter().map(String::from).collect(),
        })
    }
}

impl DroneNodeRun {
    /// The files of a run, as `slamkit ros2 drone` names them.
    pub const OUTPUTS: &'static [&'static str] = &[
        "trajectory.tum",
        "map.pgm",
        "map.yaml",
        "map.png",
        "maps",
        "cloud.ply",
        "map_pf.pgm",
        "map_pf.yaml",
        "map_pf.png",
        "map.skmap",
        "report.json",
    ];

    /// Writes `trajectory.tum` into `dir` and, when scans came in, the maps of `slamkit lidar
    /// LOG --ranges` (`map.*` of every layer, `maps/layer_NNN.*`, `cloud.ply`) and
    /// `map.skmap` (and the particle filter's best map, `map_pf.*`, when the session runs
    /// one).
    ///
    /// # Errors
    /// [`Ros2Error::Slam`] when a file cannot be written.
    pub fn write_outputs(&self, dir: &Path) -> Result<(), Ros2Error> {
        slamkit_io::write_tum(&dir.join("trajectory.tum"), &self.session.trajectory())
            .map_err(SlamError::from)?;
        if !self.scans.is_empty() {
            let frame = self.session.map_from_world();
            self.session.write_maps(dir, &self.scans, &frame)?;
            Session::save(&self.session, &dir.join("map.skmap"))?;
        }
        Ok(())
    }

    /// The run's `report.json`: the session's part as `slamkit lidar LOG --ranges` reports it,
    /// the node's counters and its receive-to-publish latency.
    pub fn report(&self, wall_seconds: f64) -> Value {
        let log = CarmenLog {
            scans: self.scans.clone(),
            ..CarmenLog::default()
        };
        let mut report = self.session.run_report(&log);
        report["input"] = json!("ros2");
        report["method"] = json!(match self.mode {
            NodeMode::Localization => "localise",
            NodeMode::Mapping => "layered",
        });
        report["frames"]["read"] = json!(self.stats.scans_received);
        report["node"] = json!(self.stats);
        report["wall_seconds"] = json!(wall_seconds);
        report["node_latency_ms"] = json!(self.stats.latency.summary());
        report
    }

    /// One line on what the run took in.
    pub fn summary(&self) -> String {
        let s = &self.stats;
        format!(
            "scans: {} received, {} processed; range readings {}, IMU {}; {} height layers",
            s.scans_received,
            s.scans_processed,
            s.ranges_received,
            s.imu_received,
            self.session.layer_maps().len()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_builds_the_node_and_session() {
        let dir = tempfile::tempdir().unwrap();
        let params = dir.path().join("p.yaml");
        std::fs::write(
            &params,
            "slamkit:\n  ros__parameters:\n    odom_topic: /odom\n    range_down_topic: /tof\n    \
             max_laser_range: 6.0\n    base_frame: base_footprint\n",
        )
        .unwrap();
        let request = LidarNodeRequest {
            params: Some(params),
            idle_exit_s: Some(1.0),
            ..LidarNodeRequest::default()
        };
        let setup = request.drone_setup().unwrap();
        assert_eq!(setup.node.lidar.idle_exit_s, Some(1.0));
        assert_eq!(setup.session.config().layers.slam.max_range_m, 6.0);
        assert_eq!(
            setup.node.describe(),
            "/scan + /range_up + /tof + /imu (/odom) -> /map, map->odom on /tf, /pose, /path, \
             /slamkit/layer"
        );
        assert!(setup.ignored_params.is_empty());
        let e = LidarNodeRequest {
            localize: Some(dir.path().join("none.skmap")),
            ..LidarNodeRequest::default()
        }
        .drone_setup()
        .err()
        .unwrap()
        .to_string();
        assert!(e.contains("none.skmap"), "{e}");
    }
}
