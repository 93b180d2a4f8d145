//! `slamkit demo`: the whole system on a simulated drone, with no download.
//!
//! Simulates a flight through a built-in world (seeded, so every run gives the same data), runs
//! ICP-SLAM on the lidar scans with the drone's drifting odometry as the initial guess, and
//! compares each estimated position with the simulator's ground truth. Writes
//! `trajectory.tum`, `groundtruth.tum`, `map.pgm`/`map.yaml`/`map.png` and `report.json`
//! (`metrics.icp.position_error_mean_m`, `metrics.icp.position_error_max_m`).
//!
//! This is a single-layer 2D run: the height layers of the seed's drone SLAM and the particle
//! filter join it as they land (issue #5).

use crate::output::{peak_rss_bytes, prepare_out_dir, progress_bar, timings_json, write_report};
use anyhow::Context;
use serde_json::json;
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{Pose2, Trajectory};
use slamkit_io::write_tum;
use slamkit_lidar::icp_slam::{run_icp_slam, IcpSlamConfig};
use slamkit_map::{save_map_yaml, save_png, OccupancyGrid, OccupancyGridConfig};
use slamkit_sim::{SimConfig, Simulation, World as SimWorld};
use std::path::PathBuf;
use std::time::Instant;

/// Built-in worlds.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum World {
    /// 5 × 5 m, 1 m high, boxes and cylinders.
    Small,
    /// 10 × 10 m, 2.4 m high, more obstacles and a ramp.
    Large,
    /// 12.9 × 7.7 m, 2.5 m high, furnished.
    Office,
}

impl World {
    fn name(self) -> &'static str {
        match self {
            World::Small => "small",
            World::Large => "large",
            World::Office => "office",
        }
    }
}

/// Arguments of `slamkit demo`.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// Built-in world.
    #[arg(long, value_enum, default_value = "small")]
    pub world: World,
    /// Seed of the simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output folder.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
}

/// Runs `slamkit demo`.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let out = prepare_out_dir(&args.out)?;
    let world = SimWorld::builtin(args.world.name())?;
    let sim = Simulation::new(world, SimConfig::default(), args.seed)
        .context("setting up the simulation")?;
    println!(
        "simulating a {:.0} s flight through the `{}` world (seed {})",
        sim.duration_s(),
        args.world.name(),
        args.seed
    );
    let run = sim.lidar_run();

    let config = IcpSlamConfig::default();
    let bar = progress_bar(run.scans.len() as u64, "icp-slam");
    let result = run_icp_slam(&run.scans, &config, |_| bar.inc(1))?;
    bar.finish_and_clear();

    // SLAM's world frame is its first pose; express it in the simulator's frame to compare.
    let sim_from_slam = run
        .ground_truth
        .poses
        .first()
        .map(|p| p.pose)
        .context("the simulation produced no scan")?;
    let mut estimate = Trajectory::new();
    for p in &result.trajectory.poses {
        estimate.push(p.timestamp, sim_from_slam * p.pose);
    }
    let errors = position_errors_m(&estimate, &run.ground_truth);
    let mean = errors.iter().sum::<f64>() / errors.len().max(1) as f64;
    let max = errors.iter().copied().fold(0.0, f64::max);

    write_tum(&out.join("trajectory.tum"), &estimate)?;
    write_tum(&out.join("groundtruth.tum"), &run.ground_truth)?;
    let mut grid = OccupancyGrid::new(OccupancyGridConfig::default())?;
    let sim_from_slam_2d = pose3_to_pose2(&sim_from_slam);
    for (scan, est) in run.scans.iter().zip(&result.estimates) {
        let world_from_laser: Pose2 = sim_from_slam_2d * est.world_from_base * scan.base_from_laser;
        grid.insert_scan(scan, &world_from_laser)?;
    }
    save_map_yaml(&grid, &out.join("map.yaml"))?;
    save_png(&grid, &out.join("map.png"))?;

    let report = json!({
        "input": { "world": args.world.name(), "seed": args.seed, "duration_s": sim.duration_s() },
        "config": { "sim": sim.config, "icp": config },
        "frames": {
            "read": run.scans.len(),
            "processed": result.stats.scans_processed,
            "skipped": result.stats.scans_skipped,
            "failed": result.stats.matches_failed,
        },
        "wall_seconds": started.elapsed().as_secs_f64(),
        "timings_ms": { "icp": timings_json(&result.timings) },
        "peak_rss_bytes": peak_rss_bytes(),
        "metrics": { "icp": {
            "position_error_mean_m": mean,
            "position_error_max_m": max,
            "path_length_m": run.ground_truth.path_length_m(),
        } },
    });
    write_report(&out, &report)?;
    println!(
        "method    mean error  max error   (path {:.1} m)",
        run.ground_truth.path_length_m()
    );
    println!("icp-slam  {mean:>8.3} m  {max:>7.3} m");
    println!("outputs in {}", out.display());
    Ok(())
}

/// Horizontal position error of each estimated pose against the ground truth pose at the same
/// index (both sampled at the scan times) (m).
fn position_errors_m(estimate: &Trajectory, truth: &Trajectory) -> Vec<f64> {
    estimate
        .poses
        .iter()
        .zip(&truth.poses)
        .map(|(e, t)| {
            (e.pose.translation.vector - t.pose.translation.vector)
                .xy()
                .norm()
        })
        .collect()
}
