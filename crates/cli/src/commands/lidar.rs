//! `slamkit lidar`: 2D lidar SLAM on a CARMEN log through a [`LidarSlam`] session (a new map,
//! localisation in a saved map, or its continuation), with the map, trajectory and report
//! written to the output folder, and the relations metric when the benchmark's `.relations`
//! file is known.

use crate::commands::bag::TopicArgs;
use crate::commands::eval::load_relations;
use crate::commands::{lidar_drone, lidar_mcl};
use crate::output::{finish_with_page, merge_json, progress_bar, Unsuccessful};
use anyhow::Context;
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::json;
use slamkit_core::{Pose2, Trajectory};
use slamkit_io::carmen::CarmenLog;
use slamkit_io::lidar_log::read_lidar_log;
use slamkit_io::output_folder::OutputFolder;
use slamkit_slam::lidar::preflight::{ensure_fits_memory, ensure_usable, particle_maps_min_bytes};
use slamkit_slam::lidar::{run_report, LidarMap};
use slamkit_slam::map_file::is_skmap;
use slamkit_slam::profile::settings;
use slamkit_slam::record::LidarRecording;
use slamkit_slam::{LidarMethod, LidarSlam, LidarSlamConfig};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The files and folders `slamkit lidar` writes in `--out` (by any method).
#[rustfmt::skip]
pub(crate) const OUTPUTS: &[&str] = &[
    "trajectory.tum", "trajectory_map.tum", "trajectory_pf.tum", "map.pgm", "map.yaml",
    "map.png", "map.skmap", "map_pf.pgm", "map_pf.yaml", "map_pf.png", "maps", "cloud.ply",
    "report.json", "report.html",
];

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
    /// CARMEN log (plain or gzip), or ROS 1 bag (told by its first bytes).
    pub log: PathBuf,
    /// The bag's topics, when the input is a bag.
    #[command(flatten)]
    pub topics: TopicArgs,
    /// SLAM method of a new map.
    #[arg(long, value_enum, default_value = "icp")]
    pub method: Method,
    /// Particles of the particle filter (default: the profile's or `--config` file's
    /// `particles`, else 30).
    #[arg(long)]
    pub particles: Option<usize>,
    /// Seed of every random choice of the run: the particle filter's draws and resampling,
    /// Monte Carlo localisation's (`--localize MAP.yaml`), the drone's particle filter
    /// (default: the configured seed, 1; ICP-SLAM and the global search draw nothing).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Localise in this saved map instead of building one: a `.skmap` (the start pose is found
    /// by global search, the map is not changed) or a ROS map_server YAML (Monte Carlo
    /// localisation).
    #[arg(long, conflicts_with = "continue_map")]
    pub localize: Option<PathBuf>,
    /// Continue this saved map (`.skmap`): the robot is found in it, then ICP-SLAM extends it.
    #[arg(long = "continue")]
    pub continue_map: Option<PathBuf>,
    /// Also write the map to this `.skmap` file (the output folder always gets map.skmap).
    #[arg(long)]
    pub save_map: Option<PathBuf>,
    /// Named profile of the robot (or a profile file `X.toml`): its `[lidar]` settings (the
    /// session's), `[drone]` with `--ranges`, `[mcl]` with `--localize MAP.yaml`.
    #[arg(long)]
    pub profile: Option<String>,
    /// TOML file with settings laid over the profile's: fields of the method's config for a new map
    /// (ICP-SLAM's or the particle filter's), of the session's with `--continue` and `--localize
    /// MAP.skmap` (`[icp]`, `[global_search]`, `[localise]`, ...), of MCL's with `--localize
    /// MAP.yaml`.
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
    /// Benchmark relations to score against; by default `<log stem>.relations` beside the log.
    #[arg(long)]
    pub relations: Option<PathBuf>,
    /// Record the run to this MCAP file (Foxglove's JSON schemas, for Foxglove): each
    /// scan, its pose and `map → base_link`, and the map and path ten times over the run.
    /// Not with `--ranges` or `--localize MAP.yaml` yet.
    #[arg(long, value_name = "FILE.mcap", conflicts_with = "ranges")]
    pub record: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "out/lidar")]
    pub out: PathBuf,
}

/// Runs `slamkit lidar`.
pub fn run(args: &LidarArgs) -> anyhow::Result<()> {
    check_relations(args)?;
    if let Some(ranges) = &args.ranges {
        return lidar_drone::run(args, ranges);
    }
    if let Some(map) = args.localize.as_deref().filter(|p| !is_skmap(p)) {
        return lidar_mcl::run_localization(args, map);
    }
    let started = Instant::now();
    let config = session_config(args)?;
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let out = folder.path();
    let log = read_log(&args.log, &args.topics)?;
    ensure_usable(&log.scans, &config.icp).context(args.log.display().to_string())?;
    let new_map = args.localize.is_none() && args.continue_map.is_none();
    let particle_maps_min_bytes = (new_map && config.method == LidarMethod::Rbpf)
        .then(|| particle_maps_min_bytes(&config.rbpf, &log.scans))
        .flatten();
    ensure_fits_memory(particle_maps_min_bytes, config.rbpf.particles)?;
    let load = |path: &Path| -> anyhow::Result<LidarMap> {
        let started = Instant::now();
        let (map, _) = LidarMap::load(path)?;
        println!(
            "map {}: {} keyframes, loaded in {:.2} s",
            path.display(),
            map.keyframes.len(),
            started.elapsed().as_secs_f64()
        );
        Ok(map)
    };
    let session_started = Instant::now();
    let (mut session, what) = match (&args.localize, &args.continue_map) {
        (Some(path), _) => (LidarSlam::localise(config, load(path)?)?, "localise"),
        (None, Some(path)) => (LidarSlam::resume(config, load(path)?)?, "continue"),
        (None, None) => {
            let name = match args.method {
                Method::Icp => "icp-slam",
                Method::Rbpf => "rbpf-slam",
            };
            (LidarSlam::new(config, Pose2::identity())?, name)
        }
    };
    let bar = progress_bar(log.scans.len() as u64, what);
    let mut recording = match &args.record {
        Some(path) => Some(LidarRecording::create(path, log.scans.len())?),
        None => None,
    };
    for (i, scan) in log.scans.iter().enumerate() {
        let update = session.push_scan(scan.clone());
        if let Some(recording) = recording.as_mut() {
            recording.push(&session, &log.scans[..=i], &update)?;
        }
        bar.inc(1);
    }
    let recorded = recording
        .map(|r| r.finish(&session, &log.scans))
        .transpose()?;
    let session_seconds = session_started.elapsed().as_secs_f64();
    bar.finish_and_clear();

    let save_map: Vec<&Path> = args.save_map.iter().map(PathBuf::as_path).collect();
    session.write_run_files(out, &log.scans, &save_map)?;
    let trajectory = session.trajectory();

    let mut report = json!({
        "input": args.log,
        "method": match (&args.localize, &args.continue_map) {
            (Some(_), _) => "localise",
            (None, Some(_)) => "continue",
            _ => match args.method { Method::Icp => "icp", Method::Rbpf => "rbpf" },
        },
        "map": args.localize.as_ref().or(args.continue_map.as_ref()),
        "wall_seconds": started.elapsed().as_secs_f64(),
        "session_seconds": session_seconds,
        "particle_maps_min_bytes": particle_maps_min_bytes,
        "recording": recorded.map(|messages| json!({ "file": args.record, "messages": messages })),
        "metrics": relations_metrics(args, &trajectory),
    });
    merge_json(&mut report, session.run_report(&log));
    finish_with_page(folder, &report, &page_title(args))?;
    print_summary(&args.out, &report);
    let jumps = session.stats().odometry_rejected;
    if jumps > 0 {
        eprintln!(
            "warning: {jumps} odometry readings jumped farther than the robot can move \
             (odometry_gate in the settings); taken as no motion"
        );
    }
    if let Some(scan) = session.stats().first_fix_scan {
        println!("found in the map at scan {scan}");
    } else if args.localize.is_some() || args.continue_map.is_some() {
        return Err(Unsuccessful("the robot was never found in the map".into()).into());
    }
    Ok(())
}

/// The session's settings ([`LidarSlamConfig::from_files`]), with `--particles` and `--seed`
/// for the particle filter when given (a file's `particles` stands otherwise).
fn session_config(args: &LidarArgs) -> anyhow::Result<LidarSlamConfig> {
    let method = match args.method {
        Method::Icp => LidarMethod::Icp,
        Method::Rbpf => LidarMethod::Rbpf,
    };
    let in_saved_map = args.localize.is_some() || args.continue_map.is_some();
    let mut config = LidarSlamConfig::from_files(
        method,
        in_saved_map,
        args.profile.as_deref(),
        args.config.as_deref(),
    )?;
    if let (false, LidarMethod::Rbpf, Some(particles)) = (in_saved_map, method, args.particles) {
        config.rbpf.particles = particles;
    }
    if let Some(seed) = args.seed {
        config.rbpf.seed = seed;
    }
    Ok(config)
}

/// The lidar log at `path` (a CARMEN file or a bag's `topics`: `slamkit_io::lidar_log`), what
/// was read from a bag and any damage told on the terminal.
pub(crate) fn read_log(path: &Path, topics: &TopicArgs) -> anyhow::Result<CarmenLog> {
    let file = read_lidar_log(path, &topics.scan_topics())?;
    if let Some(description) = &file.description {
        println!("bag {}: {description}", path.display());
    }
    for warning in &file.warnings {
        eprintln!("warning: {}: {warning}", path.display());
    }
    Ok(file.log)
}

/// A method's settings: its defaults, the profile's `[section]`, the `--config` file.
pub(crate) fn load_config<C: Serialize + DeserializeOwned + Default>(
    args: &LidarArgs,
    section: &str,
) -> anyhow::Result<C> {
    Ok(settings(
        C::default(),
        section,
        args.profile.as_deref(),
        args.config.as_deref(),
    )?)
}

/// The relations metric of `trajectory` for report.json
/// ([`slamkit_slam::lidar::run_report::relations_metrics`]); when scoring fails, the error in
/// `error` ([`finish_with_page`] writes the report, then fails with it).
pub(crate) fn relations_metrics(args: &LidarArgs, trajectory: &Trajectory) -> serde_json::Value {
    run_report::relations_metrics(args.relations.as_deref(), &args.log, trajectory)
}

/// The heading of the run's report.html: the command and the log's file name.
pub(crate) fn page_title(args: &LidarArgs) -> String {
    let name = args.log.file_name().unwrap_or(args.log.as_os_str());
    format!("slamkit lidar: {}", name.to_string_lossy())
}

/// An explicit `--relations` file is read before the run, so a wrong path fails at once.
fn check_relations(args: &LidarArgs) -> anyhow::Result<()> {
    if let Some(path) = &args.relations {
        load_relations(path)?;
    }
    Ok(())
}

/// Prints the frame counts, wall time and relations metric of `report`
/// ([`run_report::summary`]) and where the outputs are.
pub(crate) fn print_summary(out: &Path, report: &serde_json::Value) {
    println!("{}", run_report::summary(report));
    println!("outputs in {}", out.display());
}
