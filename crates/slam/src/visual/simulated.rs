//! RGB-D visual odometry on a simulated flight (the camera part of `slamkit demo`): the
//! drone's flight seen by its simulated RGB-D camera is written as a TUM RGB-D folder, read
//! back and run through the [`VisualSlam`] session like any recorded sequence, and scored by
//! ATE after SE(3) alignment (Sturm et al., IROS 2012), the `slamkit vo` metric. Only the
//! scoring reads the truth.
//!
//! To keep the demo under a minute the camera is smaller and slower than the default
//! 640×480 at 30 Hz: [`DEMO_CAMERA_SCALE`] of its size (the Freiburg 1 intrinsics scaled with
//! it) at [`DEMO_CAMERA_RATE_HZ`], over the first [`DEMO_VO_SECONDS`] of the flight.

use super::{rig_of, run, PointMapping, RunOptions, VisualSlam, VisualStats};
use crate::record::{encode_jpeg, EncodedImage};
use crate::SlamError;
use slamkit_core::camera::{Distortion, Intrinsics, PinholeCamera};
use slamkit_core::{StageTimings, Trajectory};
use slamkit_eval::{ate, Alignment, AteResult, Pairing};
use slamkit_io::tum_rgbd::{open, TumCamera, TumRgbdConfig};
use slamkit_io::Dataset;
use slamkit_sim::recording::write_tum_sequence;
use slamkit_sim::{sample_times, RgbdCameraConfig, SimConfig, Simulation, World};
use slamkit_vo::VoConfig;
use std::path::Path;

/// Image size of the demo's camera relative to the default 640×480.
pub const DEMO_CAMERA_SCALE: f64 = 0.5;
/// Frame rate of the demo's camera \[Hz\].
pub const DEMO_CAMERA_RATE_HZ: f64 = 10.0;
/// Length of the flight seen by the camera \[s\].
pub const DEMO_VO_SECONDS: f64 = 40.0;

/// What the simulated VO run produced.
#[derive(Debug)]
pub struct SimulatedVo {
    /// The estimated camera trajectory, in the world's frame: anchored at the camera's true
    /// pose at its first frame, as a robot that knows where it starts would place it.
    pub trajectory: Trajectory,
    /// ATE after SE(3) alignment: statistics, per-pose errors, aligned positions.
    pub ate: AteResult,
    /// Frame counts of the VO run.
    pub stats: VisualStats,
    /// Render, write and VO timings \[ms\].
    pub timings: StageTimings,
    /// The camera used.
    pub camera: RgbdCameraConfig,
    /// Every frame's colour image as JPEG with its time, when asked for (a recording).
    pub images: Vec<EncodedImage>,
}

/// The demo's camera: the default one scaled by [`DEMO_CAMERA_SCALE`] (pixel centres kept at
/// integer coordinates) at [`DEMO_CAMERA_RATE_HZ`].
///
/// ```
/// let camera = slamkit_slam::visual::simulated::demo_camera();
/// assert_eq!((camera.intrinsics.width, camera.intrinsics.height), (320, 240));
/// assert_eq!(camera.rate_hz, 10.0);
/// ```
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

/// Simulates the [`demo_camera`] on the first [`DEMO_VO_SECONDS`] of the flight of `world`
/// with `seed`, writes it to `dir` (a TUM RGB-D folder), runs RGB-D VO on it (calling
/// `progress` after each frame) and scores it against the camera's true trajectory. With
/// `keep_images`, the frames' colour images come back as JPEG too (encoded on the reading
/// thread, off the tracker's).
pub fn run_simulated_rgbd(
    world: &World,
    seed: u64,
    dir: &Path,
    keep_images: bool,
    progress: impl Fn(),
) -> Result<SimulatedVo, SlamError> {
    let camera = demo_camera();
    let config = SimConfig {
        rgbd: camera.clone(),
        ..SimConfig::default()
    };
    let sim = Simulation::new(world.clone(), config, seed)?;
    let times = sample_times(DEMO_VO_SECONDS.min(sim.duration_s()), camera.rate_hz);
    let mut timings = StageTimings::default();
    write_tum_sequence(&sim, &times, dir, &mut timings)?;
    let reader = TumRgbdConfig {
        camera: TumCamera::Given(PinholeCamera::new(camera.intrinsics, Distortion::default())),
        ..TumRgbdConfig::default()
    };
    let sequence = open(dir, &reader)?;
    let truth = sequence
        .ground_truth
        .clone()
        .ok_or_else(|| SlamError::Scoring("the simulated sequence has no ground truth".into()))?;
    let dataset = Dataset::Rgbd(sequence);
    let mut session = VisualSlam::new(&VoConfig::default(), rig_of(&dataset))?
        .with_point_map(PointMapping::Off)?;
    let (sender, encoded) = crossbeam_channel::unbounded();
    let source = dataset.observations().inspect(move |item| {
        if let Some(jpeg) = item
            .as_ref()
            .ok()
            .filter(|_| keep_images)
            .and_then(encode_jpeg)
        {
            // The receiver lives until the run's end.
            let _ = sender.send(jpeg);
        }
    });
    let result = run(&mut session, source, RunOptions::default(), |_| progress())?;
    let session = session.finish()?;
    timings.merge(&result.timings);
    timings.merge(&session.timings);
    let ate = ate(
        &truth,
        &result.trajectory,
        Pairing::default(),
        Alignment::Se3,
    )?;
    Ok(SimulatedVo {
        trajectory: anchored(&truth, &result.trajectory),
        ate,
        stats: session.stats,
        timings,
        camera,
        images: encoded.try_iter().collect(),
    })
}

/// `estimate` moved into `truth`'s frame so that its first pose is the true one at that time
/// (SE(3) alignment for ATE is unchanged by a rigid move); as it was when the truth does not
/// cover that time.
fn anchored(truth: &Trajectory, estimate: &Trajectory) -> Trajectory {
    let Some(first) = estimate.poses.first() else {
        return estimate.clone();
    };
    let Some(true_first) = truth.interpolate(first.timestamp) else {
        return estimate.clone();
    };
    let world_from_estimate = true_first * first.pose.inverse();
    let mut moved = Trajectory::new();
    for p in &estimate.poses {
        moved.push(p.timestamp, world_from_estimate * p.pose);
    }
    moved
}
