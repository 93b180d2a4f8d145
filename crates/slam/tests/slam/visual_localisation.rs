//! Localisation in a saved visual map (issue 20, item 6; `slamkit vo --localize`) on 7-Scenes
//! RedKitchen 0–599 of `$SLAMKIT_DATA` (skipped when it is not set): the frames mapped with
//! loop closure on (`--slam --save-map`), then run again in the saved map with no start pose.
//! The second run's poses are in the map's frame: scored against the mapping run's trajectory
//! with no alignment at all.

use slamkit_eval::{ate, Alignment, Pairing};
use slamkit_io::{Dataset, DatasetFormat};
use slamkit_slam::map_file::MapFileError;
use slamkit_slam::visual::{self, RunOptions, VisualSlam};
use slamkit_slam::{Session, SlamError};
use slamkit_testdata::data;
use slamkit_vo::frame::Rig;
use slamkit_vo::{FrameStatus, FrontendKind, VoConfig};

fn config(frontend: FrontendKind) -> VoConfig {
    visual::session_settings(
        frontend,
        DatasetFormat::SevenScenes,
        Some("kinect-v1"),
        None,
        false,
    )
    .unwrap()
}

#[test]
fn seven_scenes_relocalises_in_its_saved_map_klt() {
    let Some(dir) = data(
        "seven_scenes_relocalises_in_its_saved_map_klt",
        "rgbd/7scenes_redkitchen_frames_0000-0599",
    ) else {
        return;
    };
    let dataset = Dataset::open(&dir, DatasetFormat::SevenScenes).unwrap();
    let rig = visual::rig_of(&dataset);
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("kitchen.skmap");
    // mapping: --slam --save-map
    let mut slam_config = config(FrontendKind::Klt);
    slam_config.loop_closure.enabled = true;
    let mut mapping = VisualSlam::new(&slam_config, rig.clone()).unwrap();
    let mapped = visual::run(
        &mut mapping,
        dataset.observations(),
        RunOptions::default(),
        |_| {},
    )
    .unwrap();
    Session::save(&mapping, &path).unwrap();
    // localisation: --localize, no start pose
    let map = visual::load_map(&path, &rig).unwrap();
    let mut session = VisualSlam::localising_in(&config(FrontendKind::Klt), rig, &map).unwrap();
    let located = visual::run(
        &mut session,
        dataset.observations(),
        RunOptions::default(),
        |_| {},
    )
    .unwrap();
    let first_fix = located
        .frames
        .iter()
        .position(|f| !matches!(f.status, FrameStatus::Failed(_)))
        .unwrap();
    let against_map = ate(
        &mapped.trajectory,
        &located.trajectory,
        Pairing::default(),
        Alignment::None,
    )
    .unwrap();
    let stats = session.stats();
    let gt = dataset.ground_truth().unwrap();
    let against_gt = ate(gt, &located.trajectory, Pairing::default(), Alignment::Se3).unwrap();
    eprintln!(
        "localised in the map from frame {first_fix}: {} of {} frames posed, ATE against the \
         map's trajectory (no alignment) {:.4} m (max {:.4} m), against the ground truth \
         (SE(3)-aligned) {:.4} m, {stats:?}",
        located.trajectory.len(),
        dataset.len(),
        against_map.stats.rmse,
        against_map.stats.max,
        against_gt.stats.rmse,
    );
    assert!(first_fix < 5, "first found at frame {first_fix}");
    assert!(located.trajectory.len() >= dataset.len() - 10);
    // tracked against the map's points: measured 0.0072 m (max 0.081 m), 591 of 600 frames
    // fixed by the map; by odometry alone from the first fix on it was 0.0306 m (max 0.060 m),
    // the frames after the loop (~470 on), which loop closure moved in the map, drifting from
    // it. Issue 20 asks for 0.03 m.
    assert!(against_map.stats.rmse <= 0.03, "{:?}", against_map.stats);
    assert!(stats.map_tracked >= dataset.len() * 9 / 10, "{stats:?}");
    // the map of another rig is refused, naming the file
    let Rig::Rgbd { color, .. } = visual::rig_of(&dataset) else {
        panic!("7-Scenes is an RGB-D dataset");
    };
    let stereo = Rig::Stereo {
        left: color,
        baseline_m: 0.1,
    };
    let err = visual::load_map(&path, &stereo).unwrap_err();
    assert!(
        matches!(
            &err,
            SlamError::MapFile {
                source: MapFileError::WrongRig { .. },
                ..
            }
        ),
        "{err}"
    );
}
