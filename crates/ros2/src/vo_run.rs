//! A `slamkit ros2 vo` run as a shell drives it: the node's settings and the session's from
//! what was asked ([`VoNodeRequest::setup`]: the RealSense driver's topics unless others are
//! named, the profile and settings file as `slamkit vo` reads them, `--slam`, a map to
//! localise in), the session once the camera is known ([`VoNodeSetup::session`]), and once the
//! node stops its files (`trajectory.tum`, `cloud.ply`, the map with `--save-map`) and
//! `report.json` ([`VoNodeRun::finish`]).

use crate::dds::Discovery;
use crate::lidar_node::NodeMode;
use crate::params::RosParams;
use crate::vo_node::{VoNodeConfig, VoNodeRun};
use crate::Ros2Error;
use serde_json::{json, Value};
use slamkit_core::camera::PinholeCamera;
use slamkit_io::DatasetFormat;
use slamkit_slam::report::merge_json;
use slamkit_slam::visual::run_files::DatasetRun;
use slamkit_slam::visual::{self, PointMapping};
use slamkit_slam::{Session, SlamError, VisualSlam};
use slamkit_vo::{FrontendKind, VoConfig};
use std::path::{Path, PathBuf};

/// What a run of the camera node is asked for, on top of the node's defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct VoNodeRequest {
    /// Colour topic, when not the driver's default.
    pub rgb_topic: Option<String>,
    /// Depth topic (registered to colour), when not the driver's default.
    pub depth_topic: Option<String>,
    /// Calibration topic, when not the driver's default.
    pub camera_info_topic: Option<String>,
    /// The robot's frame, the child of `map` on `/tf` (default `camera_link`).
    pub base_frame: Option<String>,
    /// The map frame (default `map`).
    pub map_frame: Option<String>,
    /// ROS 2 parameter file ([`RosParams`]: [`VO_PARAMS`], [`NAV_PARAMS`]); what the request
    /// names itself wins over it.
    pub params: Option<PathBuf>,
    /// Feature front end.
    pub frontend: FrontendKind,
    /// Named profile of the camera (or a `.toml` profile file).
    pub profile: Option<String>,
    /// TOML file laid over the profile's settings.
    pub config: Option<PathBuf>,
    /// Loop closure on (visual SLAM).
    pub slam: bool,
    /// Localise in this saved map instead of building one.
    pub localize: Option<PathBuf>,
    /// Save the session's map here when the node stops.
    pub save_map: Option<PathBuf>,
    /// Record what the node processed to this MCAP file.
    pub record: Option<PathBuf>,
    /// Paired frames waiting for the session at most (default: a driver's ring of buffers).
    pub frame_queue: Option<usize>,
    /// Stop once no image came for this long \[s\].
    pub idle_exit_s: Option<f64>,
    /// DDS domain and discovery.
    pub discovery: Discovery,
}

impl Default for VoNodeRequest {
    fn default() -> Self {
        Self {
            rgb_topic: None,
            depth_topic: None,
            camera_info_topic: None,
            base_frame: None,
            map_frame: None,
            params: None,
            frontend: FrontendKind::Klt,
            profile: None,
            config: None,
            slam: false,
            localize: None,
            save_map: None,
            record: None,
            frame_queue: None,
            idle_exit_s: None,
            discovery: Discovery::default(),
        }
    }
}

/// The node's settings and the session's, ready for [`crate::run_vo_node`].
#[derive(Debug, Clone)]
pub struct VoNodeSetup {
    /// The node's settings.
    pub node: VoNodeConfig,
    /// The session's settings (what `slamkit vo` would run on a bag of the camera).
    pub settings: VoConfig,
    /// The saved map to localise in.
    pub localize: Option<PathBuf>,
    /// Where the map goes when the node stops.
    pub save_map: Option<PathBuf>,
}

/// The parameters `slamkit ros2 vo` takes from its parameter file.
pub const VO_PARAMS: &[&str] = &[
    "map_frame",
    "base_frame",
    "mode",
    "map_file_name",
    "rgb_topic",
    "depth_topic",
    "camera_info_topic",
];

/// The parameters `slamkit ros2 nav` takes from its parameter file.
pub const NAV_PARAMS: &[&str] = &[
    "map_frame",
    "base_frame",
    "rgb_topic",
    "depth_topic",
    "camera_info_topic",
];

impl VoNodeRequest {
    /// This request with the parameter file's values (of `allowed`, for node `node`) where
    /// the request names none: `mode: localization` localises in `map_file_name`.
    ///
    /// # Errors
    /// [`Ros2Error::Config`] for a file that does not read, a parameter not in `allowed`, or
    /// `mode: localization` without a map.
    pub fn with_params(&self, node: &str, allowed: &[&str]) -> Result<Self, Ros2Error> {
        let Some(path) = &self.params else {
            return Ok(self.clone());
        };
        let params = RosParams::load(path, &VoNodeConfig::default().node_name)?;
        if let Err(Ros2Error::Config(why)) = params.only(node, allowed) {
            return Err(Ros2Error::Config(format!("{}: {why}", path.display())));
        }
        let mut request = self.clone();
        for (slot, given) in [
            (&mut request.rgb_topic, &params.rgb_topic),
            (&mut request.depth_topic, &params.depth_topic),
            (&mut request.camera_info_topic, &params.camera_info_topic),
            (&mut request.base_frame, &params.base_frame),
            (&mut request.map_frame, &params.map_frame),
        ] {
            if slot.is_none() {
                slot.clone_from(given);
            }
        }
        if params.mode == Some(NodeMode::Localization) && request.localize.is_none() {
            request.localize = Some(params.map_file().ok_or_else(|| {
                Ros2Error::Config("mode: localization needs map_file_name".into())
            })?);
        }
        Ok(request)
    }

    /// `defaults` with what was asked laid over it: topics, frames, frame queue, idle
    /// timeout, discovery.
    pub fn node_config(&self, defaults: VoNodeConfig) -> VoNodeConfig {
        let mut node = VoNodeConfig {
            discovery: self.discovery,
            idle_exit_s: self.idle_exit_s,
            ..defaults
        };
        for (slot, asked) in [
            (&mut node.rgb_topic, &self.rgb_topic),
            (&mut node.depth_topic, &self.depth_topic),
            (&mut node.camera_info_topic, &self.camera_info_topic),
            (&mut node.base_frame, &self.base_frame),
            (&mut node.map_frame, &self.map_frame),
        ] {
            if let Some(v) = asked {
                slot.clone_from(v);
            }
        }
        if let Some(q) = self.frame_queue {
            node.frame_queue = q;
        }
        node.record.clone_from(&self.record);
        node
    }

    /// The node's settings and the session's: the driver's topics unless others are named,
    /// the profile and settings file laid over the front end's defaults as `slamkit vo` lays
    /// them for a bag, loop closure with `slam`.
    ///
    /// # Errors
    /// [`Ros2Error::Config`] for `slam` or `save_map` with `localize`, or a zero frame queue;
    /// [`Ros2Error::Slam`] for a profile or settings file that does not load.
    pub fn setup(&self) -> Result<VoNodeSetup, Ros2Error> {
        let request = self.with_params("vo", VO_PARAMS)?;
        request.setup_checked()
    }

    /// [`Self::setup`] once the parameter file is laid over the request.
    fn setup_checked(&self) -> Result<VoNodeSetup, Ros2Error> {
        if self.localize.is_some() && (self.slam || self.save_map.is_some()) {
            return Err(Ros2Error::Config(
                "localising in a saved map leaves it unchanged: no --slam or --save-map".into(),
            ));
        }
        if self.frame_queue == Some(0) {
            return Err(Ros2Error::Config(
                "the frame queue must hold a frame".into(),
            ));
        }
        let node = self.node_config(VoNodeConfig::default());
        let settings = visual::session_settings(
            self.frontend,
            DatasetFormat::RosBag,
            self.profile.as_deref(),
            self.config.as_deref(),
            self.slam,
        )?;
        Ok(VoNodeSetup {
            node,
            settings,
            localize: self.localize.clone(),
            save_map: self.save_map.clone(),
        })
    }
}

impl VoNodeSetup {
    /// The session for `camera` (a new map, or localisation in the saved one), its point map
    /// filled while the tracker is idle (a live camera does not wait for the map).
    ///
    /// # Errors
    /// [`SlamError`] for a map that does not load or is not an RGB-D camera's, or settings
    /// the session refuses.
    pub fn session(&self, camera: &PinholeCamera) -> Result<VisualSlam, SlamError> {
        let rig = visual::rgbd_rig(camera);
        let session = match &self.localize {
            Some(path) => {
                let map = visual::load_map(path, &rig)?;
                VisualSlam::localising_in(&self.settings, rig, &map)?
            }
            None => VisualSlam::new(&self.settings, rig)?,
        };
        session.with_point_map(PointMapping::WhenIdle)
    }

    /// One line on what the node reads and publishes, for the person starting it.
    ///
    /// ```
    /// use slamkit_ros2::vo_run::VoNodeRequest;
    /// let setup = VoNodeRequest::default().setup().unwrap();
    /// assert_eq!(
    ///     setup.describe(),
    ///     "/camera/camera/color/image_raw + /camera/camera/aligned_depth_to_color/image_raw \
    ///      (/camera/camera/color/camera_info) -> map->camera_link on /tf, /pose, /path"
    /// );
    /// ```
    pub fn describe(&self) -> String {
        let n = &self.node;
        format!(
            "{} + {} ({}) -> {}->{} on {}, {}, {}",
            n.rgb_topic,
            n.depth_topic,
            n.camera_info_topic,
            n.map_frame,
            n.base_frame,
            n.tf_topic,
            n.pose_topic,
            n.path_topic
        )
    }
}

impl VoNodeRun {
    /// The files of a run: what [`VoNodeRun::finish`] and the caller's `report.json` write.
    pub const OUTPUTS: &'static [&'static str] = &["trajectory.tum", "cloud.ply", "report.json"];

    /// Saves the map (when `setup` asks), ends the session, writes `trajectory.tum` and
    /// `cloud.ply` into `dir`, and returns `report.json`: the fields `slamkit vo` reports
    /// (frames, map, timings, loop closure, frame statuses) with the node's counters, its
    /// receive-to-publish latency and the effective settings.
    ///
    /// # Errors
    /// [`Ros2Error::Slam`] when the map or a file cannot be written.
    pub fn finish(self, setup: &VoNodeSetup, dir: &Path) -> Result<Value, Ros2Error> {
        if let Some(path) = &setup.save_map {
            Session::save(&self.session, path)?;
        }
        let finished = DatasetRun::finish(self.session, self.run)?;
        let recorded = match self.recording {
            Some(r) => {
                let cloud = finished.output.point_map.as_ref().map(|m| m.to_cloud());
                Some(r.finish(&finished.run.trajectory, cloud.as_ref())?)
            }
            None => None,
        };
        let (mut report, _) = finished.write_files(dir, None)?;
        let c = self.camera.intrinsics;
        merge_json(
            &mut report,
            json!({
                "input": "ros2",
                "camera": { "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy,
                            "width": c.width, "height": c.height },
                "config": setup.settings,
                "node": self.stats,
                "node_latency_ms": self.stats.latency.summary(),
                "map": { "saved_to": setup.save_map, "localised_in": setup.localize },
                "recording": recorded.map(|messages| json!({
                    "file": setup.node.record,
                    "messages": messages,
                })),
            }),
        );
        Ok(report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_builds_the_node_settings() {
        let request = VoNodeRequest {
            rgb_topic: Some("/cam/color/image_raw/compressed".into()),
            base_frame: Some("base_link".into()),
            slam: true,
            frame_queue: Some(64),
            ..VoNodeRequest::default()
        };
        let setup = request.setup().unwrap();
        assert_eq!(setup.node.rgb_topic, "/cam/color/image_raw/compressed");
        assert_eq!(setup.node.base_frame, "base_link");
        assert_eq!(setup.node.frame_queue, 64);
        assert!(setup.settings.loop_closure.enabled);
        let bad = VoNodeRequest {
            localize: Some("office.skmap".into()),
            slam: true,
            ..VoNodeRequest::default()
        };
        let e = bad.setup().unwrap_err().to_string();
        assert!(e.contains("no --slam or --save-map"), "{e}");
        let zero = VoNodeRequest {
            frame_queue: Some(0),
            ..VoNodeRequest::default()
        };
        assert!(zero.setup().is_err());
    }

    #[test]
    fn a_parameter_file_fills_what_the_request_leaves() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.yaml");
        std::fs::write(
            &path,
            "slamkit:\n  ros__parameters:\n    rgb_topic: /cam/rgb\n    base_frame: base_link\n    \
             map_frame: world\n    mode: localization\n    map_file_name: maps/office\n",
        )
        .unwrap();
        let request = VoNodeRequest {
            params: Some(path.clone()),
            base_frame: Some("camera_link".into()),
            ..VoNodeRequest::default()
        };
        let r = request.with_params("vo", VO_PARAMS).unwrap();
        assert_eq!(r.rgb_topic.as_deref(), Some("/cam/rgb"));
        // the command line wins
        assert_eq!(r.base_frame.as_deref(), Some("camera_link"));
        assert_eq!(r.localize, Some(PathBuf::from("maps/office.skmap")));
        let node = r.node_config(VoNodeConfig::default());
        assert_eq!(
            (node.map_frame.as_str(), node.rgb_topic.as_str()),
            ("world", "/cam/rgb")
        );
        // nav takes no map to localise in
        let e = request
            .with_params("nav", NAV_PARAMS)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("map_file_name, mode not used by slamkit ros2 nav"),
            "{e}"
        );
        std::fs::write(
            &path,
            "slamkit:\n  ros__parameters:\n    rgb_topc: /cam/rgb\n",
        )
        .unwrap();
        let e = request.setup().unwrap_err().to_string();
        assert!(e.contains("rgb_topc") && e.contains("p.yaml"), "{e}");
    }
}
