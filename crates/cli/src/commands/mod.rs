//! One module per subcommand: its clap arguments and its `run` function.

pub mod bag;
pub mod demo;
pub mod eval;
pub mod fleet;
pub mod fleet_sim;
pub mod lidar;
pub mod lidar_drone;
pub mod lidar_mcl;
pub mod map;
pub mod nav;
pub mod plan;
pub mod ros2;
pub mod sim;
pub mod vo;
