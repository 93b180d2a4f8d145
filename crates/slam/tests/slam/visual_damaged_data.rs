//! Issue 25 (7, 8, 9) end to end: the real KITTI 06 clip of `$SLAMKIT_DATA` (51 stereo frames
//! with ground truth), damaged in a temporary copy of symbolic links, through the visual
//! session and the VO metrics. A missing image fails its own frame (no shift of later frames
//! against the ground truth), a frame odometry cannot track gets no pose (nothing held over it
//! is scored), and ground truth shorter than the sequence scores only its frames.

use std::path::Path;

use slamkit_io::{Dataset, DatasetFormat};
use slamkit_slam::profile::Profile;
use slamkit_slam::visual::{self, RunOptions, VisualRun, VisualSlam};
use slamkit_vo::{evaluate, FrameStatus, FrontendKind, VoConfig, VoMetrics};

const CLIP: &str = "stereo/kitti_odometry_06_0000-0050";

/// `root` as links in `to`, with `replace(rel, link_target)` deciding each file: `None` leaves
/// it out, `Some(bytes)` writes those bytes instead of a link.
fn copy_with(root: &Path, to: &Path, change: &dyn Fn(&str) -> Option<Option<Vec<u8>>>) {
    for sub in ["", "image_0", "image_1"] {
        std::fs::create_dir_all(to.join(sub)).unwrap();
        for entry in std::fs::read_dir(root.join(sub)).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                continue;
            }
            let rel = path
                .strip_prefix(root)
                .unwrap()
                .to_str()
                .unwrap()
                .to_string();
            match change(&rel) {
                None => std::os::unix::fs::symlink(&path, to.join(&rel)).unwrap(),
                Some(None) => {}
                Some(Some(bytes)) => std::fs::write(to.join(&rel), bytes).unwrap(),
            }
        }
    }
}

fn run(dir: &Path) -> (VisualRun, Dataset) {
    let dataset = Dataset::open(dir, DatasetFormat::Kitti).unwrap();
    let config = Profile::builtin("stereo")
        .unwrap()
        .apply(
            "vo",
            VoConfig {
                frontend: FrontendKind::Klt,
                ..VoConfig::default()
            },
        )
        .unwrap();
    let mut session = VisualSlam::new(&config, visual::rig_of(&dataset)).unwrap();
    let result = visual::run(
        &mut session,
        dataset.observations(),
        RunOptions::default(),
        |_| {},
    )
    .unwrap();
    (result, dataset)
}

fn score(result: &VisualRun, dataset: &Dataset) -> VoMetrics {
    evaluate(&result.trajectory, dataset.ground_truth().unwrap()).unwrap()
}

/// The stamps of a run's trajectory.
fn stamps(result: &VisualRun) -> Vec<f64> {
    result
        .trajectory
        .poses
        .iter()
        .map(|p| p.timestamp)
        .collect()
}

/// KITTI frame times without frame `without`.
fn times_without(without: u32) -> Vec<f64> {
    (0..51u32)
        .filter(|&i| i != without)
        .map(|i| f64::from(i) * 0.1)
        .collect()
}

#[test]
fn missing_kitti_image_fails_its_own_frame_without_shifting_the_rest() {
    let Some(root) = slamkit_testdata::data(
        "missing_kitti_image_fails_its_own_frame_without_shifting_the_rest",
        CLIP,
    ) else {
        return;
    };
    let (intact, dataset) = run(&root);
    let intact_m = score(&intact, &dataset);
    assert_eq!(intact.trajectory.len(), 51);
    let tmp = tempfile::tempdir().unwrap();
    copy_with(&root, tmp.path(), &|rel| {
        (rel == "image_0/000020.png").then_some(None)
    });
    let (damaged, dataset) = run(tmp.path());
    assert_eq!((damaged.stats.frames, damaged.stats.skipped), (51, 1));
    assert!(
        damaged.skipped[0].starts_with("frame 20: "),
        "{:?}",
        damaged.skipped
    );
    assert_eq!(stamps(&damaged), times_without(20));
    let m = score(&damaged, &dataset);
    eprintln!(
        "KITTI 06 clip: ATE {:.4} m intact, {:.4} m with frame 20 missing",
        intact_m.ate.rmse, m.ate.rmse
    );
    assert_eq!((m.scored_frames, m.frames_without_ground_truth), (50, 0));
    // the shifted frames gave 0.66 m
    assert!(m.ate.rmse < 1.5 * intact_m.ate.rmse, "ATE {}", m.ate.rmse);
}

#[test]
fn untrackable_kitti_frame_gets_no_pose() {
    let Some(root) = slamkit_testdata::data("untrackable_kitti_frame_gets_no_pose", CLIP) else {
        return;
    };
    // frame 30's left image black: a dead sensor, decoded fine but untrackable
    let mut black = std::io::Cursor::new(Vec::new());
    image::GrayImage::new(1226, 370)
        .write_to(&mut black, image::ImageFormat::Png)
        .unwrap();
    let black = black.into_inner();
    let tmp = tempfile::tempdir().unwrap();
    copy_with(&root, tmp.path(), &|rel| {
        (rel == "image_0/000030.png").then(|| Some(black.clone()))
    });
    let (damaged, dataset) = run(tmp.path());
    let status = damaged
        .frames
        .iter()
        .find(|f| f.index == 30)
        .map(|f| &f.status);
    assert!(matches!(status, Some(FrameStatus::Failed(_))), "{status:?}");
    assert_eq!(stamps(&damaged), times_without(30));
    let m = score(&damaged, &dataset);
    eprintln!("KITTI 06 clip, frame 30 black: ATE {:.4} m", m.ate.rmse);
    assert_eq!((m.scored_frames, m.frames_without_ground_truth), (50, 0));
}

#[test]
fn kitti_ground_truth_shorter_than_the_images_scores_only_its_frames() {
    let Some(root) = slamkit_testdata::data(
        "kitti_ground_truth_shorter_than_the_images_scores_only_its_frames",
        CLIP,
    ) else {
        return;
    };
    let poses = std::fs::read_to_string(root.join("poses.txt")).unwrap();
    let first_30: String = poses.lines().take(30).map(|l| format!("{l}\n")).collect();
    let tmp = tempfile::tempdir().unwrap();
    copy_with(&root, tmp.path(), &|rel| {
        (rel == "poses.txt").then(|| Some(first_30.clone().into_bytes()))
    });
    let (result, dataset) = run(tmp.path());
    let m = score(&result, &dataset);
    eprintln!(
        "KITTI 06 clip, 30 of 51 poses: ATE {:.4} m, drift {:.2} % of {:.1} m",
        m.ate.rmse, m.end_point_drift_percent, m.path_length_m
    );
    assert_eq!((m.scored_frames, m.frames_without_ground_truth), (30, 21));
    // the drift of the 30 scored frames, not of frame 50 against frame 29's truth
    assert!(
        m.end_point_drift_percent < 2.0,
        "{}",
        m.end_point_drift_percent
    );
}
