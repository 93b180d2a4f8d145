//! `slamkit fleet robot|merger`: one robot of a fleet playing a log and publishing its map
//! updates over Zenoh, and the merger (all of it in `slamkit_fleet::{RobotNode, MergerNode}`).

use crate::commands::fleet_sim::FleetSim;
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
        /// Leave the network (close the Zenoh session) FROM seconds of log time after the first
        /// scan, for SECONDS of log time, then join again (tests of a robot out of range).
        #[arg(long, value_name = "FROM,SECONDS", value_delimiter = ',')]
        disconnect: Option<Vec<f64>>,
        /// Named profile of the robot (or a profile file `X.toml`): its `[lidar]` settings,
        /// as `slamkit lidar --profile` takes them.
        #[arg(long)]
        profile: Option<String>,
        /// TOML file with ICP-SLAM's settings laid over the profile's, as `slamkit lidar
        /// --config` takes them for a new ICP map.
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Simulated ground robots, each a `fleet robot` process playing its own stretch of the
    /// world's drive path out and back, and a merger process, all on 127.0.0.1; writes the
    /// robots' and merger's folders and report.json with the errors against the truth.
    Sim {
        /// World: `small`, `large`, `office`, or a TOML world file.
        #[arg(long)]
        world: String,
        /// Robots in the fleet.
        #[arg(long, default_value_t = 3)]
        robots: usize,
        /// Seed of the robots' sensor noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Fraction of its publications each robot's sender drops.
        #[arg(long)]
        loss: Option<f64>,
        /// Simulated seconds the last robot spends off the network, from a quarter of its run.
        #[arg(long, value_name = "SECONDS")]
        disconnect: Option<f64>,
        /// Kill robot 0 at 40 % of its run and start it again; kill the merger at 70 % and
        /// start a new one.
        #[arg(long)]
        restart: bool,
        /// Simulated seconds played per wall second.
        #[arg(long, default_value_t = 10.0)]
        rate: f64,
        /// Seconds between the merger's merges while updates arrive.
        #[arg(long, default_value_t = 2.0)]
        merge_every: f64,
    },
    /// Merges the robots' maps as updates arrive, publishes each merge on
    /// `slamkit/<fleet>/merged/{map,report}`; on Ctrl-C writes the last as `map merge` does.
    Merger {
        /// Seconds between merges while updates arrive.
        #[arg(long, default_value_t = 10.0)]
        merge_every: f64,
        /// TOML file with merge settings laid over the defaults (the fields report.json shows
        /// under `config`, such as `[places] spacing_m = 1.0`).
        #[arg(long)]
        config: Option<PathBuf>,
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
            disconnect,
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
            config.disconnect = match disconnect.as_deref() {
                None => None,
                Some(&[from, seconds]) => Some((from, seconds)),
                Some(other) => anyhow::bail!("--disconnect {other:?}: give FROM,SECONDS"),
            };
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
        FleetCommand::Sim {
            world,
            robots,
            seed,
            loss,
            disconnect,
            restart,
            rate,
            merge_every,
        } => {
            let sim = FleetSim {
                world: world.clone(),
                robots: *robots,
                seed: *seed,
                loss: *loss,
                disconnect_s: *disconnect,
                restart: *restart,
                rate: *rate,
                merge_every_s: *merge_every,
                fleet: args.fleet.clone(),
                out: out.clone(),
            };
            crate::commands::fleet_sim::run(&sim, &stop)
        }
        FleetCommand::Merger {
            merge_every,
            config: merge_config,
        } => {
            let mut config = MergerNodeConfig::new(&args.fleet, peer);
            config.merge_every_s = *merge_every;
            config.merge = crate::commands::map::merge_config(merge_config.as_deref())?;
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
