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

use crate::commands::lidar::{
    page_title, print_summary, read_log, relations_metrics, LidarArgs, Method, OUTPUTS,
};
use crate::output::{finish_with_page, merge_json, progress_bar, Unsuccessful};
use serde_json::json;
use slamkit_core::observation::time_ordered;
use slamkit_core::Observation;
use slamkit_io::drone_csv::read_observations;
use slamkit_io::output_folder::OutputFolder;
use slamkit_io::write_tum;
use slamkit_lidar::rbpf::RbpfConfig;
use slamkit_slam::drone::map::DroneMap;
use slamkit_slam::lidar::preflight::{ensure_fits_memory, particle_maps_min_bytes};
use slamkit_slam::{DroneSlam, DroneSlamConfig, Session};
use std::path::Path;
use std::time::Instant;

/// Runs the drone session on the log and the CSV files of `args` (`ranges` is `--ranges`).
pub fn run(args: &LidarArgs, ranges: &Path) -> anyhow::Result<()> {
    let started = Instant::now();
    let config = DroneSlamConfig::from_files(
        (args.method == Method::Rbpf)
            .then(|| args.particles.unwrap_or(RbpfConfig::default().particles)),
        args.seed,
        args.profile.as_deref(),
        args.config.as_deref(),
    )?;
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let out = folder.path();
    let log = read_log(&args.log, &args.topics)?;
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
    let (_, layer_files) = session.write_maps(out, &log.scans, &session.map_from_world())?;
    if let Some(poses) = session.pf_trajectory() {
        write_tum(&out.join("trajectory_pf.tum"), &poses)?;
    }
    if let Some(path) = &args.save_map {
        session.save(path)?;
    }
    let mut report = json!({
        "input": { "log": args.log, "ranges": ranges, "imu": args.imu, "flow": args.flow },
        "method": what,
        "map": args.localize.as_ref().or(args.continue_map.as_ref()),
        "readings": readings.counts,
        "layers": layer_files,
        "wall_seconds": started.elapsed().as_secs_f64(),
        "metrics": relations_metrics(args, &trajectory),
    });
    merge_json(&mut report, session.run_report(&log));
    finish_with_page(folder, &report, &page_title(args))?;
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

/// Feeds `observations` (in time order) to `session`, with a progress bar over the scans.
fn run_session(observations: Vec<Observation>, mut session: DroneSlam) -> DroneSlam {
    let scans = observations
        .iter()
        .filter(|o| matches!(o, Observation::Scan(_)))
        .count();
    let bar = progress_bar(scans as u64, "drone-slam");
    for observation in observations {
        if session.push(observation).is_some() {
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    session
}
