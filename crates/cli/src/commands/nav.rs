//! `slamkit nav`: the closed navigation loop in the simulator.
//!
//! The simulated differential-drive robot drives from the start of the world's drive path to
//! the goal ([`closed_loop`]): localised by lidar ICP-SLAM (the simulator has no RGB-D camera),
//! re-planning every 1.5 s on the map it builds, following the path with the carrot tracker.
//! Writes in `--out`: `trajectory.tum` (estimated poses), `groundtruth.tum` (true poses),
//! `map.png` (the robot's map, inflated obstacles shaded, every plan in red, the true driven
//! path in blue, the true-map shortest path in green) and `report.json` (`localisation`,
//! `metrics.reached`, `metrics.time_s`, `metrics.path_length_m`, `metrics.optimal_length_m`,
//! `metrics.max_cross_track_m`, ...).

pub mod closed_loop;

use crate::commands::plan::{parse_xy, save_rgb_png};
use crate::output::{peak_rss_bytes, prepare_out_dir, timings_json, write_report};
use anyhow::Context;
use closed_loop::{planning_grid, run_nav_loop, NavLoopConfig, NavOutcome};
use nalgebra::Point2;
use serde_json::json;
use slamkit_core::image::RgbImage;
use slamkit_io::write_tum;
use slamkit_nav::render::{draw_path, pixel_of};
use slamkit_sim::World;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `slamkit nav`.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Localisation: lidar ICP-SLAM on the simulated 2D lidar (the simulator has no \
                  RGB-D camera). The robot starts at the first point of the world's drive path, \
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
    /// Loop settings (TOML, the fields of `report.json`'s `config`; missing ones default).
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
    let config = load_config(args.config.as_deref())?;
    let outcome = run_nav_loop(world, goal, args.seed, &config)?;
    let out = prepare_out_dir(&args.out)?;
    write_tum(&out.join("trajectory.tum"), &outcome.estimate)?;
    write_tum(&out.join("groundtruth.tum"), &outcome.ground_truth)?;
    write_map_png(&out.join("map.png"), &outcome, &goal, &config)?;
    let o = &outcome;
    let report = json!({
        "input": { "world": world_name, "seed": args.seed, "goal_m": [goal.x, goal.y] },
        "localisation": "lidar ICP-SLAM",
        "config": config,
        "frames": {
            "read": o.slam_stats.scans_read,
            "processed": o.slam_stats.scans_processed,
            "skipped": o.slam_stats.scans_skipped,
            "failed": o.slam_stats.matches_failed,
        },
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
            "loop_closures": o.slam_stats.loop_closures,
        },
        "timings_ms": timings_json(&o.timings),
        "wall_seconds": started.elapsed().as_secs_f64(),
        "peak_rss_bytes": peak_rss_bytes(),
    });
    write_report(&out, &report)?;
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
        out.display()
    );
    Ok(())
}

/// The loop settings from a TOML file (missing fields default), or the defaults.
fn load_config(path: Option<&Path>) -> anyhow::Result<NavLoopConfig> {
    let Some(path) = path else {
        return Ok(NavLoopConfig::default());
    };
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))
}

/// Draws the robot's final map with every plan (red), the true-map shortest path (green) and
/// the true driven path (blue), three pixels per cell.
fn write_map_png(
    path: &Path,
    outcome: &NavOutcome,
    goal: &Point2<f64>,
    config: &NavLoopConfig,
) -> anyhow::Result<()> {
    let start = outcome
        .ground_truth
        .poses
        .first()
        .map(|p| Point2::new(p.pose.translation.x, p.pose.translation.y))
        .context("the run has no pose")?;
    let margin = config.inflate_cells() as i32 + 2;
    let grid = planning_grid(&outcome.grid, &[start, *goal], margin)
        .context("the map cannot hold the start and goal")?;
    let mut image = draw_path(&grid, &grid.inflated(config.inflate_cells()), &[]);
    let mut mark = |points: &mut dyn Iterator<Item = Point2<f64>>, colour: [u8; 3]| {
        for p in points {
            if let Some((col, row)) = pixel_of(&grid, &p) {
                if let Some(px) = image.get_mut(col, row) {
                    *px = colour;
                }
            }
        }
    };
    for plan in &outcome.plans {
        mark(&mut plan.waypoints_m.iter().copied(), [230, 120, 120]);
    }
    mark(
        &mut outcome.optimal.waypoints_m.iter().copied(),
        [30, 160, 30],
    );
    let driven = outcome
        .ground_truth
        .poses
        .iter()
        .map(|p| Point2::new(p.pose.translation.x, p.pose.translation.y));
    mark(&mut driven.collect::<Vec<_>>().into_iter(), [30, 60, 220]);
    save_rgb_png(&upscale(&image, 3), path)
}

/// Each pixel becomes a `k` × `k` block.
fn upscale(image: &RgbImage, k: usize) -> RgbImage {
    let mut out = RgbImage::filled(image.width() * k, image.height() * k, [0, 0, 0]);
    for y in 0..out.height() {
        for x in 0..out.width() {
            if let (Some(src), Some(dst)) = (image.get(x / k, y / k).copied(), out.get_mut(x, y)) {
                *dst = src;
            }
        }
    }
    out
}
