//! `slamkit sim`: simulated sensors in a world, written in real dataset formats.
//!
//! Files written in `--out`, by sensor:
//! * always: `groundtruth.tum` (true `world_from_base` at every lidar time), `world.toml` (the
//!   world simulated) and `report.json`;
//! * `lidar2d`: `lidar.clf` (CARMEN log, ROBOTLASER1 lines with the drifting odometry) and
//!   `lidar.relations` (Freiburg benchmark relations: scans 1 s apart and random far pairs, in
//!   the plane: z, roll and pitch 0);
//! * `range`: `ranges.csv` (`timestamp,up_m,down_m`, empty when nothing is in range);
//! * `imu`: `imu.csv` (`timestamp,roll_rad,pitch_rad,gyro_yaw_rad`: attitude and the heading
//!   integrated from the yaw-rate gyro, at the lidar's times);
//! * `flow`: `flow.csv` (`timestamp,integration_s,forward_mps,left_mps`: the downward
//!   optical-flow sensor's mean body-frame velocity over each period, empty when it saw no
//!   surface); the three CSV files are those `slamkit lidar LOG --ranges --imu --flow` reads
//!   ([`slamkit_io::drone_csv`] documents them) and give the drone's layered SLAM the same input
//!   as `slamkit demo` on the same world and seed;
//! * `rgbd`: a TUM RGB-D folder `tum_rgbd_fr1/` (30 Hz, 640×480, Freiburg 1 intrinsics, depth
//!   at 5000 units per metre, `groundtruth.txt` of the camera), see [`cameras`];
//! * `stereo`: a KITTI odometry folder `kitti_stereo/` (10 Hz rectified grey pair, 0.12 m
//!   baseline, `poses.txt` of the left camera).
//!
//! `--duration` cuts the run short (camera folders hold 30 frames a second of run, about
//! 1.5 MB a frame). The same world, sensors, robot, duration and seed give the same files byte
//! for byte.

pub mod cameras;

use crate::output::{peak_rss_bytes, prepare_out_dir, timings_json, write_report};
use crate::settings::settings;
use anyhow::Context;
use serde_json::json;
use slamkit_core::observation::{FlowSample, ImuSample, RangePair};
use slamkit_core::pose::{pose2_to_pose3, pose3_to_pose2};
use slamkit_core::{StageTimings, Trajectory};
use slamkit_io::carmen_writer::{write_carmen, write_relations};
use slamkit_io::drone_csv::{self, write_flow, write_imu};
use slamkit_io::relations::Relation;
use slamkit_io::write_tum;
use slamkit_sim::{relation_pairs, RobotKind, SimConfig, Simulation, Stream, World};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `slamkit sim`.
#[derive(Debug, clap::Args)]
pub struct SimArgs {
    /// World: `small`, `large`, `office`, or a TOML world file.
    #[arg(long)]
    pub world: String,
    /// Sensors to simulate, comma separated: lidar2d (or lidar), range, imu, flow, rgbd, stereo.
    #[arg(long, value_delimiter = ',', default_value = "lidar2d")]
    pub sensors: Vec<String>,
    /// The robot: the drone flies the world's flight path, the ground robot drives its drive
    /// path.
    #[arg(long, value_enum, default_value = "drone")]
    pub robot: Robot,
    /// Simulate only the first this many seconds of the run \[s\].
    #[arg(long)]
    pub duration: Option<f64>,
    /// Named profile of the robot (or a profile file `X.toml`): its `[sim]` settings.
    #[arg(long)]
    pub profile: Option<String>,
    /// TOML file with simulation settings laid over the profile's (fields of SimConfig, such
    /// as `[rgbd] rate_hz = 15` or `[diff_drive] speed_mps = 0.25`); `--robot` wins over its
    /// `robot`.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

/// The simulated robots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Robot {
    /// A drone flying the world's flight path.
    Drone,
    /// A differential-drive ground robot driving the world's drive path.
    DiffDrive,
}

/// The sensors `slamkit sim` can write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sensor {
    Lidar2d,
    Range,
    Imu,
    Flow,
    Rgbd,
    Stereo,
}

const SENSOR_NAMES: &str = "lidar2d, range, imu, flow, rgbd, stereo";

fn parse_sensors(names: &[String]) -> anyhow::Result<Vec<Sensor>> {
    let mut sensors = Vec::new();
    for name in names {
        let sensor = match name.trim() {
            "lidar2d" | "lidar" => Sensor::Lidar2d,
            "range" => Sensor::Range,
            "imu" => Sensor::Imu,
            "flow" => Sensor::Flow,
            "rgbd" => Sensor::Rgbd,
            "stereo" => Sensor::Stereo,
            other => anyhow::bail!("unknown sensor {other:?} (available: {SENSOR_NAMES})"),
        };
        if !sensors.contains(&sensor) {
            sensors.push(sensor);
        }
    }
    Ok(sensors)
}

/// Runs `slamkit sim`.
pub fn run(args: &SimArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let sensors = parse_sensors(&args.sensors)?;
    let world = World::by_name_or_file(&args.world)?;
    let world_toml = toml::to_string(&world).context("serialising the world")?;
    let config = SimConfig {
        robot: match args.robot {
            Robot::Drone => RobotKind::Drone,
            Robot::DiffDrive => RobotKind::DiffDrive,
        },
        ..settings(
            SimConfig::default(),
            "sim",
            args.profile.as_deref(),
            args.config.as_deref(),
        )?
    };
    let sim = Simulation::new(world, config.clone(), args.seed)?;
    let duration_s = match args.duration {
        Some(d) if d.is_finite() && d >= 0.0 => d.min(sim.duration_s()),
        Some(d) => anyhow::bail!("--duration {d}: must be a number of seconds, 0 or more"),
        None => sim.duration_s(),
    };
    let times = |rate_hz: f64| slamkit_sim::sample_times(duration_s, rate_hz);
    let out = prepare_out_dir(&args.out)?;
    write_file(&out.join("world.toml"), &world_toml)?;
    let lidar_times = times(config.lidar.rate_hz);
    let ground_truth = sim.ground_truth(&lidar_times);
    write_tum(&out.join("groundtruth.tum"), &ground_truth)?;
    let mut frames = serde_json::Map::new();
    if sensors.contains(&Sensor::Lidar2d) {
        let (scans, relations) = write_lidar(&sim, &out, &ground_truth)?;
        frames.insert(
            "lidar2d".into(),
            json!({ "scans": scans, "relations": relations }),
        );
    }
    if sensors.contains(&Sensor::Range) {
        let readings = write_ranges(&sim, &times(config.range_finder.rate_hz), &out)?;
        frames.insert("range".into(), json!({ "readings": readings }));
    }
    if sensors.contains(&Sensor::Imu) {
        let samples: Vec<ImuSample> = sim
            .attitude_readings(&lidar_times)
            .iter()
            .map(ImuSample::from)
            .collect();
        write_imu(&out.join("imu.csv"), &samples)?;
        frames.insert("imu".into(), json!({ "readings": samples.len() }));
    }
    if sensors.contains(&Sensor::Flow) {
        let samples: Vec<FlowSample> = sim
            .flow_readings(&times(config.flow.rate_hz))
            .iter()
            .map(FlowSample::from)
            .collect();
        write_flow(&out.join("flow.csv"), &samples)?;
        frames.insert("flow".into(), json!({ "readings": samples.len() }));
    }
    let mut timings = StageTimings::default();
    if sensors.contains(&Sensor::Rgbd) {
        let camera_times = times(config.rgbd.rate_hz);
        let dir = out.join(cameras::TUM_FOLDER);
        cameras::write_tum_sequence(&sim, &camera_times, &dir, &mut timings)?;
        frames.insert("rgbd".into(), json!({ "frames": camera_times.len() }));
    }
    if sensors.contains(&Sensor::Stereo) {
        let camera_times = times(config.stereo.rate_hz);
        let dir = out.join(cameras::KITTI_FOLDER);
        cameras::write_kitti_sequence(&sim, &camera_times, &dir, &mut timings)?;
        frames.insert("stereo".into(), json!({ "frames": camera_times.len() }));
    }
    let report = json!({
        "input": {
            "world": args.world,
            "sensors": args.sensors,
            "robot": format!("{:?}", args.robot),
            "seed": args.seed,
        },
        "config": config,
        "duration_s": duration_s,
        "frames": frames,
        "wall_seconds": started.elapsed().as_secs_f64(),
        "timings_ms": timings_json(&timings),
        "peak_rss_bytes": peak_rss_bytes(),
    });
    write_report(&out, &report)?;
    println!(
        "simulated {:.1} s of {} in {:.1} s; outputs in {}",
        duration_s,
        sim.world.name,
        started.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(())
}

/// Writes `lidar.clf` and `lidar.relations`; returns the numbers of scans and relations.
fn write_lidar(
    sim: &Simulation,
    out: &Path,
    ground_truth: &Trajectory,
) -> anyhow::Result<(usize, usize)> {
    let times: Vec<f64> = ground_truth.poses.iter().map(|p| p.timestamp).collect();
    let scans = sim.lidar_scans(&times);
    write_carmen(&out.join("lidar.clf"), &scans)?;
    let far_pairs = (times.len() / 50).max(10);
    let pairs = relation_pairs(&times, 1.0, far_pairs, &mut sim.rng(Stream::Relations, 0));
    let planar = |k: usize| pose2_to_pose3(&pose3_to_pose2(&ground_truth.poses[k].pose));
    let relations: Vec<Relation> = pairs
        .iter()
        .map(|&(i, j)| Relation {
            t1: times[i],
            t2: times[j],
            t1_from_t2: planar(i).inverse() * planar(j),
        })
        .collect();
    write_relations(&out.join("lidar.relations"), &relations)?;
    Ok((scans.len(), relations.len()))
}

/// Writes `ranges.csv` with the readings at `times`; returns their number.
fn write_ranges(sim: &Simulation, times: &[f64], out: &Path) -> anyhow::Result<usize> {
    let readings: Vec<RangePair> = sim
        .range_readings(times)
        .iter()
        .map(RangePair::from)
        .collect();
    drone_csv::write_ranges(&out.join("ranges.csv"), &readings)?;
    Ok(readings.len())
}

fn write_file(path: &Path, text: &str) -> anyhow::Result<()> {
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}
