//! `slamkit lidar --method rbpf` and `slamkit lidar --localize MAP.yaml`: the particle-filter
//! paths of the lidar command. Particle-filter SLAM writes the best particle's map; localisation
//! writes the map it was given. Both write the trajectory, report.json and, when the log's
//! benchmark `.relations` file is known, the relations metric, through the same helpers as
//! `--method icp`.

use crate::commands::lidar::{load_config, print_summary, relations_metrics, LidarArgs};
use crate::output::{peak_rss_bytes, prepare_out_dir, progress_bar, timings_json, write_report};
use anyhow::Context;
use serde_json::json;
use slamkit_core::{StageTimings, Trajectory};
use slamkit_io::carmen::CarmenLog;
use slamkit_lidar::mcl::{run_mcl, MclConfig};
use slamkit_lidar::rbpf::{run_rbpf, RbpfConfig};
use slamkit_map::{load_map_yaml, save_map_yaml, save_png, OccupancyGrid};
use std::path::Path;
use std::time::Instant;

/// Runs particle-filter SLAM (`--method rbpf`).
pub fn run_rbpf_slam(args: &LidarArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let config = RbpfConfig {
        particles: args.particles,
        ..load_config::<RbpfConfig>(args.config.as_deref())?
    };
    let out = prepare_out_dir(&args.out)?;
    let log = read_log(&args.log)?;
    let bar = progress_bar(log.scans.len() as u64, "rbpf-slam");
    let result = run_rbpf(&log.scans, &config, |_| bar.inc(1))?;
    bar.finish_and_clear();

    slamkit_io::trajectory_file::write_tum(&out.join("trajectory.tum"), &result.trajectory)?;
    let map = result
        .map
        .as_ref()
        .context("no scan of the log was usable, so no map was built")?;
    write_map(map, &out)?;
    let s = &result.stats;
    let fields = json!({
        "input": args.log,
        "method": "rbpf",
        "config": config,
        "stats": s,
    });
    let run = RunSummary {
        frames: [s.updates, s.scans_skipped, s.matches_failed],
        timings: &result.timings,
        trajectory: &result.trajectory,
    };
    write_run_report(args, &out, started, &log, fields, &run)
}

/// Runs Monte Carlo localisation in the map `--localize` names.
pub fn run_localization(args: &LidarArgs, map_path: &Path) -> anyhow::Result<()> {
    let started = Instant::now();
    let config = load_config::<MclConfig>(args.config.as_deref())?;
    let map = load_map_yaml(map_path)
        .with_context(|| format!("loading the map {}", map_path.display()))?;
    let out = prepare_out_dir(&args.out)?;
    let log = read_log(&args.log)?;
    let bar = progress_bar(log.scans.len() as u64, "mcl");
    let result = run_mcl(&log.scans, &map, &config, |_| bar.inc(1))
        .with_context(|| format!("localising in {}", map_path.display()))?;
    bar.finish_and_clear();

    slamkit_io::trajectory_file::write_tum(&out.join("trajectory.tum"), &result.trajectory)?;
    write_map(&map, &out)?;
    let s = &result.stats;
    let fields = json!({
        "input": args.log,
        "map": map_path,
        "method": "mcl",
        "config": config,
        "stats": s,
        "final_estimate": result.estimates.last().copied().flatten(),
    });
    let run = RunSummary {
        frames: [s.updates, s.scans_skipped, 0],
        timings: &result.timings,
        trajectory: &result.trajectory,
    };
    write_run_report(args, &out, started, &log, fields, &run)?;
    if let Some(scan) = s.first_converged_scan {
        println!("converged at scan {scan}");
    } else {
        println!("the particles never gathered within the convergence radius");
    }
    Ok(())
}

/// What both paths report beside their own fields.
struct RunSummary<'a> {
    /// Scans processed (filter updates), skipped and failed.
    frames: [usize; 3],
    timings: &'a StageTimings,
    trajectory: &'a Trajectory,
}

/// Writes report.json (`fields` plus the frame counts, time, memory and relations metric) and
/// prints the summary.
fn write_run_report(
    args: &LidarArgs,
    out: &Path,
    started: Instant,
    log: &CarmenLog,
    mut fields: serde_json::Value,
    run: &RunSummary<'_>,
) -> anyhow::Result<()> {
    let [processed, skipped, failed] = run.frames;
    let shared = json!({
        "frames": {
            "read": log.scans.len(),
            "processed": processed,
            "skipped": skipped,
            "failed": failed,
            "unreadable_lines": log.skipped.len(),
        },
        "wall_seconds": started.elapsed().as_secs_f64(),
        "timings_ms": timings_json(run.timings),
        "peak_rss_bytes": peak_rss_bytes(),
        "metrics": relations_metrics(args, run.trajectory)?,
    });
    if let (Some(report), serde_json::Value::Object(shared)) = (fields.as_object_mut(), shared) {
        report.extend(shared);
    }
    write_report(out, &fields)?;
    print_summary(out, &fields);
    Ok(())
}

fn read_log(path: &Path) -> anyhow::Result<CarmenLog> {
    let log = slamkit_io::carmen::read_carmen(path)
        .with_context(|| format!("reading log {}", path.display()))?;
    if log.scans.is_empty() {
        anyhow::bail!("{} holds no laser scan", path.display());
    }
    Ok(log)
}

fn write_map(map: &OccupancyGrid, out: &Path) -> anyhow::Result<()> {
    save_map_yaml(map, &out.join("map.yaml"))?;
    save_png(map, &out.join("map.png"))?;
    Ok(())
}
