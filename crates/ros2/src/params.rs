//! The node's parameter file, in ROS 2's YAML form (`node_name: ros__parameters: {...}`, or
//! `/**:` for any node), with `slam_toolbox`'s names where the meaning is the same, so a robot's
//! existing file mostly works as it is. For the lidar and drone nodes, parameters slamkit has
//! no use for are listed back to the caller (to warn), not refused: a `slam_toolbox` file
//! holds dozens. The camera nodes (`vo`, `nav`) take no `slam_toolbox` file, so there a
//! parameter they do not use is an error ([`RosParams::only`]): a misspelt topic would
//! otherwise be silently left at its default.
//!
//! ```yaml
//! slamkit:
//!   ros__parameters:
//!     map_frame: map
//!     odom_frame: odom
//!     base_frame: base_footprint
//!     scan_topic: /scan
//!     odom_topic: /odom          # "" for a robot without wheel odometry
//!     mode: mapping              # or localization (in map_file_name)
//!     map_file_name: office      # .skmap added when missing
//!     resolution: 0.05           # of the published map [m]
//!     max_laser_range: 20.0      # [m]
//!     map_update_interval: 5.0   # [s]
//!     # slamkit ros2 drone only:
//!     range_up_topic: /range_up
//!     range_down_topic: /range_down
//!     imu_topic: /imu            # "" for a drone without one
//!     # slamkit ros2 vo and nav (with map_frame, base_frame; vo also mode, map_file_name):
//!     rgb_topic: /camera/camera/color/image_raw
//!     depth_topic: /camera/camera/aligned_depth_to_color/image_raw
//!     camera_info_topic: /camera/camera/color/camera_info
//! ```

use crate::lidar_node::{LidarNodeConfig, NodeMode};
use crate::scan_node::DroneTopics;
use crate::Ros2Error;
use serde::de::DeserializeOwned;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// The parameters slamkit reads; each is optional.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RosParams {
    /// The map frame.
    pub map_frame: Option<String>,
    /// The odometry frame.
    pub odom_frame: Option<String>,
    /// The robot's frame.
    pub base_frame: Option<String>,
    /// The scan topic.
    pub scan_topic: Option<String>,
    /// The odometry topic ("" for none).
    pub odom_topic: Option<String>,
    /// Mapping or localisation.
    pub mode: Option<NodeMode>,
    /// The saved map to localise in (or to continue).
    pub map_file_name: Option<String>,
    /// Side of a cell of the published map \[m\].
    pub resolution: Option<f64>,
    /// Longest range used \[m\].
    pub max_laser_range: Option<f64>,
    /// Seconds between map redraws.
    pub map_update_interval: Option<f64>,
    /// A drone's up-looking range finder topic.
    pub range_up_topic: Option<String>,
    /// A drone's down-looking range finder topic.
    pub range_down_topic: Option<String>,
    /// A drone's IMU topic ("" for none).
    pub imu_topic: Option<String>,
    /// A camera's colour topic.
    pub rgb_topic: Option<String>,
    /// A camera's depth topic (registered to colour).
    pub depth_topic: Option<String>,
    /// A camera's calibration topic.
    pub camera_info_topic: Option<String>,
    /// The names of the parameters above that the file gives, sorted.
    pub given: Vec<String>,
    /// Everything else in the file.
    pub other: BTreeMap<String, serde_yaml::Value>,
}

/// Takes parameter `name` out of `block`, read as a `T` (the error names it).
fn take<T: DeserializeOwned>(
    block: &mut BTreeMap<String, serde_yaml::Value>,
    name: &str,
) -> Result<Option<T>, Ros2Error> {
    block
        .remove(name)
        .map(|v| {
            serde_yaml::from_value(v)
                .map_err(|e| Ros2Error::Config(format!("parameter {name}: {e}")))
        })
        .transpose()
}

impl RosParams {
    /// Reads the parameters of `node_name` from a parameter file's text: the block named for
    /// the node (with or without a leading `/`), else `/**`, else the only block.
    ///
    /// ```
    /// use slamkit_ros2::params::RosParams;
    /// let text = "slamkit:\n  ros__parameters:\n    base_frame: base_footprint\n    \
    ///             transform_timeout: 0.2\n";
    /// let p = RosParams::parse(text, "slamkit").unwrap();
    /// assert_eq!(p.base_frame.as_deref(), Some("base_footprint"));
    /// assert_eq!(p.ignored(), ["transform_timeout"]);
    /// ```
    ///
    /// # Errors
    /// [`Ros2Error::Config`] for text that is not such a file, or a known parameter of the
    /// wrong type.
    pub fn parse(text: &str, node_name: &str) -> Result<Self, Ros2Error> {
        let mut blocks: BTreeMap<String, serde_yaml::Value> = serde_yaml::from_str(text)
            .map_err(|e| Ros2Error::Config(format!("parameter file: {e}")))?;
        let key = [
            node_name.to_string(),
            format!("/{node_name}"),
            "/**".to_string(),
        ]
        .into_iter()
        .find(|k| blocks.contains_key(k))
        .or_else(|| {
            (blocks.len() == 1)
                .then(|| blocks.keys().next().cloned())
                .flatten()
        })
        .ok_or_else(|| {
            Ros2Error::Config(format!(
                "parameter file: no block for node {node_name} (blocks: {})",
                blocks.keys().cloned().collect::<Vec<_>>().join(", ")
            ))
        })?;
        let block = blocks.remove(&key).unwrap_or_default();
        let mut block = match block {
            serde_yaml::Value::Mapping(mut m) => m.remove("ros__parameters"),
            _ => None,
        }
        .map(serde_yaml::from_value::<BTreeMap<String, serde_yaml::Value>>)
        .transpose()
        .map_err(|e| Ros2Error::Config(format!("parameter file, block {key}: {e}")))?
        .ok_or_else(|| {
            Ros2Error::Config(format!("parameter file, block {key}: no ros__parameters"))
        })?;
        let names: Vec<String> = block.keys().cloned().collect();
        let b = &mut block;
        let mut params = Self {
            map_frame: take(b, "map_frame")?,
            odom_frame: take(b, "odom_frame")?,
            base_frame: take(b, "base_frame")?,
            scan_topic: take(b, "scan_topic")?,
            odom_topic: take(b, "odom_topic")?,
            mode: take(b, "mode")?,
            map_file_name: take(b, "map_file_name")?,
            resolution: take(b, "resolution")?,
            max_laser_range: take(b, "max_laser_range")?,
            map_update_interval: take(b, "map_update_interval")?,
            range_up_topic: take(b, "range_up_topic")?,
            range_down_topic: take(b, "range_down_topic")?,
            imu_topic: take(b, "imu_topic")?,
            rgb_topic: take(b, "rgb_topic")?,
            depth_topic: take(b, "depth_topic")?,
            camera_info_topic: take(b, "camera_info_topic")?,
            given: Vec::new(),
            other: BTreeMap::new(),
        };
        params.given = names
            .into_iter()
            .filter(|n| !block.contains_key(n))
            .collect();
        params.other = block;
        Ok(params)
    }

    /// Refuses a file with parameters other than `allowed` (for a node that reads no
    /// `slam_toolbox` file, `node` naming it in the error).
    ///
    /// ```
    /// use slamkit_ros2::params::RosParams;
    /// let p = RosParams::parse("/**:\n  ros__parameters:\n    rgb_topc: /c\n", "slamkit").unwrap();
    /// let e = p.only("vo", &["rgb_topic"]).unwrap_err().to_string();
    /// assert!(e.contains("rgb_topc"), "{e}");
    /// ```
    ///
    /// # Errors
    /// [`Ros2Error::Config`] naming the parameters refused and those taken.
    pub fn only(&self, node: &str, allowed: &[&str]) -> Result<(), Ros2Error> {
        let refused: Vec<&str> = self
            .given
            .iter()
            .chain(self.other.keys())
            .map(String::as_str)
            .filter(|name| !allowed.contains(name))
            .collect();
        if refused.is_empty() {
            return Ok(());
        }
        Err(Ros2Error::Config(format!(
            "parameter file: {} not used by slamkit ros2 {node} (it takes {})",
            refused.join(", "),
            allowed.join(", ")
        )))
    }

    /// Reads and parses the parameter file at `path` ([`RosParams::parse`]).
    ///
    /// # Errors
    /// [`Ros2Error::Config`] naming the file when it cannot be read or parsed.
    pub fn load(path: &std::path::Path, node_name: &str) -> Result<Self, Ros2Error> {
        let name = path.display();
        let text = std::fs::read_to_string(path)
            .map_err(|e| Ros2Error::Config(format!("reading {name}: {e}")))?;
        Self::parse(&text, node_name).map_err(|e| Ros2Error::Config(format!("{name}: {e}")))
    }

    /// Names of the parameters slamkit does not use, sorted.
    pub fn ignored(&self) -> Vec<&str> {
        self.other.keys().map(String::as_str).collect()
    }

    /// The saved map named by `map_file_name` (`.skmap` added when it has no extension).
    pub fn map_file(&self) -> Option<PathBuf> {
        self.map_file_name.as_ref().map(|name| {
            let path = PathBuf::from(name);
            if path.extension().is_some() {
                path
            } else {
                path.with_extension("skmap")
            }
        })
    }

    /// Lays the parameters over the node's settings and the session's longest range
    /// (`max_range_m`, the lidar's usable range in the session's settings).
    ///
    /// # Errors
    /// [`Ros2Error::Config`] for a resolution, range or interval that is not positive.
    pub fn apply(
        &self,
        node: &mut LidarNodeConfig,
        max_range_m: &mut f64,
    ) -> Result<(), Ros2Error> {
        let positive = |name: &str, v: Option<f64>| match v {
            Some(x) if !(x.is_finite() && x > 0.0) => Err(Ros2Error::Config(format!(
                "{name} must be a positive number, not {x}"
            ))),
            _ => Ok(v),
        };
        for (slot, value) in [
            (&mut node.map_frame, &self.map_frame),
            (&mut node.odom_frame, &self.odom_frame),
            (&mut node.base_frame, &self.base_frame),
            (&mut node.scan_topic, &self.scan_topic),
        ] {
            if let Some(v) = value {
                slot.clone_from(v);
            }
        }
        if let Some(topic) = &self.odom_topic {
            node.odom_topic = (!topic.is_empty()).then(|| topic.clone());
        }
        if let Some(mode) = self.mode {
            node.mode = mode;
        }
        if let Some(r) = positive("resolution", self.resolution)? {
            node.resolution_m = r;
        }
        if let Some(s) = positive("map_update_interval", self.map_update_interval)? {
            node.map_update_interval_s = s;
        }
        if let Some(r) = positive("max_laser_range", self.max_laser_range)? {
            *max_range_m = r;
        }
        Ok(())
    }

    /// Lays a drone's topic parameters over `topics`.
    pub fn apply_drone(&self, topics: &mut DroneTopics) {
        if let Some(t) = &self.range_up_topic {
            topics.range_up_topic.clone_from(t);
        }
        if let Some(t) = &self.range_down_topic {
            topics.range_down_topic.clone_from(t);
        }
        if let Some(t) = &self.imu_topic {
            topics.imu_topic = (!t.is_empty()).then(|| t.clone());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_slam::LidarSlamConfig;

    #[test]
    fn a_slam_toolbox_style_file_applies() {
        let text = "/**:\n  ros__parameters:\n    odom_topic: \"\"\n    mode: localization\n    \
                    map_file_name: maps/office\n    resolution: 0.1\n    max_laser_range: 12.0\n    \
                    solver_plugin: solver_plugins::CeresSolver\n";
        let p = RosParams::parse(text, "slamkit").unwrap();
        let (mut node, mut session) = (LidarNodeConfig::default(), LidarSlamConfig::default());
        p.apply(&mut node, &mut session.icp.max_range_m).unwrap();
        assert_eq!(node.odom_topic, None);
        assert_eq!(node.mode, NodeMode::Localization);
        assert_eq!(node.resolution_m, 0.1);
        assert_eq!(session.icp.max_range_m, 12.0);
        assert_eq!(p.map_file(), Some(PathBuf::from("maps/office.skmap")));
        assert_eq!(p.ignored(), ["solver_plugin"]);
    }

    #[test]
    fn bad_files_give_clear_errors() {
        let wrong_type = "slamkit:\n  ros__parameters:\n    resolution: fine\n";
        let e = RosParams::parse(wrong_type, "slamkit")
            .unwrap_err()
            .to_string();
        assert!(e.contains("resolution"), "{e}");
        let two = "a:\n  ros__parameters: {}\nb:\n  ros__parameters: {}\n";
        let e = RosParams::parse(two, "slamkit").unwrap_err().to_string();
        assert!(e.contains("no block for node slamkit"), "{e}");
        let negative = "slamkit:\n  ros__parameters:\n    resolution: -1.0\n";
        let p = RosParams::parse(negative, "slamkit").unwrap();
        let e = p
            .apply(&mut LidarNodeConfig::default(), &mut 20.0)
            .unwrap_err();
        assert!(e.to_string().contains("positive"), "{e}");
        assert!(RosParams::parse("[1, 2]", "slamkit").is_err());
    }

    #[test]
    fn a_drones_topics_apply() {
        let text = "slamkit:\n  ros__parameters:\n    range_up_topic: /tof/up\n    \
                    range_down_topic: /tof/down\n    imu_topic: \"\"\n";
        let p = RosParams::parse(text, "slamkit").unwrap();
        let mut topics = DroneTopics::default();
        p.apply_drone(&mut topics);
        assert_eq!(
            (
                topics.range_up_topic.as_str(),
                topics.range_down_topic.as_str()
            ),
            ("/tof/up", "/tof/down")
        );
        assert_eq!(topics.imu_topic, None);
        assert!(p.ignored().is_empty());
    }
}
