//! `slamkit sim`: simulated sensors in a world, written in real dataset formats.
//!
//! Writes in `--out` `world.toml` (the world simulated), `report.json` and the recording of
//! [`slamkit_sim::recording`]: `groundtruth.tum`, and by sensor `lidar.clf` + `lidar.relations`
//! (`lidar2d`), `ranges.csv` (`range`), `imu.csv` (`imu`), `flow.csv` (`flow`), the TUM RGB-D
//! folder `tum_rgbd_fr1/` (`rgbd`) and the KITTI folder `kitti_stereo/` (`stereo`). The three
//! CSV files are those `slamkit lidar LOG --ranges --imu --flow` reads ([`slamkit_io::drone_csv`]
//! documents them) and give the drone's layered SLAM the same input as `slamkit demo` on the
//! same world and seed.
//!
//! `--path loopN` drives the ground robot N times round the world's closed `drive_loop` (the
//! same places seen again, for `slamkit vo --slam`'s loop closing).
//!
//! `--duration` cuts the run short (camera folders hold 30 frames a second of run, about
//! 1.5 MB a frame). The same world, sensors, robot, duration and seed give the same files byte
//! for byte.

use crate::output::finish;
use anyhow::Context;
use serde_json::json;
use slamkit_core::StageTimings;
use slamkit_io::output_folder::OutputFolder;
use slamkit_ros2::{run_drone_sim_node, run_sim_node, DroneSimNodeConfig, SimNodeConfig};
use slamkit_sim::recording::{counts_by_sensor, write_recording, Sensor, KITTI_FOLDER, TUM_FOLDER};
use slamkit_sim::{GroundRobot, RobotKind, RobotPath, SimConfig, Simulation, World};
use slamkit_slam::ground_robot::closed_loop::NavLoopConfig;
use slamkit_slam::profile::settings;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `slamkit sim`.
#[derive(Debug, clap::Args)]
pub struct SimArgs {
    /// World: `small`, `large`, `office`, or a TOML world file.
    #[arg(long)]
    pub world: String,
    /// Sensors to simulate, comma separated: lidar2d (or lidar), range, imu, flow, rgbd, stereo.
    #[arg(long, value_delimiter = ',', default_value = "lidar2d")]
    pub sensors: Vec<String>,
    /// The robot: the drone flies the world's flight path, the ground robot drives its drive
    /// path.
    #[arg(long, value_enum, default_value = "drone")]
    pub robot: Robot,
    /// The path: `default` (the world's flight or drive path) or `loopN`, N laps of the
    /// world's closed drive (`office` has one; with `--robot diff-drive`), for loop closing.
    #[arg(long, default_value = "default")]
    pub path: String,
    /// Simulate only the first SECONDS of the run.
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,
    /// Named profile of the robot (or a profile file `X.toml`): its `[sim]` settings.
    #[arg(long)]
    pub profile: Option<String>,
    /// TOML file with simulation settings laid over the profile's (the fields report.json
    /// shows under `config`, such as `[rgbd] rate_hz = 15` or `[diff_drive] speed_mps = 0.25`);
    /// `--robot` wins over its `robot`.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Publish live on ROS 2 instead of writing files: the ground robot of `slamkit nav`
    /// (`--robot diff-drive --sensors rgbd`) publishes its camera at 10 Hz as a RealSense
    /// driver does and drives by /cmd_vel; the drone (`--robot drone --sensors
    /// lidar2d,range,imu`) flies its flight path in real time publishing /scan, /range_up,
    /// /range_down and /imu (for `slamkit ros2 drone`); until Ctrl-C or `--duration` (or the
    /// flight's end); `groundtruth.tum` and `report.json` go to `--out`.
    #[arg(long)]
    pub ros2: bool,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

/// The simulated robots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Robot {
    /// A drone flying the world's flight path.
    Drone,
    /// A differential-drive ground robot driving the world's drive path.
    DiffDrive,
}

/// The files and folders `slamkit sim` writes in `--out` (by sensor).
#[rustfmt::skip]
const OUTPUTS: &[&str] = &[
    "world.toml", "report.json", "groundtruth.tum", "lidar.clf", "lidar.relations", "ranges.csv",
    "imu.csv", "flow.csv", TUM_FOLDER, KITTI_FOLDER,
];

/// Runs `slamkit sim`.
pub fn run(args: &SimArgs) -> anyhow::Result<()> {
    if args.ros2 {
        return live(args);
    }
    let started = Instant::now();
    let sensors = Sensor::parse_list(&args.sensors)?;
    let world = World::by_name_or_file(&args.world)?;
    let world_toml = toml::to_string(&world).context("serialising the world")?;
    let config = SimConfig {
        robot: match args.robot {
            Robot::Drone => RobotKind::Drone,
            Robot::DiffDrive => RobotKind::DiffDrive,
        },
        ..settings(
            SimConfig::default(),
            "sim",
            args.profile.as_deref(),
            args.config.as_deref(),
        )?
    };
    let path: RobotPath = args.path.parse()?;
    let sim = Simulation::on_path(world, config.clone(), path, args.seed)?;
    let duration_s = match args.duration {
        Some(d) if d.is_finite() && d >= 0.0 => d.min(sim.duration_s()),
        Some(d) => anyhow::bail!("--duration {d}: must be a number of seconds, 0 or more"),
        None => sim.duration_s(),
    };
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let out = folder.path();
    std::fs::write(out.join("world.toml"), world_toml)
        .with_context(|| format!("writing world.toml in {}", args.out.display()))?;
    let mut timings = StageTimings::default();
    let written = write_recording(&sim, &sensors, duration_s, out, &mut timings)?;
    let report = json!({
        "input": {
            "world": args.world,
            "sensors": args.sensors,
            "robot": format!("{:?}", args.robot),
            "path": args.path,
            "seed": args.seed,
        },
        "config": config,
        "duration_s": duration_s,
        "frames": counts_by_sensor(&written),
        "wall_seconds": started.elapsed().as_secs_f64(),
        "timings_ms": timings.summary(),
    });
    finish(folder, &report)?;
    println!(
        "simulated {:.1} s of {} in {:.1} s; outputs in {}",
        duration_s,
        sim.world.name,
        started.elapsed().as_secs_f64(),
        args.out.display()
    );
    Ok(())
}

/// `slamkit sim --ros2`: the ground robot of `slamkit nav` live on ROS 2
/// ([`slamkit_ros2::sim_node`]).
fn live(args: &SimArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    if let Some(d) = args.duration.filter(|d| !(d.is_finite() && *d > 0.0)) {
        anyhow::bail!("--duration {d}: must be a positive number of seconds");
    }
    let sensors = Sensor::parse_list(&args.sensors)?;
    let drone = [Sensor::Lidar2d, Sensor::Range, Sensor::Imu];
    let same = |a: &[Sensor], b: &[Sensor]| a.len() == b.len() && a.iter().all(|s| b.contains(s));
    if args.robot == Robot::Drone && same(&sensors, &drone) {
        return live_drone(args, started);
    }
    if sensors != [Sensor::Rgbd] || args.robot != Robot::DiffDrive {
        anyhow::bail!(
            "--ros2 publishes the ground robot's RGB-D camera (--robot diff-drive --sensors \
             rgbd) or the drone's lidar, range finders and IMU (--robot drone --sensors \
             lidar2d,range,imu)"
        );
    }
    let world = World::by_name_or_file(&args.world)?;
    let sim = settings(
        NavLoopConfig::default().sim,
        "sim",
        args.profile.as_deref(),
        args.config.as_deref(),
    )?;
    let mut robot = GroundRobot::new(world, &sim, args.seed)?;
    let config = SimNodeConfig {
        discovery: crate::commands::ros2::discovery()?,
        duration_s: args.duration,
        ..SimNodeConfig::default()
    };
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let stop = crate::output::stop_flag()?;
    println!(
        "slamkit sim --ros2: {} at {} Hz on {}, {}, {}, {} ({} -> {}); driven by {}; Ctrl-C stops",
        robot.simulation().world.name,
        sim.rgbd.rate_hz,
        config.rgb_topic,
        config.depth_topic,
        config.camera_info_topic,
        config.tf_static_topic,
        config.base_frame,
        config.optical_frame,
        config.cmd_vel_topic
    );
    let stats = run_sim_node(&config, &mut robot, &stop)?;
    let node = json!(stats);
    finish_live(
        args,
        folder,
        "DiffDrive",
        json!(sim),
        node,
        &stats.truth,
        started,
    )?;
    println!(
        "{} frames published, {} commands, {} periods driven; outputs in {}",
        stats.frames_published,
        stats.commands_received,
        stats.steps_driven,
        args.out.display()
    );
    Ok(())
}

/// `slamkit sim --ros2 --robot drone`: the drone's flight live on ROS 2
/// ([`slamkit_ros2::drone_sim_node`]).
fn live_drone(args: &SimArgs, started: Instant) -> anyhow::Result<()> {
    let world = World::by_name_or_file(&args.world)?;
    let config = SimConfig {
        robot: RobotKind::Drone,
        ..settings(
            SimConfig::default(),
            "sim",
            args.profile.as_deref(),
            args.config.as_deref(),
        )?
    };
    let path: RobotPath = args.path.parse()?;
    let sim = Simulation::on_path(world, config.clone(), path, args.seed)?;
    let node = DroneSimNodeConfig {
        discovery: crate::commands::ros2::discovery()?,
        duration_s: args.duration,
        ..DroneSimNodeConfig::default()
    };
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let stop = crate::output::stop_flag()?;
    println!(
        "slamkit sim --ros2: the drone of {} for {:.1} s on {}, {}, {}, {} ({} -> {}); Ctrl-C \
         stops",
        sim.world.name,
        args.duration.unwrap_or(f64::INFINITY).min(sim.duration_s()),
        node.scan_topic,
        node.range_up_topic,
        node.range_down_topic,
        node.imu_topic,
        node.base_frame,
        node.laser_frame
    );
    let stats = run_drone_sim_node(&node, &sim, &stop)?;
    let node = json!(stats);
    finish_live(
        args,
        folder,
        "Drone",
        json!(config),
        node,
        &stats.truth,
        started,
    )?;
    println!(
        "{} scans, {} range and {} IMU messages published ({} late); outputs in {}",
        stats.scans_published,
        stats.ranges_published,
        stats.imu_published,
        stats.late,
        args.out.display()
    );
    Ok(())
}

/// Writes a live run's `groundtruth.tum` and `report.json` (the simulated `robot`, its
/// settings `config`, the node's counters `node`) and commits the folder.
fn finish_live(
    args: &SimArgs,
    folder: OutputFolder,
    robot: &str,
    config: serde_json::Value,
    node: serde_json::Value,
    truth: &slamkit_core::Trajectory,
    started: Instant,
) -> anyhow::Result<()> {
    slamkit_io::write_tum(&folder.path().join("groundtruth.tum"), truth)?;
    let report = json!({
        "input": { "world": args.world, "seed": args.seed, "robot": robot, "ros2": true },
        "config": config,
        "node": node,
        "wall_seconds": started.elapsed().as_secs_f64(),
    });
    finish(folder, &report)
}
