//! `slamkit nav`: the closed navigation loop in the simulator.
//!
//! The simulated differential-drive robot drives from the start of the world's drive path to
//! the goal ([`slamkit_slam::ground_robot::closed_loop`]): the [`slamkit_slam::GroundRobotNav`]
//! session localises it by RGB-D visual odometry, maps the depth images into a floor grid,
//! re-plans every 1.5 s on it and follows the path with the carrot tracker.
//! Writes in `--out`: `trajectory.tum` (estimated poses), `groundtruth.tum` (true poses),
//! `frames.csv` (per camera frame: true and estimated pose, VO's status, inliers and failure),
//! `map.png` (the robot's map, inflated obstacles shaded, every plan in red, the true driven
//! path in blue, the true-map shortest path in green), `map.skmap` (the camera's keyframes and
//! the floor grid: `slamkit plan --map` plans on it) and `report.json` (`localisation`,
//! `metrics.reached`, `metrics.time_s`, `metrics.path_length_m`, `metrics.optimal_length_m`,
//! `metrics.max_cross_track_m`, ...).

use crate::commands::plan::parse_xy;
use crate::output::{finish, peak_rss_bytes, timings_json, Unsuccessful};
use anyhow::Context;
use nalgebra::Point2;
use serde_json::json;
use slamkit_core::Pose2;
use slamkit_io::image_writer::save_rgb_png;
use slamkit_io::output_folder::OutputFolder;
use slamkit_io::write_tum;
use slamkit_sim::World;
use slamkit_slam::ground_robot::closed_loop::{run_nav_loop, FrameRecord, NavLoopConfig};
use slamkit_slam::profile::settings;
use slamkit_vo::FrameStatus;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The files `slamkit nav` writes in `--out`.
#[rustfmt::skip]
const OUTPUTS: &[&str] = &[
    "trajectory.tum",
    "groundtruth.tum",
    "map.png",
    "map.skmap",
    "frames.csv",
    "report.json",
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
    let outcome = run_nav_loop(world, goal, args.seed, &config)?;
    write_tum(&out.join("trajectory.tum"), &outcome.estimate)?;
    write_tum(&out.join("groundtruth.tum"), &outcome.ground_truth)?;
    save_rgb_png(&out.join("map.png"), &outcome.map_image(&config))?;
    outcome.map.save(&out.join("map.skmap"))?;
    write_frames_csv(&out.join("frames.csv"), &outcome.frames)?;
    let o = &outcome;
    let report = json!({
        "input": { "world": world_name, "seed": args.seed, "goal_m": [goal.x, goal.y] },
        "localisation": "RGB-D visual odometry",
        "config": config,
        "frames": o.camera_stats,
        "metrics": {
            "reached": o.reached,
            "time_s": o.time_s,
            "path_length_m": o.path_length_m,
            "optimal_length_m": o.optimal.length_m,
            "length_ratio": o.path_length_m / o.optimal.length_m.max(1e-9),
            "max_cross_track_m": o.max_cross_track_m,
            "final_distance_m": o.final_distance_m,
            "localisation_error_mean_m": o.localisation_error_mean_m,
            "localisation_error_max_m": o.localisation_error_max_m,
            "plans": o.plans.len(),
            "plan_failures": o.plan_failures,
            "blocked_steps": o.blocked_steps,
        },
        "timings_ms": timings_json(&o.timings),
        "wall_seconds": started.elapsed().as_secs_f64(),
        "peak_rss_bytes": peak_rss_bytes(),
    });
    finish(folder, &report)?;
    println!(
        "{} after {:.1} s: driven {:.2} m (shortest {:.2} m), max cross-track {:.3} m, {:.2} m \
         from the goal; written to {}",
        if o.reached {
            "goal reached"
        } else {
            "goal NOT reached"
        },
        o.time_s,
        o.path_length_m,
        o.optimal.length_m,
        o.max_cross_track_m,
        o.final_distance_m,
        args.out.display()
    );
    if !o.reached {
        return Err(Unsuccessful(format!(
            "the goal was not reached: {:.2} m from it after {:.1} s",
            o.final_distance_m, o.time_s
        ))
        .into());
    }
    Ok(())
}

/// One line per camera frame: time, true and estimated `x, y, yaw` (m, degrees; empty when
/// VO failed), VO's status, inliers, correspondences and failure reason.
fn write_frames_csv(path: &Path, frames: &[FrameRecord]) -> anyhow::Result<()> {
    let mut text = String::from(
        "t_s,true_x_m,true_y_m,true_yaw_deg,est_x_m,est_y_m,est_yaw_deg,status,inliers,\
         correspondences,reason\n",
    );
    let pose = |p: &Pose2| {
        let t = p.translation.vector;
        format!(
            "{:.4},{:.4},{:.3}",
            t.x,
            t.y,
            p.rotation.angle().to_degrees()
        )
    };
    for f in frames {
        let estimate = f.estimate.as_ref().map_or(",,".to_string(), pose);
        let status = match &f.status {
            FrameStatus::Initialised { features } => format!("initialised,{features},,"),
            FrameStatus::Tracked {
                inliers,
                correspondences,
            } => format!("tracked,{inliers},{correspondences},"),
            FrameStatus::Failed(reason) => {
                format!("failed,,,\"{}\"", format!("{reason:?}").replace('"', "'"))
            }
        };
        text += &format!("{:.2},{},{estimate},{status}\n", f.t_s, pose(&f.truth));
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}
