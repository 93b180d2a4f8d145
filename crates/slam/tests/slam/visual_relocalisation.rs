//! Relocalisation (issue 20, item 5) on 7-Scenes RedKitchen 0–599 of `$SLAMKIT_DATA` (skipped
//! when it is not set), with loop closure on (`slamkit vo --slam`): the sequence read with a
//! stretch of 30 frames made black (their colour images replaced by a black JPEG), and read
//! with 100 frames left out (a kidnapped camera). Tracking is lost; each frame after is looked
//! for among the keyframes, and tracking resumes where it is found, in the same map frame.
//! The frames in between have no pose. Scored against the ground truth: the frames after the
//! loss, under the SE(3) alignment of the whole trajectory (one map frame: a resumed stretch
//! in a frame of its own would not fit it).

use std::path::Path;

use slamkit_eval::{ate, Alignment, Pairing};
use slamkit_io::{Dataset, DatasetFormat};
use slamkit_slam::visual::{self, RunOptions, VisualRun, VisualSlam, VisualStats};
use slamkit_testdata::data;
use slamkit_vo::FrontendKind;

const REDKITCHEN: &str = "rgbd/7scenes_redkitchen_frames_0000-0599";

/// Runs `dataset` with `frontend` and loop closure on.
fn run(dataset: &Dataset, frontend: FrontendKind) -> (VisualRun, VisualStats) {
    let config = visual::session_settings(
        frontend,
        DatasetFormat::SevenScenes,
        Some("kinect-v1"),
        None,
        true,
    )
    .unwrap();
    let mut session = VisualSlam::new(&config, visual::rig_of(dataset)).unwrap();
    let result = visual::run(
        &mut session,
        dataset.observations(),
        RunOptions::default(),
        |_| {},
    )
    .unwrap();
    (result, session.stats())
}

/// RMSE \[m\] of the poses at or after `from_s`, the whole trajectory aligned (SE(3)).
fn ate_after(result: &VisualRun, dataset: &Dataset, from_s: f64) -> (f64, f64, usize) {
    let gt = dataset.ground_truth().unwrap();
    let a = ate(gt, &result.trajectory, Pairing::default(), Alignment::Se3).unwrap();
    let after: Vec<f64> = a
        .timestamps
        .iter()
        .zip(&a.errors_m)
        .filter(|(t, _)| **t >= from_s - 1e-9)
        .map(|(_, e)| *e)
        .collect();
    let rmse = (after.iter().map(|e| e * e).sum::<f64>() / after.len() as f64).sqrt();
    (a.stats.rmse, rmse, after.len())
}

/// 7-Scenes with the colour images of frames `black` replaced by a black JPEG.
fn with_black_stretch(dir: &Path, tmp: &Path, black: std::ops::Range<usize>) -> Dataset {
    let Dataset::Rgbd(mut sequence) = Dataset::open(dir, DatasetFormat::SevenScenes).unwrap()
    else {
        panic!("7-Scenes is an RGB-D dataset");
    };
    let path = tmp.join("black.color.jpg");
    image::RgbImage::new(640, 480).save(&path).unwrap();
    for f in &mut sequence.frames[black] {
        f.color.clone_from(&path);
    }
    Dataset::Rgbd(sequence)
}

fn black_stretch_is_survived(test: &str, frontend: FrontendKind, max_ate_after_m: f64) {
    let Some(dir) = data(test, REDKITCHEN) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let black = 300..330;
    let dataset = with_black_stretch(&dir, tmp.path(), black.clone());
    let (result, stats) = run(&dataset, frontend);
    // no pose for a black frame, and none invented while lost
    let timestamps = dataset.timestamps();
    let posed = |i: usize| {
        result
            .trajectory
            .poses
            .iter()
            .any(|p| p.timestamp == timestamps[i])
    };
    assert!(black.clone().all(|i| !posed(i)));
    // tracking resumes within 10 frames after the stretch, and holds
    let resumed = (black.end..timestamps.len()).find(|&i| posed(i)).unwrap();
    let posed_after = (black.end..timestamps.len()).filter(|&i| posed(i)).count();
    let (ate_all, ate_after, scored) = ate_after(&result, &dataset, timestamps[black.end]);
    eprintln!(
        "{frontend:?}, frames {black:?} black: resumed at {resumed}, {posed_after} posed after, \
         ATE {ate_all:.4} m, after the stretch {ate_after:.4} m ({scored} frames), {stats:?}"
    );
    assert!(resumed < black.end + 10, "resumed at frame {resumed}");
    assert!(stats.relocalisations >= 1, "{stats:?}");
    assert!(posed_after >= timestamps.len() - black.end - 15);
    assert!(ate_after <= max_ate_after_m, "ATE after {ate_after}");
}

// measured: both resume on frame 330, the first after the stretch; ATE after it 0.0290 m
// (KLT) and 0.0375 m (ORB), over all frames 0.0308 / 0.0484 m
#[test]
fn seven_scenes_black_stretch_relocalises_klt() {
    black_stretch_is_survived(
        "seven_scenes_black_stretch_relocalises_klt",
        FrontendKind::Klt,
        0.04,
    );
}

#[test]
fn seven_scenes_black_stretch_relocalises_orb() {
    black_stretch_is_survived(
        "seven_scenes_black_stretch_relocalises_orb",
        FrontendKind::Orb,
        0.04,
    );
}

#[test]
fn seven_scenes_kidnapped_camera_relocalises() {
    let Some(dir) = data("seven_scenes_kidnapped_camera_relocalises", REDKITCHEN) else {
        return;
    };
    // frames 370-469 left out: the camera jumps from frame 369 to frame 470, into the part of
    // the kitchen it saw around frames 180-340
    let Dataset::Rgbd(mut sequence) = Dataset::open(&dir, DatasetFormat::SevenScenes).unwrap()
    else {
        panic!("7-Scenes is an RGB-D dataset");
    };
    sequence.frames.drain(370..470);
    let landing = sequence.frames[370].timestamp;
    let dataset = Dataset::Rgbd(sequence);
    // measured 0.0216 / 0.0486 m over the frames after the jump (0.0287 / 0.0531 m over all):
    // ORB's odometry is the weaker on this sequence (0.0446 m with --slam, no jump)
    for (frontend, bound) in [(FrontendKind::Klt, 0.03), (FrontendKind::Orb, 0.055)] {
        let (result, stats) = run(&dataset, frontend);
        let (ate_all, ate_after, scored) = ate_after(&result, &dataset, landing);
        eprintln!(
            "{frontend:?}, kidnapped from 369 to 470: ATE {ate_all:.4} m, after {ate_after:.4} m \
             ({scored} frames), {stats:?}"
        );
        assert!(stats.relocalisations >= 1, "{stats:?}");
        assert!(scored >= 100, "{scored} frames after the jump");
        assert!(ate_after <= bound, "ATE after {ate_after}");
    }
}
