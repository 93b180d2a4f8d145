//! `slamkit ros2 lidar`: the ROS 2 node ([`slamkit_ros2`]) with its arguments; on stop
//! (Ctrl-C, SIGTERM, or `--idle-exit`) the map, trajectory and report go to `--out`.

use crate::output::finish;
use slamkit_io::output_folder::OutputFolder;
use slamkit_ros2::{run_lidar_node, LidarNodeRequest, LidarNodeRun};
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

/// Runs `slamkit ros2`.
pub fn run(args: &Ros2Args) -> anyhow::Result<()> {
    match &args.node {
        Ros2Node::Lidar(a) => lidar(a),
    }
}

fn lidar(args: &LidarNodeArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let request = LidarNodeRequest {
        params: args.params.clone(),
        localize: args.localize.clone(),
        continue_map: args.continue_map.clone(),
        profile: args.profile.clone(),
        config: args.config.clone(),
        idle_exit_s: args.idle_exit,
        domain_id: std::env::var("ROS_DOMAIN_ID").ok(),
    };
    let setup = request.setup()?;
    if !setup.ignored_params.is_empty() {
        let ignored = setup.ignored_params.join(", ");
        eprintln!("note: parameters not used by slamkit: {ignored}");
    }
    let folder = OutputFolder::create(&args.out, LidarNodeRun::OUTPUTS)?;
    let stop = crate::output::stop_flag()?;
    let out = args.out.display();
    let what = setup.node.describe();
    println!("slamkit ros2 lidar: {what}; Ctrl-C stops and saves to {out}");
    let run = run_lidar_node(&setup.node, setup.session, &stop)?;
    run.write_outputs(folder.path())?;
    finish(folder, &run.report(started.elapsed().as_secs_f64()))?;
    println!("{}; outputs in {out}", run.summary());
    Ok(())
}
