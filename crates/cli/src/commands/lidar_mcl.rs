//! `slamkit lidar --localize MAP.yaml`: Monte Carlo localisation in a ROS map_server map (the
//! map of any tool). Writes the trajectory, the map it was given, report.json and, when the
//! log's benchmark `.relations` file is known, the relations metric, through the same helpers
//! as the session paths.

use crate::commands::lidar::{
    load_config, page_title, print_summary, read_log, relations_metrics, LidarArgs, OUTPUTS,
};
use crate::output::{finish_with_page, merge_json, progress_bar, Unsuccessful};
use anyhow::Context;
use serde_json::json;
use slamkit_io::output_folder::OutputFolder;
use slamkit_lidar::icp_slam::IcpSlamConfig;
use slamkit_lidar::mcl::{run_mcl, MclConfig};
use slamkit_map::load_map_yaml;
use slamkit_map::save_grid_files;
use slamkit_slam::lidar::preflight::ensure_usable;
use slamkit_slam::lidar::run_report;
use std::path::Path;
use std::time::Instant;

/// Runs Monte Carlo localisation in the map `--localize` names.
pub fn run_localization(args: &LidarArgs, map_path: &Path) -> anyhow::Result<()> {
    let started = Instant::now();
    anyhow::ensure!(
        args.record.is_none(),
        "--record is not available for Monte Carlo localisation (--localize MAP.yaml) yet"
    );
    let mut config = load_config::<MclConfig>(args, "mcl")?;
    if let Some(seed) = args.seed {
        config.seed = seed;
    }
    let map = load_map_yaml(map_path)
        .with_context(|| format!("loading the map {}", map_path.display()))?;
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let out = folder.path();
    let log = read_log(&args.log, &args.topics)?;
    ensure_usable(&log.scans, &IcpSlamConfig::default()).context(args.log.display().to_string())?;
    let bar = progress_bar(log.scans.len() as u64, "mcl");
    let result = run_mcl(&log.scans, &map, &config, |_| bar.inc(1))
        .with_context(|| format!("localising in {}", map_path.display()))?;
    bar.finish_and_clear();

    slamkit_io::trajectory_file::write_tum(&out.join("trajectory.tum"), &result.trajectory)?;
    save_grid_files(&map, &out.join("map"))?;
    let mut report = json!({
        "input": args.log,
        "map": map_path,
        "wall_seconds": started.elapsed().as_secs_f64(),
        "metrics": relations_metrics(args, &result.trajectory),
    });
    merge_json(&mut report, run_report::mcl_report(&result, &config, &log));
    finish_with_page(folder, &report, &page_title(args))?;
    print_summary(&args.out, &report);
    match result.stats.first_converged_scan {
        Some(scan) => println!("converged at scan {scan}"),
        None => {
            return Err(Unsuccessful(
                "the particles never gathered within the convergence radius".into(),
            )
            .into())
        }
    }
    Ok(())
}
