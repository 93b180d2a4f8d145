//! `slamkit`: localisation, mapping and navigation for small robots, from the command line.
//!
//! The command-line contract (subcommands, flags, output files) is in DESIGN.md; tests,
//! benchmarks and users call it, so it changes only on purpose.

mod commands;
mod output;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// slamkit: localisation, mapping and navigation for small robots (drones, balancing and
/// wheeled robots with a CPU and no GPU).
#[derive(Debug, Parser)]
#[command(name = "slamkit", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Simulate a robot in a built-in world, run SLAM on it and report the errors (no download).
    Demo(commands::demo::DemoArgs),
    /// Visual odometry on an RGB-D or stereo dataset folder.
    Vo(commands::vo::VoArgs),
    /// 2D lidar SLAM (ICP or particle filter), or localisation in / continuation of a saved
    /// map, on a CARMEN log or a ROS 1 bag.
    Lidar(Box<commands::lidar::LidarArgs>),
    /// What a ROS 1 bag holds: topics, types, counts, time span.
    Bag(commands::bag::BagArgs),
    /// Inspect and export saved maps (`.skmap`).
    Map(commands::map::MapArgs),
    /// Accuracy of a trajectory against ground truth: ATE, RPE, relations metric.
    Eval(commands::eval::EvalArgs),
    /// Plan a path on an occupancy grid map.
    Plan(commands::plan::PlanArgs),
    /// Simulate sensors in a world and write real dataset formats with ground truth.
    Sim(commands::sim::SimArgs),
    /// Closed loop in the simulator: localise, map, plan and drive to a goal.
    Nav(commands::nav::NavArgs),
    /// A ROS 2 node (no ROS install needed): live topics in, map, tf and pose out.
    Ros2(commands::ros2::Ros2Args),
    /// Many robots, one map, over Zenoh: a robot playing a log, or the merger.
    Fleet(commands::fleet::FleetArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Demo(args) => commands::demo::run(args),
        Command::Vo(args) => commands::vo::run(args),
        Command::Lidar(args) => commands::lidar::run(args),
        Command::Bag(args) => commands::bag::run(args),
        Command::Map(args) => commands::map::run(args),
        Command::Eval(args) => commands::eval::run(args),
        Command::Plan(args) => commands::plan::run(args),
        Command::Sim(args) => commands::sim::run(args),
        Command::Nav(args) => commands::nav::run(args),
        Command::Ros2(args) => commands::ros2::run(args),
        Command::Fleet(args) => commands::fleet::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) if err.is::<output::Unsuccessful>() => {
            eprintln!("unsuccessful: {err}");
            ExitCode::from(output::UNSUCCESSFUL_EXIT)
        }
        Err(err) => {
            // One line: the error and its causes, outermost first; never a backtrace.
            eprintln!("error: {}", output::error_chain(&err));
            ExitCode::FAILURE
        }
    }
}
