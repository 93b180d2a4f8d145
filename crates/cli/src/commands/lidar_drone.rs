//! `slamkit lidar LOG --ranges ranges.csv [--imu imu.csv] [--flow flow.csv]`: the drone's
//! layered SLAM ([`slamkit_slam::DroneSlam`]) on a recorded flight, the CARMEN log's scans
//! merged in time order with the range finders, attitude and optical flow of the CSV files
//! ([`slamkit_io::drone_csv`] documents their columns). `--method rbpf` also runs the particle
//! filter on the layered increments (`--particles`, seeded by `--seed`; a `[particle_filter]`
//! table in `--config` replaces the particle count, and `--seed` still sets its seed).
//! `--localize MAP.skmap` localises in a drone's saved map (not changing it), `--continue
//! MAP.skmap` extends it; the drone is found in the map by a
//! global search ([`slamkit_slam::drone::in_map`]). Writes `trajectory.tum`,
//! `maps/layer_NNN.{pgm,yaml,png}`, `map.{pgm,yaml,png}`, `cloud.ply`, `report.json`, with
//! `--method rbpf` `trajectory_pf.tum` and `map_pf.*`, and with `--save-map` the `.skmap`.

use crate::commands::drone_files::{run_session, write_grids, write_ply};
use crate::commands::lidar::{
    load_config, print_summary, read_log, relations_metrics, LidarArgs, Method, OUTPUTS,
};
use crate::output::{
    ensure_fits_memory, finish, peak_rss_bytes, timings_json, write_grid, Unsuccessful,
};
use serde_json::json;
use slamkit_core::observation::time_ordered;
use slamkit_core::Observation;
use slamkit_io::drone_csv::read_observations;
use slamkit_io::output_folder::OutputFolder;
use slamkit_io::write_tum;
use slamkit_lidar::rbpf::RbpfConfig;
use slamkit_map::OccupancyGridConfig;
use slamkit_slam::drone::map::DroneMap;
use slamkit_slam::drone::particle_filter::drone_pf_config;
use slamkit_slam::lidar::preflight::particle_maps_min_bytes;
use slamkit_slam::{DroneSlam, DroneSlamConfig, Session};
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
    if let (Some(pf), Some(seed)) = (config.particle_filter.as_mut(), args.seed) {
        pf.seed = seed;
    }
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let out = folder.path();
    let log = read_log(args)?;
    if let Some(pf) = &config.particle_filter {
        ensure_fits_memory(particle_maps_min_bytes(pf, &log.scans), pf.particles)?;
    }
    let readings = read_observations(ranges, args.imu.as_deref(), args.flow.as_deref())?;
    let mut observations = readings.observations;
    observations.extend(log.scans.iter().cloned().map(Observation::Scan));
    let (session, what) = match (&args.localize, &args.continue_map) {
        (Some(map), _) => (
            DroneSlam::localise(config.clone(), DroneMap::load(map)?)?,
            "localise",
        ),
        (None, Some(map)) => (
            DroneSlam::resume(config.clone(), DroneMap::load(map)?)?,
            "continue",
        ),
        (None, None) => (DroneSlam::new(config.clone())?, "layered"),
    };
    let session = run_session(time_ordered(observations), session);

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
        "method": what,
        "map": args.localize.as_ref().or(args.continue_map.as_ref()),
        "in_map": session.in_map_stats(),
        "config": config,
        "frames": {
            "read": log.scans.len(),
            "processed": counts.processed,
            "skipped": counts.skipped,
            "failed": counts.failed,
            "odometry_rejected": session.odometry_rejected(),
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
    let Some(stats) = session.in_map_stats() else {
        return Ok(());
    };
    match stats.found_at_scan {
        Some(scan) => {
            println!("found in the map at scan {scan}");
            Ok(())
        }
        None => Err(Unsuccessful(format!(
            "the drone was never found in the map ({} searches)",
            stats.searches
        ))
        .into()),
    }
}
