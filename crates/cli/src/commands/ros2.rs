//! `slamkit ros2 lidar|drone|vo|nav`: the ROS 2 nodes ([`slamkit_ros2`]) with their arguments; on stop
//! (Ctrl-C, SIGTERM, or `--idle-exit`) the map, trajectory and report go to `--out`.

use crate::commands::plan::parse_xy;
use crate::commands::vo::{CameraTopicArgs, Frontend};
use crate::output::finish;
use slamkit_io::output_folder::OutputFolder;
use slamkit_ros2::dds::Discovery;
use slamkit_ros2::{run_drone_node, DroneNodeRun};
use slamkit_ros2::{run_lidar_node, run_vo_node, LidarNodeRequest, LidarNodeRun};
use slamkit_ros2::{run_nav_node, NavNodeConfig, NavNodeRun, VoNodeRequest, VoNodeRun};
use slamkit_slam::ground_robot::closed_loop::NavLoopConfig;
use slamkit_slam::profile::settings;
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
    /// A drone's layered 2D lidar SLAM (or localisation in a saved map) on /scan, the up and
    /// down range finders (/range_up, /range_down), /imu and, where present, /odom; publishes
    /// the current height layer's map on /map, map→base_link (map→odom with odometry) on
    /// /tf, /pose, /path and the layer on /slamkit/layer.
    Drone(LidarNodeArgs),
    /// Visual odometry / SLAM (or localisation in a saved map) on an RGB-D camera's colour,
    /// aligned depth and camera_info (a RealSense driver's topics by default); publishes
    /// map→camera_link on /tf, /pose and /path.
    Vo(VoNodeArgs),
    /// A ground robot with an RGB-D camera driven to a goal (`--goal`, or /goal_pose as RViz
    /// sends it): the session of `slamkit nav` on the camera's topics; publishes /cmd_vel,
    /// map→base_footprint on /tf, /pose, /path, /plan and /map.
    Nav(NavNodeArgs),
}

/// Arguments of `slamkit ros2 nav`.
#[derive(Debug, clap::Args)]
struct NavNodeArgs {
    /// The camera's topics (default: the RealSense ROS 2 driver's, with aligned depth).
    #[command(flatten)]
    topics: CameraTopicArgs,
    /// Goal `X,Y` in the map frame (m; the map frame is the base frame where the robot
    /// stands at the first frame); without it the robot waits for one on /goal_pose.
    #[arg(long, allow_hyphen_values = true)]
    goal: Option<String>,
    /// ROS 2 parameter file: map_frame, base_frame, rgb_topic, depth_topic,
    /// camera_info_topic; any other is an error. The options given here win.
    #[arg(long)]
    params: Option<PathBuf>,
    /// The robot's frame on the floor, the child of `map` on /tf (the camera's mounting from
    /// it to the images' optical frame comes from /tf_static) [default: base_footprint].
    #[arg(long)]
    base_frame: Option<String>,
    /// Named profile of the robot (or a profile file `X.toml`): its `[nav]` settings, as for
    /// `slamkit nav`.
    #[arg(long)]
    profile: Option<String>,
    /// TOML file laid over the profile's settings (as for `slamkit nav`; the `sim` table is
    /// not used).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Frames waiting for the session at most; newer ones are dropped and counted.
    #[arg(long)]
    frame_queue: Option<usize>,
    /// Stop once no image came for this many seconds.
    #[arg(long)]
    idle_exit: Option<f64>,
    /// Where the trajectory, map and report go when the node stops.
    #[arg(long, default_value = "out/ros2-nav")]
    out: PathBuf,
}

/// Arguments of `slamkit ros2 vo`.
#[derive(Debug, clap::Args)]
struct VoNodeArgs {
    /// The camera's topics (default: the RealSense ROS 2 driver's, with aligned depth:
    /// /camera/camera/color/image_raw, /camera/camera/aligned_depth_to_color/image_raw,
    /// /camera/camera/color/camera_info).
    #[command(flatten)]
    topics: CameraTopicArgs,
    /// ROS 2 parameter file: map_frame, base_frame, mode (mapping|localization),
    /// map_file_name, rgb_topic, depth_topic, camera_info_topic; any other is an error. The
    /// options given here win.
    #[arg(long)]
    params: Option<PathBuf>,
    /// The frame published as the child of `map` on /tf (the camera's mounting from it to
    /// the images' optical frame comes from /tf_static) [default: camera_link].
    #[arg(long)]
    base_frame: Option<String>,
    /// Feature front end.
    #[arg(long, value_enum, default_value = "klt")]
    frontend: Frontend,
    /// Named profile of the camera (or a profile file `X.toml`): its `[vo]` settings.
    #[arg(long)]
    profile: Option<String>,
    /// TOML file laid over the profile's settings (as for `slamkit vo`).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Visual SLAM: keyframes, place recognition and loop closure.
    #[arg(long)]
    slam: bool,
    /// Write the map to this `.skmap` when the node stops.
    #[arg(long)]
    save_map: Option<PathBuf>,
    /// Localise in this saved map (a `.skmap` of a `--slam` run) instead of building one.
    #[arg(long, conflicts_with_all = ["save_map", "slam"])]
    localize: Option<PathBuf>,
    /// Record what the node processed to this MCAP file (as `slamkit vo --record`: each
    /// frame's image and pose, the path every 100 frames, the final path and point map).
    #[arg(long)]
    record: Option<PathBuf>,
    /// Frames waiting for the session at most; newer ones are dropped and counted.
    #[arg(long)]
    frame_queue: Option<usize>,
    /// Stop once no image came for this many seconds.
    #[arg(long)]
    idle_exit: Option<f64>,
    /// Where the trajectory, point cloud and report go when the node stops.
    #[arg(long, default_value = "out/ros2-vo")]
    out: PathBuf,
}

/// Arguments of `slamkit ros2 lidar` and `slamkit ros2 drone`.
#[derive(Debug, clap::Args)]
struct LidarNodeArgs {
    /// ROS 2 parameter file (`slam_toolbox` names: map_frame, odom_frame, base_frame,
    /// scan_topic, odom_topic, mode, map_file_name, resolution, max_laser_range,
    /// map_update_interval; for the drone also range_up_topic, range_down_topic, imu_topic).
    #[arg(long)]
    params: Option<PathBuf>,
    /// Localise in this saved map (`.skmap`) instead of building one.
    #[arg(long, conflicts_with = "continue_map")]
    localize: Option<PathBuf>,
    /// Continue this saved map (`.skmap`).
    #[arg(long = "continue")]
    continue_map: Option<PathBuf>,
    /// Named profile of the robot (or a `.toml` profile file): its `[lidar]` settings (the
    /// drone's: `[drone]`).
    #[arg(long)]
    profile: Option<String>,
    /// TOML file laid over the profile's settings (as for `slamkit lidar`).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Stop once no message came for this many seconds after the first scan.
    #[arg(long)]
    idle_exit: Option<f64>,
    /// Record what the node processed to this MCAP file (as `slamkit lidar --record`: each
    /// scan with its pose, the map and path every 500 scans and at the end; the lidar node
    /// only).
    #[arg(long)]
    record: Option<PathBuf>,
    /// Where the map, trajectory and report go when the node stops (default `out/ros2`, the
    /// drone's `out/ros2-drone`).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Runs `slamkit ros2`.
pub fn run(args: &Ros2Args) -> anyhow::Result<()> {
    match &args.node {
        Ros2Node::Lidar(a) => lidar(a),
        Ros2Node::Drone(a) => drone(a),
        Ros2Node::Vo(a) => vo(a),
        Ros2Node::Nav(a) => nav(a),
    }
}

/// The discovery the environment asks for (`ROS_DOMAIN_ID`, `ROS_LOCALHOST_ONLY`,
/// `ROS_AUTOMATIC_DISCOVERY_RANGE`).
pub(crate) fn discovery() -> anyhow::Result<Discovery> {
    let var = |name| std::env::var(name).ok();
    Ok(Discovery::from_env(
        var("ROS_DOMAIN_ID").as_deref(),
        var("ROS_LOCALHOST_ONLY").as_deref(),
        var("ROS_AUTOMATIC_DISCOVERY_RANGE").as_deref(),
    )?)
}

fn vo(args: &VoNodeArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let t = &args.topics;
    let request = VoNodeRequest {
        rgb_topic: t.rgb_topic.clone(),
        depth_topic: t.depth_topic.clone(),
        camera_info_topic: t.camera_info_topic.clone(),
        base_frame: args.base_frame.clone(),
        map_frame: None,
        params: args.params.clone(),
        frontend: crate::commands::vo::frontend_kind(args.frontend),
        profile: args.profile.clone(),
        config: args.config.clone(),
        slam: args.slam,
        localize: args.localize.clone(),
        save_map: args.save_map.clone(),
        record: args.record.clone(),
        frame_queue: args.frame_queue,
        idle_exit_s: args.idle_exit,
        discovery: discovery()?,
    };
    let setup = request.setup()?;
    let folder = OutputFolder::create(&args.out, VoNodeRun::OUTPUTS)?;
    let stop = crate::output::stop_flag()?;
    let out = args.out.display();
    println!(
        "slamkit ros2 vo: {}; Ctrl-C stops and saves to {out}",
        setup.describe()
    );
    let run = run_vo_node(&setup.node, |camera| setup.session(camera), &stop)?;
    let mut report = run.finish(&setup, folder.path())?;
    report["wall_seconds"] = serde_json::json!(started.elapsed().as_secs_f64());
    let summary = slamkit_slam::visual::run_files::summary(&report);
    finish(folder, &report)?;
    println!("{summary}\noutputs in {out}");
    Ok(())
}

fn nav(args: &NavNodeArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let goal = args
        .goal
        .as_deref()
        .map(|text| parse_xy(text, "goal"))
        .transpose()?;
    let t = &args.topics;
    let request = VoNodeRequest {
        rgb_topic: t.rgb_topic.clone(),
        depth_topic: t.depth_topic.clone(),
        camera_info_topic: t.camera_info_topic.clone(),
        base_frame: args.base_frame.clone(),
        params: args.params.clone(),
        frame_queue: args.frame_queue,
        idle_exit_s: args.idle_exit,
        discovery: discovery()?,
        ..VoNodeRequest::default()
    }
    .with_params("nav", slamkit_ros2::vo_run::NAV_PARAMS)?;
    if args.frame_queue == Some(0) {
        anyhow::bail!("--frame-queue 0: the frame queue must hold a frame");
    }
    let defaults = NavNodeConfig::default();
    let config = NavNodeConfig {
        camera: request.node_config(defaults.camera.clone()),
        ..defaults
    };
    let nav = settings(
        NavLoopConfig::default(),
        "nav",
        args.profile.as_deref(),
        args.config.as_deref(),
    )?
    .nav();
    let folder = OutputFolder::create(&args.out, NavNodeRun::OUTPUTS)?;
    let stop = crate::output::stop_flag()?;
    let out = args.out.display();
    let c = &config.camera;
    let heading = goal.map_or_else(
        || format!("the goal on {}", config.goal_topic),
        |g| format!("({}, {})", g.x, g.y),
    );
    println!(
        "slamkit ros2 nav: {} + {} ({}) to {heading} -> {}, {}->{} on {}, {}, {}, {}, {}; \
         Ctrl-C stops the robot and saves to {out}",
        c.rgb_topic,
        c.depth_topic,
        c.camera_info_topic,
        config.cmd_vel_topic,
        c.map_frame,
        c.base_frame,
        c.tf_topic,
        c.pose_topic,
        c.path_topic,
        config.plan_topic,
        config.map_topic
    );
    let run = run_nav_node(&config, &nav, goal, &stop)?;
    let mut report = run.finish(&nav, folder.path())?;
    report["wall_seconds"] = serde_json::json!(started.elapsed().as_secs_f64());
    finish(folder, &report)?;
    let s = &run.stats;
    println!(
        "{} commands, {} poses, {} frames before a goal, last status {:?}; outputs in {out}",
        s.commands_published, s.camera.poses_published, s.frames_before_goal, s.last_status
    );
    Ok(())
}

/// What `slamkit ros2 lidar` and `slamkit ros2 drone` are asked for.
fn lidar_request(args: &LidarNodeArgs) -> anyhow::Result<LidarNodeRequest> {
    Ok(LidarNodeRequest {
        params: args.params.clone(),
        localize: args.localize.clone(),
        continue_map: args.continue_map.clone(),
        profile: args.profile.clone(),
        config: args.config.clone(),
        idle_exit_s: args.idle_exit,
        record: args.record.clone(),
        discovery: discovery()?,
    })
}

fn lidar(args: &LidarNodeArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let out_dir = args.out.clone().unwrap_or_else(|| "out/ros2".into());
    let setup = lidar_request(args)?.setup()?;
    note_ignored(&setup.ignored_params);
    let folder = OutputFolder::create(&out_dir, LidarNodeRun::OUTPUTS)?;
    let stop = crate::output::stop_flag()?;
    let out = out_dir.display();
    let what = setup.node.describe();
    println!("slamkit ros2 lidar: {what}; Ctrl-C stops and saves to {out}");
    let run = run_lidar_node(&setup.node, setup.session, &stop)?;
    run.write_outputs(folder.path())?;
    finish(folder, &run.report(started.elapsed().as_secs_f64()))?;
    println!("{}; outputs in {out}", run.summary());
    Ok(())
}

/// Says which parameters of the file slamkit does not use.
fn note_ignored(ignored: &[String]) {
    if !ignored.is_empty() {
        eprintln!(
            "note: parameters not used by slamkit: {}",
            ignored.join(", ")
        );
    }
}

fn drone(args: &LidarNodeArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let out_dir = args.out.clone().unwrap_or_else(|| "out/ros2-drone".into());
    let setup = lidar_request(args)?.drone_setup()?;
    note_ignored(&setup.ignored_params);
    let folder = OutputFolder::create(&out_dir, DroneNodeRun::OUTPUTS)?;
    let stop = crate::output::stop_flag()?;
    let out = out_dir.display();
    let what = setup.node.describe();
    println!("slamkit ros2 drone: {what}; Ctrl-C stops and saves to {out}");
    let run = run_drone_node(&setup.node, setup.session, &stop)?;
    run.write_outputs(folder.path())?;
    finish(folder, &run.report(started.elapsed().as_secs_f64()))?;
    println!("{}; outputs in {out}", run.summary());
    Ok(())
}
