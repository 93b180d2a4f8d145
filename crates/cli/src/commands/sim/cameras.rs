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
) -> anyhow::Result<()> {
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
