//! A `slamkit ros2 lidar` run as a shell drives it, so the command line (and any other shell)
//! only parses arguments, shows progress and commits the output folder: the node's settings
//! and session built from what was asked ([`LidarNodeRequest::setup`]: node defaults, the
//! parameter file, `ROS_DOMAIN_ID`, a saved map), and once the node stops, its output files
//! and `report.json` ([`LidarNodeRun::write_outputs`], [`LidarNodeRun::report`]).

use crate::dds::Discovery;
use crate::lidar_node::{LidarNodeConfig, LidarNodeRun, NodeMode};
use crate::params::RosParams;
use crate::Ros2Error;
use serde_json::{json, Value};
use slamkit_core::Pose2;
use slamkit_slam::lidar::LidarMap;
use slamkit_slam::{LidarMethod, LidarSlam, LidarSlamConfig, SlamError};
use std::path::{Path, PathBuf};

/// What a run of the lidar node is asked for, on top of the node's defaults.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LidarNodeRequest {
    /// ROS 2 parameter file ([`RosParams`]).
    pub params: Option<PathBuf>,
    /// Localise in this saved map (wins over the parameter file's `map_file_name`).
    pub localize: Option<PathBuf>,
    /// Continue this saved map.
    pub continue_map: Option<PathBuf>,
    /// Named profile of the robot (or a `.toml` profile file).
    pub profile: Option<String>,
    /// TOML file laid over the profile's settings.
    pub config: Option<PathBuf>,
    /// Stop once no message came for this long after the first scan \[s\].
    pub idle_exit_s: Option<f64>,
    /// Record what the node processed to this MCAP file.
    pub record: Option<PathBuf>,
    /// DDS domain and discovery (the caller reads them from the environment,
    /// [`Discovery::from_env`]: a library does not read the process's environment).
    pub discovery: Discovery,
}

/// The node's settings and its session, ready for [`crate::run_lidar_node`].
pub struct LidarNodeSetup {
    /// The node's settings.
    pub node: LidarNodeConfig,
    /// The session: a new map, a continued one, or localisation in a saved one.
    pub session: LidarSlam,
    /// Parameters of the file that slamkit does not use (a caller may warn about them).
    pub ignored_params: Vec<String>,
}

impl LidarNodeRequest {
    /// The node's settings (defaults, then the parameter file, then this request) and the
    /// session: localisation when a map to localise in is named (`localize`, or `mode:
    /// localization` with `map_file_name`), else a continued map, else a new one.
    ///
    /// # Errors
    /// [`Ros2Error::Config`] for a bad parameter file or setting, or
    /// localisation without a map; [`Ros2Error::Slam`] for a profile, settings file or saved
    /// map that does not load.
    pub fn setup(&self) -> Result<LidarNodeSetup, Ros2Error> {
        let mut node = self.node_config(LidarNodeConfig::default());
        let (params, localize) = self.params_and_map(&node.node_name)?;
        let mut config = LidarSlamConfig::from_files(
            LidarMethod::Icp,
            localize.is_some() || self.continue_map.is_some(),
            self.profile.as_deref(),
            self.config.as_deref(),
        )?;
        params.apply(&mut node, &mut config.icp.max_range_m)?;
        set_mode(&mut node.mode, localize.is_some())?;
        let load = |path: &Path| LidarMap::load(path).map(|(map, _)| map);
        let session = match (&localize, &self.continue_map) {
            (Some(path), _) => LidarSlam::localise(config, load(path)?)?,
            (None, Some(path)) => LidarSlam::resume(config, load(path)?)?,
            (None, None) => LidarSlam::new(config, Pose2::identity())?,
        };
        Ok(LidarNodeSetup {
            node,
            session,
            ignored_params: params.ignored().into_iter().map(String::from).collect(),
        })
    }

    /// `defaults` with the request's idle timeout, discovery and recording.
    pub(crate) fn node_config(&self, defaults: LidarNodeConfig) -> LidarNodeConfig {
        LidarNodeConfig {
            idle_exit_s: self.idle_exit_s,
            discovery: self.discovery,
            record: self.record.clone(),
            ..defaults
        }
    }

    /// The parameter file's parameters (none without a file) and the saved map to localise
    /// in: `localize`, else `map_file_name` with `mode: localization`.
    pub(crate) fn params_and_map(
        &self,
        node_name: &str,
    ) -> Result<(RosParams, Option<PathBuf>), Ros2Error> {
        let params = match &self.params {
            Some(path) => RosParams::load(path, node_name)?,
            None => RosParams::default(),
        };
        let localize = self.localize.clone().or_else(|| {
            (params.mode == Some(NodeMode::Localization))
                .then(|| params.map_file())
                .flatten()
        });
        Ok((params, localize))
    }
}

/// Localisation when there is a map to localise in; `mode: localization` without one is an
/// error.
pub(crate) fn set_mode(mode: &mut NodeMode, have_map: bool) -> Result<(), Ros2Error> {
    if have_map {
        *mode = NodeMode::Localization;
        Ok(())
    } else if *mode == NodeMode::Localization {
        Err(Ros2Error::Config(
            "mode: localization needs a map: --localize MAP.skmap or map_file_name".into(),
        ))
    } else {
        Ok(())
    }
}

impl LidarNodeConfig {
    /// One line on what the node reads and publishes, for the person starting it:
    /// `/scan (/odom) -> /map, map->odom on /tf, /pose`.
    ///
    /// ```
    /// use slamkit_ros2::LidarNodeConfig;
    /// let line = LidarNodeConfig::default().describe();
    /// assert_eq!(line, "/scan (/odom) -> /map, map->odom on /tf, /pose");
    /// ```
    pub fn describe(&self) -> String {
        format!(
            "{} ({}) -> {}, {}->{} on {}, {}",
            self.scan_topic,
            self.odom_topic.as_deref().unwrap_or("no odometry"),
            self.map_topic,
            self.map_frame,
            self.odom_frame,
            self.tf_topic,
            self.pose_topic
        )
    }
}

impl LidarNodeRun {
    /// The files of a run, as `slamkit ros2 lidar` names them: what each run writes in its
    /// output folder ([`LidarNodeRun::write_outputs`] and the caller's `report.json`).
    pub const OUTPUTS: &'static [&'static str] = &[
        "trajectory.tum",
        "map.pgm",
        "map.yaml",
        "map.png",
        "map.skmap",
        "report.json",
    ];

    /// Writes `trajectory.tum` into `dir`, and the map (`map.pgm`, `map.yaml`, `map.png`,
    /// `map.skmap`) when there is one: scans came in, or the node localised in a saved map.
    ///
    /// # Errors
    /// [`Ros2Error::Slam`] when a file cannot be written.
    pub fn write_outputs(&self, dir: &Path) -> Result<(), Ros2Error> {
        let trajectory = self.session.trajectory();
        slamkit_io::trajectory_file::write_tum(&dir.join("trajectory.tum"), &trajectory)
            .map_err(SlamError::from)?;
        if !self.scans.is_empty() || self.mode == NodeMode::Localization {
            let grid = self.session.output_grid(&self.scans)?;
            slamkit_map::save_grid_files(&grid, &dir.join("map")).map_err(SlamError::from)?;
            let path = dir.join("map.skmap");
            self.session
                .map_file()
                .and_then(|file| file.save(&path))
                .map_err(|source| SlamError::MapFile { path, source })?;
        }
        Ok(())
    }

    /// The run's `report.json` (DESIGN.md's fields: input, effective config, frames, wall
    /// seconds, per-stage timings) with the node's counters and its receive-to-publish latency.
    pub fn report(&self, wall_seconds: f64) -> Value {
        let counts = self.session.frame_counts();
        json!({
            "input": "ros2",
            "method": match self.mode {
                NodeMode::Localization => "localise",
                NodeMode::Mapping => "icp",
            },
            "config": self.session.config(),
            "node": self.stats,
            "frames": {
                "read": self.stats.scans_received,
                "processed": counts.processed,
                "skipped": counts.skipped,
                "failed": counts.failed,
            },
            "session": self.session.stats(),
            "wall_seconds": wall_seconds,
            "timings_ms": self.session.timings().summary(),
            "node_latency_ms": self.stats.latency.summary(),
            "recording": self.recorded.as_ref().map(|(file, messages)| json!({
                "file": file,
                "messages": messages,
            })),
        })
    }

    /// One line on what the run took in: `scans: N received, M processed`.
    pub fn summary(&self) -> String {
        format!(
            "scans: {} received, {} processed",
            self.stats.scans_received, self.stats.scans_processed
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
            "slamkit:\n  ros__parameters:\n    odom_topic: \"\"\n    scan_topic: /front/scan\n    \
             transform_timeout: 0.2\n",
        )
        .unwrap();
        let request = LidarNodeRequest {
            params: Some(params),
            idle_exit_s: Some(2.0),
            discovery: Discovery {
                domain_id: 7,
                localhost_only: true,
            },
            ..LidarNodeRequest::default()
        };
        let setup = request.setup().unwrap();
        assert_eq!(setup.node.discovery, request.discovery);
        assert_eq!(setup.node.idle_exit_s, Some(2.0));
        assert_eq!(setup.node.mode, NodeMode::Mapping);
        assert_eq!(
            setup.node.describe(),
            "/front/scan (no odometry) -> /map, map->odom on /tf, /pose"
        );
        assert_eq!(setup.ignored_params, ["transform_timeout"]);
    }

    #[test]
    fn bad_requests_give_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let params = dir.path().join("p.yaml");
        std::fs::write(
            &params,
            "slamkit:\n  ros__parameters:\n    mode: localization\n",
        )
        .unwrap();
        let no_map = LidarNodeRequest {
            params: Some(params),
            ..LidarNodeRequest::default()
        };
        let e = no_map.setup().err().unwrap().to_string();
        assert!(e.contains("localization needs a map"), "{e}");
        let missing = LidarNodeRequest {
            localize: Some(dir.path().join("none.skmap")),
            ..LidarNodeRequest::default()
        };
        let e = missing.setup().err().unwrap().to_string();
        assert!(e.contains("none.skmap"), "{e}");
    }
}
