//! `slamkit ros2 lidar`: the ROS 2 node ([`slamkit_ros2`]) with its arguments; on stop
//! (Ctrl-C, SIGTERM, or `--idle-exit`) the map, trajectory and report go to `--out`.

use crate::output::finish;
use anyhow::Context;
use serde_json::json;
use slamkit_core::Pose2;
use slamkit_io::output_folder::OutputFolder;
use slamkit_ros2::params::RosParams;
use slamkit_ros2::{run_lidar_node, LidarNodeConfig, NodeMode};
use slamkit_slam::lidar::LidarMap;
use slamkit_slam::{LidarMethod, LidarSlam, LidarSlamConfig};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `slamkit ros2`.
#[derive(Debug, clap::Args)]
pub struct Ros2Args {
    #[command(subcommand)]
    node: Ros2Node,
}

#[derive(Debug, clap::Subcommand)]
enum Ros2Node {
    /// 2D lidar SLAM (or localisation in a saved map) on /scan and /odom; publishes /map,
    /// map→odom on /tf and /pose.
    Lidar(LidarNodeArgs),
}

/// Arguments of `slamkit ros2 lidar`.
#[derive(Debug, clap::Args)]
struct LidarNodeArgs {
    /// ROS 2 parameter file (`slam_toolbox` names: map_frame, odom_frame, base_frame,
    /// scan_topic, odom_topic, mode, map_file_name, resolution, max_laser_range,
    /// map_update_interval).
    #[arg(long)]
    params: Option<PathBuf>,
    /// Localise in this saved map (`.skmap`) instead of building one.
    #[arg(long, conflicts_with = "continue_map")]
    localize: Option<PathBuf>,
    /// Continue this saved map (`.skmap`).
    #[arg(long = "continue")]
    continue_map: Option<PathBuf>,
    /// Named profile of the robot (or a `.toml` profile file): its `[lidar]` settings.
    #[arg(long)]
    profile: Option<String>,
    /// TOML file laid over the profile's settings (as for `slamkit lidar`).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Stop once no message came for this many seconds after the first scan.
    #[arg(long)]
    idle_exit: Option<f64>,
    /// Where the map, trajectory and report go when the node stops.
    #[arg(long, default_value = "out/ros2")]
    out: PathBuf,
}

/// The files `slamkit ros2 lidar` writes in `--out`.
const OUTPUTS: &[&str] = &[
    "trajectory.tum",
    "map.pgm",
    "map.yaml",
    "map.png",
    "map.skmap",
    "report.json",
];

/// Runs `slamkit ros2`.
pub fn run(args: &Ros2Args) -> anyhow::Result<()> {
    match &args.node {
        Ros2Node::Lidar(a) => lidar(a),
    }
}

fn lidar(args: &LidarNodeArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let mut node = LidarNodeConfig {
        idle_exit_s: args.idle_exit,
        ..LidarNodeConfig::default()
    };
    if let Ok(id) = std::env::var("ROS_DOMAIN_ID") {
        node.domain_id = id
            .parse()
            .with_context(|| format!("ROS_DOMAIN_ID={id} is not a domain number"))?;
    }
    let params = match &args.params {
        Some(path) => RosParams::load(path, &node.node_name)?,
        None => RosParams::default(),
    };
    if !params.ignored().is_empty() {
        let ignored = params.ignored().join(", ");
        eprintln!("note: parameters not used by slamkit: {ignored}");
    }
    let localize = args.localize.clone().or_else(|| {
        (params.mode == Some(NodeMode::Localization))
            .then(|| params.map_file())
            .flatten()
    });
    let in_map = localize.is_some() || args.continue_map.is_some();
    let mut config = LidarSlamConfig::from_files(
        LidarMethod::Icp,
        in_map,
        args.profile.as_deref(),
        args.config.as_deref(),
    )?;
    params.apply(&mut node, &mut config)?;
    if localize.is_some() {
        node.mode = NodeMode::Localization;
    }
    anyhow::ensure!(
        node.mode == NodeMode::Mapping || localize.is_some(),
        "mode: localization needs a map: --localize MAP.skmap or map_file_name"
    );
    let load = |path: &PathBuf| {
        LidarMap::load(path)
            .map(|(map, _)| map)
            .with_context(|| format!("loading {}", path.display()))
    };
    let session = match (&localize, &args.continue_map) {
        (Some(path), _) => LidarSlam::localise(config, load(path)?)?,
        (None, Some(path)) => LidarSlam::resume(config, load(path)?)?,
        (None, None) => LidarSlam::new(config, Pose2::identity())?,
    };
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let stop = crate::output::stop_flag()?;
    println!(
        "slamkit ros2 lidar: {} ({}) -> {}, {} on /tf, {}; Ctrl-C stops and saves to {}",
        node.scan_topic,
        node.odom_topic.as_deref().unwrap_or("no odometry"),
        node.map_topic,
        format_args!("{}->{}", node.map_frame, node.odom_frame),
        node.pose_topic,
        args.out.display()
    );
    let run = run_lidar_node(&node, session, &stop)?;
    let out = folder.path();
    let trajectory = run.session.trajectory();
    slamkit_io::trajectory_file::write_tum(&out.join("trajectory.tum"), &trajectory)?;
    if !run.scans.is_empty() || localize.is_some() {
        slamkit_map::save_grid_files(&run.session.output_grid(&run.scans)?, &out.join("map"))?;
        run.session.map_file()?.save(&out.join("map.skmap"))?;
    }
    let counts = run.session.frame_counts();
    let report = json!({
        "input": "ros2",
        "method": if localize.is_some() { "localise" } else { "icp" },
        "config": run.session.config(),
        "node": run.stats,
        "frames": {
            "read": run.stats.scans_received,
            "processed": counts.processed,
            "skipped": counts.skipped,
            "failed": counts.failed,
        },
        "session": run.session.stats(),
        "wall_seconds": started.elapsed().as_secs_f64(),
        "timings_ms": run.session.timings().summary(),
        "node_latency_ms": run.stats.latency.summary(),
    });
    finish(folder, &report)?;
    println!(
        "scans: {} received, {} processed; outputs in {}",
        run.stats.scans_received,
        run.stats.scans_processed,
        args.out.display()
    );
    Ok(())
}
