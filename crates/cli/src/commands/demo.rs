//! `slamkit demo`: the whole system on a simulated drone, with no download
//! ([`slamkit_slam::drone::demo`] says what it runs and writes).
//!
//! Writes in `--out`: `trajectory.tum`, `groundtruth.tum`, `map.pgm`/`map.yaml`/`map.png` (every
//! layer's scans in one grid), `maps/layer_NNN.{pgm,yaml,png}` (one grid per height layer),
//! `cloud.ply` (the merged layer maps), `trajectory_pf.tum` and `map_pf.{pgm,yaml,png}` (the
//! particle filter's best trajectory and map), `errors_icp.png` and `errors_pf.png` (top view
//! and error over time), `rgbd/` (the camera's TUM RGB-D folder), `trajectory_vo.tum`,
//! `errors_vo.png`, `report.json` (`metrics.{icp,pf}.position_error_mean_m`,
//! `metrics.{icp,pf}.position_error_max_m`, `metrics.vo.ate_rmse_m`,
//! `metrics.layer_localisation`) and `report.html` (the page every run gets:
//! [`slamkit_slam::report::page`]).
//! With `--record FILE.mcap`, the run as an MCAP file ([`slamkit_slam::record::record_demo`]).

use crate::output::{finish_with_page, progress_bar};
use serde_json::json;
use slamkit_io::output_folder::OutputFolder;
use slamkit_slam::drone::demo::{run_demo, DemoStep, DEMO_OUTPUTS};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `slamkit demo`.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// Built-in world: `small` (5 × 5 m, 1 m high, boxes and cylinders), `large` (10 × 10 m,
    /// 2.4 m high, more obstacles and a ramp) or `office` (12.9 × 7.7 m, 2.5 m high, furnished).
    #[arg(long, default_value = "small", value_parser = ["small", "large", "office"])]
    pub world: String,
    /// Seed of the simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output folder.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Also record the run as an MCAP file (Foxglove opens it): scans, every method's poses
    /// and the truth, the maps as they grow, the camera's images and its odometry.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
}

/// Runs `slamkit demo`.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let folder = OutputFolder::create(&args.out, DEMO_OUTPUTS)?;
    let flight_bar = progress_bar(0, "drone-slam");
    let camera_bar = progress_bar(0, "rgbd-vo");
    let progress = |step| match step {
        DemoStep::Simulated { duration_s, scans } => {
            let (world, seed) = (&args.world, args.seed);
            println!(
                "simulating a {duration_s:.0} s flight through the `{world}` world (seed {seed})"
            );
            flight_bar.set_length(scans as u64);
        }
        DemoStep::Scan => flight_bar.inc(1),
        DemoStep::CameraFrame => {
            flight_bar.finish_and_clear();
            camera_bar.inc(1);
        }
    };
    let mut outcome = run_demo(
        &args.world,
        args.seed,
        folder.path(),
        args.record.as_deref(),
        &progress,
    )?;
    camera_bar.finish_and_clear();
    outcome.report["wall_seconds"] = json!(started.elapsed().as_secs_f64());
    let title = format!("slamkit demo: {} world, seed {}", args.world, args.seed);
    finish_with_page(folder, &outcome.report, &title)?;
    println!("{}", outcome.summary());
    println!("outputs in {}", args.out.display());
    Ok(())
}
