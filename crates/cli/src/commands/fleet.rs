//! `slamkit fleet robot|merger`: one robot of a fleet playing a log and publishing its map
//! updates over Zenoh, and the merger (all of it in `slamkit_fleet::{RobotNode, MergerNode}`).

use crate::output::{finish, progress_bar, stop_flag};
use slamkit_fleet::{robot_node::ROBOT_FILES, MergerNode, MergerNodeConfig, PeerConfig};
use slamkit_fleet::{RobotNode, RobotNodeConfig};
use slamkit_io::output_folder::OutputFolder;
use slamkit_slam::{merge::output::MERGE_FILES, LidarMethod, LidarSlam, LidarSlamConfig};
use std::path::PathBuf;

/// Arguments of `slamkit fleet`: one process of a fleet, on explicit endpoints such as
/// `tcp/127.0.0.1:7447` (multicast scouting is off).
#[derive(Debug, clap::Args)]
pub struct FleetArgs {
    #[command(subcommand)]
    command: FleetCommand,
    /// The fleet's name: its keys are `slamkit/<fleet>/...`.
    #[arg(long, global = true, default_value = "fleet")]
    fleet: String,
    /// Endpoints to listen on.
    #[arg(long, global = true)]
    listen: Vec<String>,
    /// Endpoints of peers to connect to.
    #[arg(long, global = true)]
    connect: Vec<String>,
    /// Output folder (a robot keeps its messages there, in updates.skmu, and resumes them).
    #[arg(long, global = true, default_value = "out/fleet")]
    out: PathBuf,
}

#[derive(Debug, clap::Subcommand)]
enum FleetCommand {
    /// ICP-SLAM on a CARMEN log or ROS 1 bag played at `--rate`, publishing its map updates
    /// and keeping the fleet's newest merged map in merged.skmap; then writes trajectory.tum,
    /// map.skmap, sent.skmap and report.json, and answers queries until Ctrl-C, when it writes
    /// report.json again with the merged maps taken since.
    Robot {
        /// The log.
        log: PathBuf,
        /// The robot's name in the fleet.
        #[arg(long)]
        robot: String,
        /// Log seconds played per second (0: as fast as it can).
        #[arg(long, default_value_t = 1.0)]
        rate: f64,
        /// Drop this fraction of publications on purpose (tests of recovery by query).
        #[arg(long)]
        loss: Option<f64>,
        /// Named profile of the robot (or a profile file `X.toml`): its `[lidar]` settings,
        /// as `slamkit lidar --profile` takes them.
        #[arg(long)]
        profile: Option<String>,
        /// TOML file with ICP-SLAM's settings laid over the profile's, as `slamkit lidar
        /// --config` takes them for a new ICP map.
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Merges the robots' maps as updates arrive, publishes each merge on
    /// `slamkit/<fleet>/merged/{map,report}`; on Ctrl-C writes the last as `map merge` does.
    Merger {
        /// Seconds between merges while updates arrive.
        #[arg(long, default_value_t = 10.0)]
        merge_every: f64,
    },
}

/// Runs `slamkit fleet`.
pub fn run(args: &FleetArgs) -> anyhow::Result<()> {
    let (stop, out) = (stop_flag()?, &args.out);
    let peer = PeerConfig {
        listen: args.listen.clone(),
        connect: args.connect.clone(),
    };
    match &args.command {
        FleetCommand::Robot {
            log,
            robot,
            rate,
            loss,
            profile,
            config,
        } => {
            let settings = LidarSlamConfig::from_files(
                LidarMethod::Icp,
                false,
                profile.as_deref(),
                config.as_deref(),
            )?;
            let log = crate::commands::lidar::read_log(log, &Default::default())?;
            let slam = LidarSlam::new(settings, Default::default())?;
            let mut config = RobotNodeConfig::new(&args.fleet, robot, peer, out);
            (config.rate, config.loss) = (*rate, loss.map(|p| (p, 1)));
            let mut node = RobotNode::start(config, slam)?;
            let bar = progress_bar(log.scans.len() as u64, "robot");
            let done = node.play(&log, &stop, |n| bar.set_position(n as u64))?;
            let write = |node: &RobotNode| -> anyhow::Result<()> {
                let folder = OutputFolder::create(out, ROBOT_FILES)?;
                let report = node.write(folder.path(), &log)?;
                finish(folder, &report)
            };
            write(&node)?;
            bar.finish_and_clear();
            let done = if done { "done" } else { "stopped" };
            println!("log {done}; answering queries until Ctrl-C");
            node.serve(&stop)?;
            write(&node)
        }
        FleetCommand::Merger { merge_every } => {
            let mut config = MergerNodeConfig::new(&args.fleet, peer);
            config.merge_every_s = *merge_every;
            let mut node = MergerNode::start(config)?;
            node.run(&stop)?;
            let folder = OutputFolder::create(out, MERGE_FILES)?;
            let report = node.write(folder.path())?;
            finish(folder, &report)?;
            println!("{} merges; outputs in {}", node.merges(), out.display());
            Ok(())
        }
    }
}
