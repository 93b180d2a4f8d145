//! Accuracy of the visual session on the real sequences of `$SLAMKIT_DATA` (skipped when it is
//! not set), started at the identity and scored after SE(3) alignment. The bounds sit just above
//! what the published defaults measure (BENCHMARKS.md, "Visual odometry").

use slamkit_testdata::data;
use std::path::Path;

use slamkit_io::{Dataset, DatasetFormat};
use slamkit_slam::profile::Profile;
use slamkit_slam::visual::{self, RunOptions, VisualSlam};
use slamkit_vo::{evaluate, FrameStatus, FrontendKind, TrackingMode, VoConfig, VoMetrics};

fn score(
    dir: &Path,
    format: DatasetFormat,
    config: &VoConfig,
) -> Result<(VoMetrics, usize), Box<dyn std::error::Error>> {
    let dataset = Dataset::open(dir, format)?;
    let mut session = VisualSlam::new(config, visual::rig_of(&dataset))?;
    let result = visual::run(
        &mut session,
        dataset.observations(),
        RunOptions::default(),
        |_| {},
    )?;
    let failed = result
        .frames
        .iter()
        .filter(|f| matches!(f.status, FrameStatus::Failed(_)))
        .count();
    let gt = dataset.ground_truth().ok_or("no ground truth")?;
    Ok((evaluate(&result.trajectory, gt)?, failed))
}

/// The `stereo` profile's settings for `frontend`, as `slamkit vo` takes them for KITTI.
fn stereo(frontend: FrontendKind) -> VoConfig {
    let base = VoConfig {
        frontend,
        ..VoConfig::default()
    };
    Profile::builtin("stereo")
        .unwrap()
        .apply("vo", base)
        .unwrap()
}

#[test]
fn kitti_06_clip_klt_frame_to_frame() {
    let Some(dir) = data(
        "kitti_06_clip_klt_frame_to_frame",
        "stereo/kitti_odometry_06_0000-0050",
    ) else {
        return;
    };
    let config = stereo(FrontendKind::Klt);
    let (m, failed) = score(&dir, DatasetFormat::Kitti, &config).unwrap();
    eprintln!(
        "KITTI 06 KLT: ATE {:.4} m, drift {:.2} %, {failed} failed",
        m.ate.rmse, m.end_point_drift_percent
    );
    // measured 0.0606 m and 0.61 % (issue 4: ≤ 0.15 m, ≤ 1.0 %)
    assert!(m.ate.rmse <= 0.115, "ATE {}", m.ate.rmse);
    assert!(
        m.end_point_drift_percent <= 0.8,
        "drift {}",
        m.end_point_drift_percent
    );
    assert_eq!(failed, 0);
}

#[test]
fn kitti_06_clip_orb_frame_to_frame() {
    let Some(dir) = data(
        "kitti_06_clip_orb_frame_to_frame",
        "stereo/kitti_odometry_06_0000-0050",
    ) else {
        return;
    };
    let config = stereo(FrontendKind::Orb);
    let (m, failed) = score(&dir, DatasetFormat::Kitti, &config).unwrap();
    eprintln!(
        "KITTI 06 ORB: ATE {:.4} m, drift {:.2} %, {failed} failed",
        m.ate.rmse, m.end_point_drift_percent
    );
    // measured 0.0856 m, 0.52 %, with the features also described on coarser levels
    // (`local_map.scale_levels`; 0.0944 m without, 0.1328 m before the cells; issue 4:
    // ≤ 0.15 m, ≤ 1.0 %)
    assert!(m.ate.rmse <= 0.10, "ATE {}", m.ate.rmse);
    assert!(
        m.end_point_drift_percent <= 1.0,
        "drift {}",
        m.end_point_drift_percent
    );
    assert_eq!(failed, 0);
}

#[test]
fn seven_scenes_redkitchen_local_map() {
    let Some(dir) = data(
        "seven_scenes_redkitchen_local_map",
        "rgbd/7scenes_redkitchen_frames_0000-0599",
    ) else {
        return;
    };
    let config = Profile::builtin("kinect-v1")
        .unwrap()
        .apply("vo", VoConfig::default())
        .unwrap();
    assert_eq!(config.mode, TrackingMode::LocalMap);
    let (m, failed) = score(&dir, DatasetFormat::SevenScenes, &config).unwrap();
    eprintln!(
        "7-Scenes local map: ATE {:.4} m, drift {:.2} %, {failed} failed",
        m.ate.rmse, m.end_point_drift_percent
    );
    // measured 0.0400 m over all 600 frames (issue 4: ≤ 0.045 m)
    assert!(m.ate.rmse <= 0.043, "ATE {}", m.ate.rmse);
    assert_eq!(failed, 0);
}
