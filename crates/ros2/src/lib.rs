//! slamkit on a live ROS 2 robot, with no ROS installation: a node over RustDDS (through
//! `ros2-client`, both pure Rust) that subscribes to the robot's sensors, runs the same
//! session the command line runs on files ([`slamkit_slam`]), and publishes the map, the
//! `map → odom` transform and the pose as `slam_toolbox` does, so RViz, Foxglove and Nav2 take
//! them as they are.
//!
//! * [`lidar_node`]: `slamkit ros2 lidar` (2D lidar + wheel odometry).
//! * [`drone_node`]: `slamkit ros2 drone` (2D lidar + up/down range finders + IMU: layered
//!   SLAM), with [`drone_readings`]: the finders and the IMU as the session's readings.
//! * [`scan_node`]: what the lidar and drone nodes share (readers, threads, publishing).
//! * [`lidar_run`]: its settings and session from a request, its output files and report.
//! * [`pairing`]: live scans tied to odometry by the rule of the bag reader, in publication
//!   order.
//! * [`vo_node`]: `slamkit ros2 vo` (an RGB-D camera such as a RealSense).
//! * [`vo_run`]: its settings and session from a request, its output files and report.
//! * [`rgbd_pairing`]: live colour and depth images paired by stamp, as the bag reader pairs
//!   them (the camera input of the vo and nav nodes reads and pairs on threads of its own).
//! * [`nav_node`]: `slamkit ros2 nav` (a ground robot with an RGB-D camera, driven to a goal
//!   on `/cmd_vel`).
//! * [`sim_node`]: `slamkit sim --ros2` (the simulated robot of `slamkit nav`, its camera
//!   published live, driven by `/cmd_vel`), and [`drone_sim_node`]: the simulated drone's
//!   flight, its lidar, range finders and IMU published live.
//! * [`dds`]: what every node does with DDS (discovery, QoS, readers, the pose writers).
//! * [`params`]: the ROS-style parameter file (`--params FILE.yaml`).
//! * [`msgs`], [`grid_msg`]: the messages, and the occupancy grid as `nav_msgs/OccupancyGrid`.
//!
//! Frames follow REP 105 (`map`, `odom`, `base_link`); discovery is DDS's default (multicast
//! on the domain's ports), as every ROS 2 node's, or this machine only over `127.0.0.1` when
//! asked (`ROS_LOCALHOST_ONLY=1`, [`dds::Discovery`]).

mod camera_input;
pub mod dds;
pub mod drone_node;
pub mod drone_readings;
pub mod drone_sim_node;
pub mod grid_msg;
pub mod lidar_node;
pub mod lidar_run;
pub mod msgs;
pub mod nav_node;
pub mod pairing;
pub mod params;
pub mod rgbd_pairing;
pub mod scan_node;
pub mod sim_node;
pub mod vo_node;
pub mod vo_run;

pub use drone_node::{run_drone_node, DroneNodeConfig, DroneNodeRun, DroneNodeSetup};
pub use drone_sim_node::{run_drone_sim_node, DroneSimNodeConfig, DroneSimNodeStats};
pub use lidar_node::{run_lidar_node, LidarNodeConfig, LidarNodeRun, NodeMode, NodeStats};
pub use lidar_run::{LidarNodeRequest, LidarNodeSetup};
pub use nav_node::{run_nav_node, NavNodeConfig, NavNodeRun, NavNodeStats};
pub use scan_node::DroneTopics;
pub use sim_node::{run_sim_node, SimNodeConfig, SimNodeStats};
pub use vo_node::{run_vo_node, VoNodeConfig, VoNodeRun, VoNodeStats};
pub use vo_run::{VoNodeRequest, VoNodeSetup};

/// Why the node cannot run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Ros2Error {
    /// DDS could not start, or a reader or writer could not be made.
    #[error("DDS: {0}")]
    Dds(String),
    /// A node or topic name that ROS 2 does not accept.
    #[error("not a valid ROS 2 name: {0}")]
    Name(String),
    /// A setting out of range, or a parameter file that does not read.
    #[error("settings: {0}")]
    Config(String),
    /// The map could not be written.
    #[error("saving the map: {0}")]
    MapFile(String),
    /// The session failed.
    #[error(transparent)]
    Slam(#[from] slamkit_slam::SlamError),
}
