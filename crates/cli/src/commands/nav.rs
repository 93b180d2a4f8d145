//! `slamkit nav`: the closed navigation loop in the simulator.
//!
//! The simulated differential-drive robot drives from the start of the world's drive path to
//! the goal ([`slamkit_slam::ground_robot::closed_loop`]): the [`slamkit_slam::GroundRobotNav`]
//! session localises it by RGB-D visual odometry, maps the depth images into a floor grid,
//! re-plans every 1.5 s on it and follows the path with the carrot tracker.
//! Writes in `--out`: `trajectory.tum` (estimated poses), `groundtruth.tum` (true poses),
//! `frames.csv` (per camera frame: true and estimated pose, VO's status, inliers and failure),
//! `map.png` (the robot's map, inflated obstacles shaded, every plan in red, the true driven
//! path in blue, the true-map shortest path in green), `map.pgm`/`map.yaml` (the robot's floor
//! grid, ROS `map_server` format), `map.skmap` (the camera's keyframes and
//! the floor grid: `slamkit plan --map` plans on it) and `report.json` (`localisation`,
//! `metrics.reached`, `metrics.time_s`, `metrics.path_length_m`, `metrics.optimal_length_m`,
//! `metrics.max_cross_track_m`, ...). With `--record FILE.mcap`, the run as an MCAP file
//! ([`slamkit_slam::record::NavRecording`]).

use crate::commands::plan::parse_xy;
use crate::output::{finish_with_page, Unsuccessful};
use nalgebra::Point2;
use serde_json::json;
use slamkit_io::output_folder::OutputFolder;
use slamkit_sim::World;
use slamkit_slam::ground_robot::closed_loop::{run_nav_loop, NavLoopConfig};
use slamkit_slam::profile::settings;
use slamkit_slam::record::NavRecording;
use std::path::PathBuf;
use std::time::Instant;

/// The files `slamkit nav` writes in `--out`.
#[rustfmt::skip]
const OUTPUTS: &[&str] = &[
    "trajectory.tum",
    "groundtruth.tum",
    "map.png",
    "map.pgm",
    "map.yaml",
    "map.skmap",
    "frames.csv",
    "report.json",
    "report.html",
];

/// Arguments of `slamkit nav`.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Localisation: RGB-D visual odometry on the simulated camera (10 Hz), mapping \
                  its depth into a floor grid. The robot starts at the first point of the world's drive path, \
                  re-plans every 1.5 s on the map it builds and follows the path with the \
                  carrot tracker."
)]
pub struct NavArgs {
    /// World: `small`, `large`, `office`, or a TOML world file.
    #[arg(long)]
    pub world: String,
    /// Goal `X,Y` (m); the world's built-in goal when omitted.
    #[arg(long, allow_hyphen_values = true)]
    pub goal: Option<String>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Named profile of the robot (or a profile file `X.toml`): its `[nav]` settings.
    #[arg(long)]
    pub profile: Option<String>,
    /// Loop settings laid over the profile's (TOML, the fields of `report.json`'s `config`;
    /// missing ones keep their values).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "out/nav")]
    pub out: PathBuf,
    /// Also record the run as an MCAP file (Foxglove opens it): the camera's images, the
    /// estimated and true poses, every plan, and the map as it grows.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
}

/// Runs `slamkit nav`.
pub fn run(args: &NavArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let world = World::by_name_or_file(&args.world)?;
    let goal = match &args.goal {
        Some(text) => parse_xy(text, "goal")?,
        None => Point2::new(world.nav_goal[0], world.nav_goal[1]),
    };
    let world_name = world.name.clone();
    let config = settings(
        NavLoopConfig::default(),
        "nav",
        args.profile.as_deref(),
        args.config.as_deref(),
    )?;
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let out = folder.path();
    let mut recording = args
        .record
        .as_deref()
        .map(NavRecording::create)
        .transpose()?;
    let outcome = run_nav_loop(world, goal, args.seed, &config, recording.as_mut())?;
    let recorded = recording
        .map(|r| r.finish(outcome.time_s, &outcome.grid))
        .transpose()?;
    outcome.write_run_files(out, &config)?;
    let o = &outcome;
    let report = json!({
        "input": { "world": world_name, "seed": args.seed, "goal_m": [goal.x, goal.y] },
        "localisation": "RGB-D visual odometry",
        "config": config,
        "frames": o.camera_stats,
        "metrics": o.metrics_json(),
        "timings_ms": o.timings.summary(),
        "recording": recorded.map(|messages| json!({ "file": args.record, "messages": messages })),
        "wall_seconds": started.elapsed().as_secs_f64(),
    });
    let title = format!("slamkit nav: {world_name} world, seed {}", args.seed);
    finish_with_page(folder, &report, &title)?;
    println!("{}; written to {}", o.summary(), args.out.display());
    if !o.reached {
        return Err(Unsuccessful(format!(
            "the goal was not reached: {:.2} m from it after {:.1} s",
            o.final_distance_m, o.time_s
        ))
        .into());
    }
    Ok(())
}
