//! The camera outputs of `slamkit sim` (also used by `slamkit demo`): the simulated RGB-D camera
//! written as a TUM RGB-D folder and the stereo pair as a KITTI odometry folder.
//!
//! Frames are rendered one at a time (the renderer spreads a frame's rows over the cores) and
//! written at once, so a long sequence never sits in memory; render and write wall times are
//! recorded per frame.

use slamkit_core::StageTimings;
use slamkit_io::kitti::KittiCalib;
use slamkit_io::kitti_writer::KittiWriter;
use slamkit_io::tum_rgbd_writer::TumRgbdWriter;
use slamkit_sim::Simulation;
use std::path::Path;
use std::time::Instant;

/// Folder name of the TUM output: the TUM reader takes the Freiburg 1 calibration for folder
/// names holding `fr1`, the intrinsics the simulated camera has by default.
pub const TUM_FOLDER: &str = "tum_rgbd_fr1";
/// Folder name of the KITTI output.
pub const KITTI_FOLDER: &str = "kitti_stereo";

/// Renders the RGB-D camera at `times` (frame `i` at `times[i]`) and writes a TUM RGB-D
/// folder at `dir`, ground truth being the true `world_from_camera`. Per-frame timings go to
/// `timings` as `render_rgbd` and `write_rgbd` \[ms\].
pub fn write_tum_sequence(
    sim: &Simulation,
    times: &[f64],
    dir: &Path,
    timings: &mut StageTimings,
) -> anyhow::Result<()> {
    let config = &sim.config.rgbd;
    let mut writer = TumRgbdWriter::create(dir, config.depth_units_per_metre)?;
    for (i, &t) in times.iter().enumerate() {
        let start = Instant::now();
        let frame = sim.rgbd_frame(i, t);
        timings.record_since("render_rgbd", start);
        let start = Instant::now();
        writer.write_frame(frame.timestamp, &frame.color, &frame.depth_m)?;
        timings.record_since("write_rgbd", start);
    }
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
) -> anyhow::Result<()> {
    let config = &sim.config.stereo;
    let calib = KittiCalib::rectified(&config.intrinsics, config.baseline_m);
    let mut writer = KittiWriter::create(dir, &calib)?;
    for (i, &t) in times.iter().enumerate() {
        let start = Instant::now();
        let frame = sim.stereo_frame(i, t);
        timings.record_since("render_stereo", start);
        let start = Instant::now();
        writer.write_frame(frame.timestamp, &frame.left, &frame.right)?;
        timings.record_since("write_stereo", start);
    }
    let truth = sim.sensor_ground_truth(times, &config.mount.base_from_camera());
    writer.finish(&truth)?;
    Ok(())
}
