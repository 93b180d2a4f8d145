//! The RGB-D visual odometry part of `slamkit demo`: the drone's flight seen by its simulated
//! RGB-D camera, written as a TUM RGB-D folder (`rgbd/`), read back and run through
//! the [`VisualSlam`] session like any recorded sequence, and scored by ATE after SE(3) alignment
//! (Sturm et al., IROS 2012), the `slamkit vo` metric.
//!
//! To keep the demo under a minute the camera is smaller and slower than the default
//! 640×480 at 30 Hz: [`DEMO_CAMERA_SCALE`] of its size (the Freiburg 1 intrinsics scaled with
//! it) at [`DEMO_CAMERA_RATE_HZ`], over the first [`DEMO_VO_SECONDS`] of the flight.

use crate::commands::sim::cameras::write_tum_sequence;
use anyhow::Context;
use slamkit_core::camera::{Distortion, Intrinsics, PinholeCamera};
use slamkit_core::StageTimings;
use slamkit_eval::plot::{plot_errors, ErrorSeries, TopView};
use slamkit_eval::{ate, Alignment, AteResult, Pairing};
use slamkit_io::tum_rgbd::{open, TumCamera, TumRgbdConfig};
use slamkit_io::Dataset;
use slamkit_sim::{sample_times, RgbdCameraConfig, SimConfig, Simulation, World};
use slamkit_slam::visual::{self, PointMapping, RunOptions, VisualSlam, VisualStats};
use slamkit_vo::VoConfig;
use std::path::{Path, PathBuf};

/// Image size of the demo's camera relative to the default 640×480.
pub const DEMO_CAMERA_SCALE: f64 = 0.5;
/// Frame rate of the demo's camera \[Hz\].
pub const DEMO_CAMERA_RATE_HZ: f64 = 10.0;
/// Length of the flight seen by the camera \[s\].
pub const DEMO_VO_SECONDS: f64 = 40.0;

/// What the VO part of the demo produced.
#[derive(Debug)]
pub struct VoDemo {
    /// Title shown in the table and the page.
    pub title: &'static str,
    /// ATE after SE(3) alignment: statistics, per-pose errors, aligned positions.
    pub ate: AteResult,
    /// Frame counts of the VO run.
    pub stats: VisualStats,
    /// Render, write and VO timings \[ms\].
    pub timings: StageTimings,
    /// The camera used.
    pub camera: RgbdCameraConfig,
    /// Top view and error plot.
    pub plot: PathBuf,
}

/// The demo's camera: the default one scaled by [`DEMO_CAMERA_SCALE`] (pixel centres kept at
/// integer coordinates) at [`DEMO_CAMERA_RATE_HZ`].
pub fn demo_camera() -> RgbdCameraConfig {
    let full = RgbdCameraConfig::default();
    let k = full.intrinsics;
    let s = DEMO_CAMERA_SCALE;
    let centre = |c: f64| (c + 0.5) * s - 0.5;
    RgbdCameraConfig {
        intrinsics: Intrinsics::from_array(
            [k.fx * s, k.fy * s, centre(k.cx), centre(k.cy)],
            (k.width as f64 * s).round() as usize,
            (k.height as f64 * s).round() as usize,
        ),
        rate_hz: DEMO_CAMERA_RATE_HZ,
        ..full
    }
}

/// Simulates the camera on the first [`DEMO_VO_SECONDS`] of the flight of `world` with `seed`,
/// writes `out/rgbd/` (TUM
/// RGB-D), runs RGB-D VO on it and writes `trajectory_vo.tum` and `errors_vo.png`.
pub fn run_vo_demo(
    world: &World,
    seed: u64,
    out: &Path,
    progress: impl Fn(),
) -> anyhow::Result<VoDemo> {
    let camera = demo_camera();
    let config = SimConfig {
        rgbd: camera.clone(),
        ..SimConfig::default()
    };
    let sim = Simulation::new(world.clone(), config, seed).context("setting up the camera")?;
    let times = sample_times(DEMO_VO_SECONDS.min(sim.duration_s()), camera.rate_hz);
    let dir = out.join("rgbd");
    let mut timings = StageTimings::default();
    write_tum_sequence(&sim, &times, &dir, &mut timings)?;
    let reader = TumRgbdConfig {
        camera: TumCamera::Given(PinholeCamera::new(camera.intrinsics, Distortion::default())),
        ..TumRgbdConfig::default()
    };
    let sequence = open(&dir, &reader).with_context(|| format!("reading {}", dir.display()))?;
    let truth = sequence
        .ground_truth
        .clone()
        .context("the simulated sequence has no ground truth")?;
    let dataset = Dataset::Rgbd(sequence);
    let mut session = VisualSlam::new(&VoConfig::default(), visual::rig_of(&dataset))?
        .with_point_map(PointMapping::Off)?;
    let run = visual::run(
        &mut session,
        dataset.observations(),
        RunOptions::default(),
        |_| progress(),
    )?;
    let session = session.finish()?;
    timings.merge(&run.timings);
    timings.merge(&session.timings);
    let ate = ate(&truth, &run.trajectory, Pairing::default(), Alignment::Se3)
        .context("scoring visual odometry")?;
    slamkit_io::write_tum(&out.join("trajectory_vo.tum"), &run.trajectory)?;
    let plot = out.join("errors_vo.png");
    plot_errors(
        &plot,
        &TopView {
            reference: &ate.reference_positions,
            estimate: &ate.aligned_estimate_positions,
        },
        &ErrorSeries {
            title: "RGB-D visual odometry: position error (SE(3)-aligned)",
            label: "position error [m]",
            timestamps: &ate.timestamps,
            errors: &ate.errors_m,
        },
    )?;
    Ok(VoDemo {
        title: "RGB-D visual odometry",
        ate,
        stats: session.stats,
        timings,
        camera,
        plot,
    })
}

/// `metrics.vo` of report.json: ATE after SE(3) alignment \[m\].
pub fn metrics_json(vo: &VoDemo) -> serde_json::Value {
    let s = &vo.ate.stats;
    serde_json::json!({
        "ate_rmse_m": s.rmse,
        "ate_mean_m": s.mean,
        "ate_max_m": s.max,
        "pairs": s.pairs,
    })
}

/// `vo` of report.json: the camera, frame counts and timings.
pub fn report_json(vo: &VoDemo) -> serde_json::Value {
    serde_json::json!({
        "camera": vo.camera,
        "frames": vo.stats,
        "timings_ms": crate::output::timings_json(&vo.timings),
    })
}
