//! Fast motion (issue 20, "Done when"): the KITTI 06 clip of `$SLAMKIT_DATA` (frames 0–50,
//! skipped when it is not set) read taking every 3rd frame, as a car at highway speed seen at
//! 10 Hz: about 3 m between frames, image motion of tens of pixels near the borders. Both front
//! ends must track every frame (no failed frame, no re-initialisation), the ATE (SE(3)
//! aligned) at most 0.20 m. The view of the dataset is built here: the same sequence with two
//! frames of three left out.

use slamkit_io::{Dataset, DatasetFormat};
use slamkit_slam::visual::{self, RunOptions, VisualSlam};
use slamkit_testdata::data;
use slamkit_vo::{evaluate, FrameStatus, FrontendKind};

const KITTI_06: &str = "stereo/kitti_odometry_06_0000-0050";

/// KITTI 06 frames 0, 3, 6, …, 48.
fn every_third_frame(test: &str) -> Option<Dataset> {
    let dir = data(test, KITTI_06)?;
    let Dataset::Stereo(mut sequence) = Dataset::open(&dir, DatasetFormat::Kitti).unwrap() else {
        panic!("KITTI is a stereo dataset");
    };
    let mut i = 0;
    sequence.frames.retain(|_| {
        i += 1;
        (i - 1) % 3 == 0
    });
    Some(Dataset::Stereo(sequence))
}

/// Runs `frontend` with the `stereo` profile (as `slamkit vo` does for KITTI) and checks the
/// issue's bar: every frame tracked, one initialisation, ATE ≤ `max_ate_m`.
fn tracks_every_frame(test: &str, frontend: FrontendKind, max_ate_m: f64) {
    let Some(dataset) = every_third_frame(test) else {
        return;
    };
    let config =
        visual::session_settings(frontend, DatasetFormat::Kitti, Some("stereo"), None, false)
            .unwrap();
    let mut session = VisualSlam::new(&config, visual::rig_of(&dataset)).unwrap();
    let result = visual::run(
        &mut session,
        dataset.observations(),
        RunOptions::default(),
        |_| {},
    )
    .unwrap();
    let stats = session.stats();
    let failed: Vec<(usize, FrameStatus)> = result
        .frames
        .iter()
        .enumerate()
        .filter(|(_, f)| matches!(f.status, FrameStatus::Failed(_)))
        .map(|(i, f)| (i, f.status.clone()))
        .collect();
    let m = evaluate(&result.trajectory, dataset.ground_truth().unwrap()).unwrap();
    eprintln!(
        "KITTI 06 every 3rd frame, {frontend:?}: {} frames, ATE {:.4} m, drift {:.2} %, \
         failed {failed:?}, {stats:?}",
        dataset.len(),
        m.ate.rmse,
        m.end_point_drift_percent
    );
    assert_eq!(dataset.len(), 17);
    assert!(failed.is_empty(), "failed frames {failed:?}");
    assert_eq!(stats.initialisations, 1, "{stats:?}");
    assert_eq!(result.trajectory.len(), dataset.len());
    assert!(m.ate.rmse <= max_ate_m, "ATE {}", m.ate.rmse);
}

// Measured 2026-11-27 (`cargo test --release -p slamkit-slam --test slam visual_fast_motion:: --
// --include-ignored --nocapture`; docs/experiments/visual-slam.md, "Fast motion: why the
// poses are poor at 3 m steps"): KLT 0.1835 m, every frame tracked, since the stereo profile no
// longer caps the corners at 500 (0.292 m with the cap: 12-65 correspondences, the rest lost to
// wrong minima as the near points' windows grow 1.2-1.4x between frames; more pyramid levels
// or a wider window do not help).
#[test]
fn kitti_06_every_third_frame_klt() {
    tracks_every_frame("kitti_06_every_third_frame_klt", FrontendKind::Klt, 0.20);
}

// Measured 2026-11-28 (the same command): ORB 0.1672 m, every frame tracked, since the stereo
// profile describes the features on two coarser levels too (`local_map.scale_levels = 2`) and
// a guided search whose matches fit no motion is repeated widely (docs/experiments/
// visual-slam.md, "Fast motion: ORB across the scale change"); before, with level 0 only, 10
// of 17 frames failed (ATE 15.1 m). About 1 s in release (0.94 s, KLT 0.59 s).
#[test]
fn kitti_06_every_third_frame_orb() {
    tracks_every_frame("kitti_06_every_third_frame_orb", FrontendKind::Orb, 0.20);
}
