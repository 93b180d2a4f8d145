//! One module per subcommand: its clap arguments and its `run` function.

pub mod demo;
pub mod eval;
pub mod lidar;
pub mod lidar_mcl;
pub mod nav;
pub mod plan;
pub mod sim;
pub mod vo;
