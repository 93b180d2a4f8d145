//! slamkit-slam: the systems. One online session per robot rig, usable from any program (the
//! CLI, a ROS 2 node, a Python binding, a fleet process), and the map file that lets what a
//! session learned outlive it.
//!
//! A session takes timestamped [`Observation`](slamkit_core::Observation)s one at a time and
//! answers each with an [`Update`] (pose, tracking status, what changed in the map); it can
//! [`save`](Session::save) its map as a `.skmap` file and be built again from one, to localise
//! in it or to continue it. Sessions start from a given pose (identity by default) or from a
//! loaded map; none ever reads ground truth.
//!
//! * [`session`]: the [`Session`] trait and [`Update`].
//! * [`collator`]: restores time order when sources interleave.
//! * [`drone`]: [`DroneSlam`], layered 2D lidar SLAM for a drone with up/down range finders,
//!   attitude and gyro, and optionally optical flow and a particle filter; its grids per
//!   layer, and its run on a simulated flight scored against the truth (`drone::simulated`,
//!   `drone::kidnapped`).
//! * [`map_file`]: the `.skmap` container: header, sections, checksum, atomic writes.
//! * [`memory`]: this process's peak memory and the machine's, for reports and preflight checks.
//! * [`report`]: pieces of the JSON run reports every shell assembles.
//! * [`odometry_gate`]: odometry jumps a robot cannot have made, taken as no motion.
//! * [`profile`]: named profiles (`config/*.toml`) and configuration files laid over a
//!   session's settings.
//! * [`lidar`]: [`LidarSlam`], 2D lidar SLAM (ICP-SLAM or a particle filter) and localisation in
//!   a saved map.
//! * [`visual`]: [`VisualSlam`], visual odometry of an RGB-D or stereo camera as a session, and
//!   [`visual::run`], which overlaps decoding and frame preparation with tracking;
//!   `visual::simulated` runs it on a simulated camera and scores it.
//! * [`map_updates`]: what a robot of a fleet sends about its map, incrementally, and its
//!   map rebuilt from those messages in any order.
//! * [`merge`]: offline merging of 2D lidar maps whose relative poses are unknown (place
//!   recognition, verification, pairwise consistency, joint pose-graph optimisation).
//! * [`ground_robot`]: [`GroundRobotNav`], a ground robot's camera session, floor grid, planner
//!   and path tracker; its closed loop in the simulator.
//!
//! Nothing in this crate prints, reads arguments or exits the process.

pub mod collator;
pub mod drone;
mod error;
pub mod ground_robot;
pub mod lidar;
pub mod map_file;
pub mod map_updates;
pub mod memory;
pub mod merge;
pub mod odometry_gate;
pub mod profile;
pub mod record;
pub mod report;
pub mod session;
pub mod visual;

pub use collator::Collator;
pub use drone::{DroneSlam, DroneSlamConfig};
pub use error::SlamError;
pub use ground_robot::GroundRobotNav;
pub use lidar::{LidarMap, LidarMethod, LidarSlam, LidarSlamConfig};
pub use session::{MapChange, Session, TrackingStatus, Update};
pub use visual::VisualSlam;
