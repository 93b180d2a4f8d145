//! `slamkit lidar`: 2D lidar SLAM on a CARMEN log, with the map, trajectory and report written
//! to the output folder, and the relations metric when the benchmark's `.relations` file is
//! known.

use crate::commands::eval::load_relations;
use crate::commands::{lidar_drone, lidar_pf};
use crate::config_file::config_over;
use crate::output::{peak_rss_bytes, prepare_out_dir, progress_bar, timings_json, write_report};
use anyhow::Context;
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::json;
use slamkit_core::{LaserScan, Trajectory};
use slamkit_io::carmen::{CarmenLog, SkipReason};
use slamkit_lidar::icp_slam::{run_icp_slam, IcpSlamConfig, IcpSlamOutput, IcpSlamStats};
use slamkit_map::{save_map_yaml, save_png, OccupancyGrid, OccupancyGridConfig};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// SLAM methods.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// Incremental scan-to-map ICP (as MRPT's icp-slam).
    Icp,
    /// Rao-Blackwellised particle filter (GMapping-style).
    Rbpf,
}

/// Arguments of `slamkit lidar`.
#[derive(Debug, clap::Args)]
pub struct LidarArgs {
    /// CARMEN log (plain or gzip).
    pub log: PathBuf,
    /// SLAM method.
    #[arg(long, value_enum, default_value = "icp")]
    pub method: Method,
    /// Particles of the particle filter.
    #[arg(long, default_value_t = 30)]
    pub particles: usize,
    /// Localise in this saved map (ROS map_server YAML) instead of building one.
    #[arg(long)]
    pub localize: Option<PathBuf>,
    /// TOML file with configuration overrides (fields of the method's config).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A drone's up/down range finders (`timestamp,up_m,down_m`): run the drone's layered
    /// SLAM on the log (see `slamkit_io::drone_csv` for the files' columns).
    #[arg(long)]
    pub ranges: Option<PathBuf>,
    /// The drone's attitude and gyro heading (`timestamp,roll_rad,pitch_rad,gyro_yaw_rad`);
    /// with `--ranges`.
    #[arg(long, requires = "ranges")]
    pub imu: Option<PathBuf>,
    /// The drone's optical flow (`timestamp,integration_s,forward_mps,left_mps`); with
    /// `--ranges`.
    #[arg(long, requires = "ranges")]
    pub flow: Option<PathBuf>,
    /// Seed of the particle filter (drone, `--method rbpf`).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Save the map here (`.skmap`; drone runs).
    #[arg(long, requires = "ranges")]
    pub save_map: Option<PathBuf>,
    /// Benchmark relations to score against; by default `<log stem>.relations` beside the log.
    #[arg(long)]
    pub relations: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "out/lidar")]
    pub out: PathBuf,
}

/// Runs `slamkit lidar`.
pub fn run(args: &LidarArgs) -> anyhow::Result<()> {
    if let Some(ranges) = &args.ranges {
        anyhow::ensure!(
            args.localize.is_none(),
            "--localize is not available for drone runs (--ranges)"
        );
        return lidar_drone::run(args, ranges);
    }
    if let Some(map) = &args.localize {
        return lidar_pf::run_localization(args, map);
    }
    if args.method == Method::Rbpf {
        return lidar_pf::run_rbpf_slam(args);
    }
    let started = Instant::now();
    let config: IcpSlamConfig = load_config(args.config.as_deref())?;
    let out = prepare_out_dir(&args.out)?;
    let log = slamkit_io::carmen::read_carmen(&args.log)
        .with_context(|| format!("reading log {}", args.log.display()))?;
    if log.scans.is_empty() {
        anyhow::bail!("{} holds no laser scan", args.log.display());
    }
    let bar = progress_bar(log.scans.len() as u64, "icp-slam");
    let result = run_icp_slam(&log.scans, &config, |_| bar.inc(1))?;
    bar.finish_and_clear();

    slamkit_io::trajectory_file::write_tum(&out.join("trajectory.tum"), &result.trajectory)?;
    let grid = build_grid(&log.scans, &result)?;
    save_map_yaml(&grid, &out.join("map.yaml"))?;
    save_png(&grid, &out.join("map.png"))?;

    let metrics = relations_metrics(args, &result.trajectory)?;
    let report = json!({
        "input": args.log,
        "method": "icp",
        "config": config,
        "frames": {
            "read": log.scans.len(),
            "processed": result.stats.scans_processed,
            "skipped": result.stats.scans_skipped,
            "failed": result.stats.matches_failed,
            "unreadable_lines": log.skipped.len(),
        },
        "scans": scan_counts(&log, &result.stats),
        "stats": result.stats,
        "wall_seconds": started.elapsed().as_secs_f64(),
        "timings_ms": timings_json(&result.timings),
        "peak_rss_bytes": peak_rss_bytes(),
        "metrics": metrics,
    });
    write_report(&out, &report)?;
    print_summary(&out, &report);
    Ok(())
}

/// Scans read and processed, and the broken ones skipped: scans the mapper could not use, by
/// reason, and log lines the reader could not parse (truncated, NaN, garbage), by reason.
fn scan_counts(log: &CarmenLog, stats: &IcpSlamStats) -> serde_json::Value {
    let mut unreadable: BTreeMap<&str, usize> = BTreeMap::new();
    for line in &log.skipped {
        *unreadable.entry(skip_reason_key(&line.reason)).or_default() += 1;
    }
    json!({
        "read": log.scans.len(),
        "processed": stats.scans_processed,
        "skipped_broken": stats.skipped_broken.total(),
        "skipped_broken_reasons": stats.skipped_broken,
        "unreadable_lines": log.skipped.len(),
        "unreadable_line_reasons": unreadable,
    })
}

/// A short name for why the reader skipped a line.
fn skip_reason_key(reason: &SkipReason) -> &'static str {
    match reason {
        SkipReason::NotUtf8 => "not_utf8",
        SkipReason::Garbage { .. } => "garbage",
        SkipReason::FieldCount { .. } => "wrong_field_count",
        SkipReason::BadField { .. } => "bad_field",
        SkipReason::BadBeams(_) => "bad_beams",
        SkipReason::ReadError(_) => "read_error",
        SkipReason::OutOfRange(_) => "out_of_range",
        _ => "other",
    }
}

/// The method's configuration: its defaults with the TOML file at `path` laid over them.
pub(crate) fn load_config<C: Serialize + DeserializeOwned + Default>(
    path: Option<&Path>,
) -> anyhow::Result<C> {
    config_over(C::default(), path)
}

/// The explicit `--relations`, else `<stem>.relations` beside the log (`intel.fromrosbag.clf.gz`
/// → `intel.relations`), when it exists.
fn relations_path(args: &LidarArgs) -> Option<PathBuf> {
    if let Some(path) = &args.relations {
        return Some(path.clone());
    }
    let name = args.log.file_name()?.to_str()?;
    let stem = name.split('.').next()?;
    let candidate = args.log.with_file_name(format!("{stem}.relations"));
    candidate.exists().then_some(candidate)
}

/// The relations metric of `trajectory` (JSON), or null when no relations file is known.
pub(crate) fn relations_metrics(
    args: &LidarArgs,
    trajectory: &Trajectory,
) -> anyhow::Result<serde_json::Value> {
    let Some(path) = relations_path(args) else {
        return Ok(json!(null));
    };
    let relations = load_relations(&path)?;
    let stats = slamkit_eval::relations_error(&relations, trajectory)
        .with_context(|| format!("scoring against {}", path.display()))?;
    Ok(json!({ "relations_file": path, "relations": stats }))
}

/// Inserts every scan at its estimated pose into a fresh occupancy grid.
fn build_grid(scans: &[LaserScan], result: &IcpSlamOutput) -> anyhow::Result<OccupancyGrid> {
    let mut grid = OccupancyGrid::new(OccupancyGridConfig::default())?;
    for (scan, est) in scans.iter().zip(&result.estimates) {
        let world_from_laser = est.world_from_base * scan.base_from_laser;
        grid.insert_scan(scan, &world_from_laser)
            .context("inserting a scan into the occupancy grid")?;
    }
    Ok(grid)
}

/// Prints the frame counts, wall time and relations metric of `report`.
pub(crate) fn print_summary(out: &Path, report: &serde_json::Value) {
    let f = &report["frames"];
    println!(
        "scans: {} read, {} processed, {} skipped, {} failed matches; {:.1} s",
        f["read"], f["processed"], f["skipped"], f["failed"], report["wall_seconds"]
    );
    let r = &report["metrics"]["relations"];
    if !r.is_null() {
        println!(
            "relations metric: {:.4} ± {:.4} m, {:.3} ± {:.3} deg over {} relations",
            r["trans_mean"].as_f64().unwrap_or(f64::NAN),
            r["trans_std"].as_f64().unwrap_or(f64::NAN),
            r["rot_mean_deg"].as_f64().unwrap_or(f64::NAN),
            r["rot_std_deg"].as_f64().unwrap_or(f64::NAN),
            r["count"]
        );
    }
    println!("outputs in {}", out.display());
}
