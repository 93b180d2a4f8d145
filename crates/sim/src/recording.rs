//! A simulated run written as a recording, in the formats of real datasets, so that every
//! reader, session and benchmark script runs on simulated data unchanged (`slamkit sim`,
//! and the camera part of `slamkit demo`).
//!
//! Files written in the output folder, by [`Sensor`]:
//! * `groundtruth.tum`: the true `world_from_base` at every lidar time (always);
//! * [`Sensor::Lidar2d`]: `lidar.clf` (CARMEN log, ROBOTLASER1 lines with the drifting
//!   odometry) and `lidar.relations` (Freiburg benchmark relations: scans 1 s apart and random
//!   far pairs, in the plane: z, roll and pitch 0);
//! * [`Sensor::Range`]: `ranges.csv`; [`Sensor::Imu`]: `imu.csv` (attitude and gyro heading at
//!   the lidar's times); [`Sensor::Flow`]: `flow.csv` (the columns are
//!   [`slamkit_io::drone_csv`]'s);
//! * [`Sensor::Rgbd`]: a TUM RGB-D folder [`TUM_FOLDER`] (depth at the camera's units per
//!   metre, `groundtruth.txt` of the camera), see [`write_tum_sequence`];
//! * [`Sensor::Stereo`]: a KITTI odometry folder [`KITTI_FOLDER`] (rectified grey pair,
//!   `poses.txt` of the left camera), see [`write_kitti_sequence`].
//!
//! Camera frames are rendered one at a time (the renderer spreads a frame's rows over the
//! cores) and written at once, so a long sequence never sits in memory; render and write wall
//! times are recorded per frame. The same simulation, sensors and duration give the same files
//! byte for byte.

use crate::{relation_pairs, sample_times, SimError, Simulation, Stream};
use slamkit_core::observation::{FlowSample, ImuSample, RangePair};
use slamkit_core::pose::{pose2_to_pose3, pose3_to_pose2};
use slamkit_core::{StageTimings, Trajectory};
use slamkit_io::carmen_writer::{write_carmen, write_relations};
use slamkit_io::drone_csv::{write_flow, write_imu, write_ranges};
use slamkit_io::kitti::KittiCalib;
use slamkit_io::kitti_writer::KittiWriter;
use slamkit_io::relations::Relation;
use slamkit_io::tum_rgbd_writer::TumRgbdWriter;
use slamkit_io::{write_tum, IoError};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

/// Folder name of the TUM output: the TUM reader takes the Freiburg 1 calibration for folder
/// names holding `fr1`, the intrinsics the simulated camera has by default.
pub const TUM_FOLDER: &str = "tum_rgbd_fr1";
/// Folder name of the KITTI output.
pub const KITTI_FOLDER: &str = "kitti_stereo";

/// The sensors a recording can hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sensor {
    /// The planar lidar with the drifting odometry.
    Lidar2d,
    /// The up and down range finders.
    Range,
    /// Attitude and yaw-rate gyro.
    Imu,
    /// The downward optical-flow sensor.
    Flow,
    /// The RGB-D camera.
    Rgbd,
    /// The stereo pair.
    Stereo,
}

impl Sensor {
    /// The sensor's name in `report.json` and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Sensor::Lidar2d => "lidar2d",
            Sensor::Range => "range",
            Sensor::Imu => "imu",
            Sensor::Flow => "flow",
            Sensor::Rgbd => "rgbd",
            Sensor::Stereo => "stereo",
        }
    }

    /// The sensors named in `names` (`lidar` is `lidar2d`), each once, in the order first named.
    ///
    /// ```
    /// use slamkit_sim::recording::Sensor;
    /// let names = ["lidar", "imu", "lidar2d"].map(String::from);
    /// assert_eq!(Sensor::parse_list(&names)?, [Sensor::Lidar2d, Sensor::Imu]);
    /// assert!(Sensor::parse_list(&["sonar".into()]).is_err());
    /// # Ok::<(), slamkit_sim::SimError>(())
    /// ```
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] naming an unknown sensor and the known ones.
    pub fn parse_list(names: &[String]) -> Result<Vec<Sensor>, SimError> {
        const ALL: [Sensor; 6] = [
            Sensor::Lidar2d,
            Sensor::Range,
            Sensor::Imu,
            Sensor::Flow,
            Sensor::Rgbd,
            Sensor::Stereo,
        ];
        let mut sensors = Vec::new();
        for name in names.iter().map(|n| n.trim()) {
            let name = if name == "lidar" { "lidar2d" } else { name };
            let Some(&sensor) = ALL.iter().find(|s| s.name() == name) else {
                let known: Vec<&str> = ALL.iter().map(|s| s.name()).collect();
                return Err(SimError::InvalidConfig(format!(
                    "unknown sensor {name:?} (available: {})",
                    known.join(", ")
                )));
            };
            if !sensors.contains(&sensor) {
                sensors.push(sensor);
            }
        }
        Ok(sensors)
    }
}

/// What was written for one sensor: named counts (`scans`, `relations`, `readings`,
/// `frames`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Written {
    /// The sensor.
    pub sensor: Sensor,
    /// Counts by name.
    pub counts: Vec<(&'static str, usize)>,
}

/// The counts of every sensor written, by sensor name and count name (`report.json`'s
/// `frames` of `slamkit sim`).
pub fn counts_by_sensor(
    written: &[Written],
) -> BTreeMap<&'static str, BTreeMap<&'static str, usize>> {
    written
        .iter()
        .map(|w| (w.sensor.name(), w.counts.iter().copied().collect()))
        .collect()
}

/// Writes `groundtruth.tum` and each of `sensors` (in order) for the first `duration_s` of
/// `sim` into `out` (which must exist), recording camera render and write times in
/// `timings`.
///
/// ```
/// use slamkit_sim::recording::{write_recording, Sensor};
/// use slamkit_sim::{SimConfig, Simulation, World};
///
/// let sim = Simulation::new(World::builtin("small")?, SimConfig::default(), 1)?;
/// let out = std::env::temp_dir().join(format!("slamkit_recording_doc_{}", std::process::id()));
/// std::fs::create_dir_all(&out)?;
/// let mut timings = slamkit_core::StageTimings::default();
/// let written = write_recording(&sim, &[Sensor::Range], 2.0, &out, &mut timings)?;
/// let rows = std::fs::read_to_string(out.join("ranges.csv"))?.lines().count();
/// assert_eq!(written[0].counts, vec![("readings", rows - 1)]); // a header line, then one per reading
/// std::fs::remove_dir_all(&out)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn write_recording(
    sim: &Simulation,
    sensors: &[Sensor],
    duration_s: f64,
    out: &Path,
    timings: &mut StageTimings,
) -> Result<Vec<Written>, IoError> {
    let config = &sim.config;
    let times = |rate_hz: f64| sample_times(duration_s, rate_hz);
    let lidar_times = times(config.lidar.rate_hz);
    let ground_truth = sim.ground_truth(&lidar_times);
    write_tum(&out.join("groundtruth.tum"), &ground_truth)?;
    let mut written = Vec::new();
    for &sensor in sensors {
        let counts = match sensor {
            Sensor::Lidar2d => {
                let (scans, relations) = write_lidar(sim, out, &ground_truth)?;
                vec![("scans", scans), ("relations", relations)]
            }
            Sensor::Range => {
                let readings: Vec<RangePair> = sim
                    .range_readings(&times(config.range_finder.rate_hz))
                    .iter()
                    .map(RangePair::from)
                    .collect();
                write_ranges(&out.join("ranges.csv"), &readings)?;
                vec![("readings", readings.len())]
            }
            Sensor::Imu => {
                let samples: Vec<ImuSample> = sim
                    .attitude_readings(&lidar_times)
                    .iter()
                    .map(ImuSample::from)
                    .collect();
                write_imu(&out.join("imu.csv"), &samples)?;
                vec![("readings", samples.len())]
            }
            Sensor::Flow => {
                let samples: Vec<FlowSample> = sim
                    .flow_readings(&times(config.flow.rate_hz))
                    .iter()
                    .map(FlowSample::from)
                    .collect();
                write_flow(&out.join("flow.csv"), &samples)?;
                vec![("readings", samples.len())]
            }
            Sensor::Rgbd => {
                let camera_times = times(config.rgbd.rate_hz);
                write_tum_sequence(sim, &camera_times, &out.join(TUM_FOLDER), timings)?;
                vec![("frames", camera_times.len())]
            }
            Sensor::Stereo => {
                let camera_times = times(config.stereo.rate_hz);
                write_kitti_sequence(sim, &camera_times, &out.join(KITTI_FOLDER), timings)?;
                vec![("frames", camera_times.len())]
            }
        };
        written.push(Written { sensor, counts });
    }
    Ok(written)
}

/// Writes `lidar.clf` and `lidar.relations`; returns the numbers of scans and relations.
fn write_lidar(
    sim: &Simulation,
    out: &Path,
    ground_truth: &Trajectory,
) -> Result<(usize, usize), IoError> {
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

/// Renders the RGB-D camera at `times` (frame `i` at `times[i]`) and writes a TUM RGB-D
/// folder at `dir`, ground truth being the true `world_from_camera`. Per-frame timings go to
/// `timings` as `render_rgbd` and `write_rgbd` \[ms\].
pub fn write_tum_sequence(
    sim: &Simulation,
    times: &[f64],
    dir: &Path,
    timings: &mut StageTimings,
) -> Result<(), IoError> {
    let config = &sim.config.rgbd;
    let mut writer = TumRgbdWriter::create(dir, config.depth_units_per_metre)?;
    let stages = ("render_rgbd", "write_rgbd");
    for_each_frame(
        times,
        timings,
        stages,
        |i, t| sim.rgbd_frame(i, t),
        |frame| writer.write_frame(frame.timestamp, &frame.color, &frame.depth_m),
    )?;
    let truth = sim.sensor_ground_truth(times, &config.mount.base_from_camera());
    writer.finish(&truth)?;
    Ok(())
}

/// Renders the stereo pair at `times` and writes a KITTI odometry folder at `dir`, ground
/// truth being the true `world_from_left` (relative to the first frame, as KITTI stores it).
/// Per-frame timings go to `timings` as `render_stereo` and `write_stereo` \[ms\].
pub fn write_kitti_sequence(
    sim: &Simulation,
    times: &[f64],
    dir: &Path,
    timings: &mut StageTimings,
) -> Result<(), IoError> {
    let config = &sim.config.stereo;
    let calib = KittiCalib::rectified(&config.intrinsics, config.baseline_m);
    let mut writer = KittiWriter::create(dir, &calib)?;
    let stages = ("render_stereo", "write_stereo");
    for_each_frame(
        times,
        timings,
        stages,
        |i, t| sim.stereo_frame(i, t),
        |frame| writer.write_frame(frame.timestamp, &frame.left, &frame.right),
    )?;
    let truth = sim.sensor_ground_truth(times, &config.mount.base_from_camera());
    writer.finish(&truth)?;
    Ok(())
}

/// Renders frame `i` at `times[i]` and hands it to `write`, one frame at a time, recording each
/// call's wall time under the `(render, write)` stage names \[ms\].
fn for_each_frame<F, E>(
    times: &[f64],
    timings: &mut StageTimings,
    (render_stage, write_stage): (&str, &str),
    render: impl Fn(usize, f64) -> F,
    mut write: impl FnMut(F) -> Result<(), E>,
) -> Result<(), E> {
    for (i, &t) in times.iter().enumerate() {
        let start = Instant::now();
        let frame = render(i, t);
        timings.record_since(render_stage, start);
        let start = Instant::now();
        write(frame)?;
        timings.record_since(write_stage, start);
    }
    Ok(())
}
