//! `slamkit lidar LOG --ranges ranges.csv [--imu imu.csv] [--flow flow.csv]`: the drone's
//! layered SLAM ([`slamkit_slam::DroneSlam`]) on a recorded flight, the CARMEN log's scans
//! merged in time order with the range finders, attitude and optical flow of the CSV files
//! ([`slamkit_io::drone_csv`] documents their columns). `--method rbpf` also runs the particle
//! filter on the layered increments (`--particles`, seeded by `--seed`; a `[particle_filter]`
//! table in `--config` replaces both). Writes `trajectory.tum`,
//! `maps/layer_NNN.{pgm,yaml,png}`, `map.{pgm,yaml,png}`, `cloud.ply`, `report.json`, with
//! `--method rbpf` `trajectory_pf.tum` and `map_pf.*`, and with `--save-map` the `.skmap`.

use crate::commands::drone_files::{run_session, write_grids, write_ply};
use crate::commands::lidar::{
    load_config, print_summary, read_log, relations_metrics, LidarArgs, Method, OUTPUTS,
};
use crate::output::{ensure_fits_memory, finish, peak_rss_bytes, timings_json, write_grid};
use serde_json::json;
use slamkit_core::observation::time_ordered;
use slamkit_core::Observation;
use slamkit_io::drone_csv::read_observations;
use slamkit_io::output_folder::OutputFolder;
use slamkit_io::write_tum;
use slamkit_lidar::rbpf::RbpfConfig;
use slamkit_map::OccupancyGridConfig;
use slamkit_slam::drone::particle_filter::drone_pf_config;
use slamkit_slam::lidar::preflight::particle_maps_min_bytes;
use slamkit_slam::{DroneSlamConfig, Session};
use std::path::Path;
use std::time::Instant;

/// Runs the drone session on the log and the CSV files of `args` (`ranges` is `--ranges`).
pub fn run(args: &LidarArgs, ranges: &Path) -> anyhow::Result<()> {
    let started = Instant::now();
    let mut config: DroneSlamConfig = load_config(args, "drone")?;
    if args.method == Method::Rbpf && config.particle_filter.is_none() {
        config.particle_filter = Some(RbpfConfig {
            particles: args.particles,
            ..drone_pf_config(args.seed.unwrap_or(RbpfConfig::default().seed))
        });
    }
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let out = folder.path();
    let log = read_log(&args.log)?;
    if let Some(pf) = &config.particle_filter {
        ensure_fits_memory(particle_maps_min_bytes(pf, &log.scans), pf.particles)?;
    }
    let readings = read_observations(ranges, args.imu.as_deref(), args.flow.as_deref())?;
    let mut observations = readings.observations;
    observations.extend(log.scans.iter().cloned().map(Observation::Scan));
    let session = run_session(time_ordered(observations), config.clone())?;

    let trajectory = session.trajectory();
    write_tum(&out.join("trajectory.tum"), &trajectory)?;
    let grid_config = OccupancyGridConfig::default();
    let grids = session.layer_grids(&log.scans, &session.map_from_world(), &grid_config)?;
    let layer_files = write_grids(out, &grids)?;
    write_ply(&out.join("cloud.ply"), &session.merged_cloud())?;
    let pf = match (session.particle_filter(), session.pf_trajectory()) {
        (Some(pf), Some(poses)) => {
            write_tum(&out.join("trajectory_pf.tum"), &poses)?;
            if let Some(grid) = pf.map() {
                write_grid(grid, &out.join("map_pf"))?;
            }
            json!({ "stats": pf.stats(), "timings_ms": timings_json(pf.timings()) })
        }
        _ => json!(null),
    };
    if let Some(path) = &args.save_map {
        session.save(path)?;
    }
    let stats = session.stats();
    let counts = session.frame_counts();
    let report = json!({
        "input": { "log": args.log, "ranges": ranges, "imu": args.imu, "flow": args.flow },
        "method": "layered",
        "config": config,
        "frames": {
            "read": log.scans.len(),
            "processed": counts.processed,
            "skipped": counts.skipped,
            "failed": counts.failed,
            "unreadable_lines": log.skipped.len(),
        },
        "readings": readings.counts,
        "stats": stats,
        "layers": layer_files
            .iter()
            .map(|l| json!({ "layer": l.layer, "z_range_m": l.z_range_m, "scans": l.scans }))
            .collect::<Vec<_>>(),
        "pf": pf,
        "wall_seconds": started.elapsed().as_secs_f64(),
        "timings_ms": timings_json(session.timings()),
        "peak_rss_bytes": peak_rss_bytes(),
        "metrics": relations_metrics(args, &trajectory)?,
    });
    finish(folder, &report)?;
    println!("{} height layers", layer_files.len());
    print_summary(&args.out, &report);
    Ok(())
}
