//! Loop closure (`loop_closure.enabled`, `slamkit vo --slam`) on the real sequences of
//! `$SLAMKIT_DATA` (skipped when it is not set): 7-Scenes RedKitchen 0–599 revisits the
//! places of frames ~180–340 from frame ~470 on; the KITTI 06 clip (51 frames of a straight
//! drive) has no loop. Every accepted closure is checked against the ground truth (wrong: off
//! by more than 0.3 m or 10°). Bounds sit just above what the defaults measure (BENCHMARKS.md,
//! "Visual SLAM").

use slamkit_testdata::data;
use std::path::Path;

use slamkit_core::{Observation, Trajectory};
use slamkit_io::{Dataset, DatasetFormat};
use slamkit_slam::map_file::Rig;
use slamkit_slam::profile::Profile;
use slamkit_slam::visual::{self, LoopStats, RunOptions, VisualSlam};
use slamkit_vo::metrics::ClosureCheck;
use slamkit_vo::{evaluate, FrontendKind, VoConfig, VoMetrics};

/// Runs `profile` with `frontend` and loop closure on; the metrics, the back end's counts and
/// the closures scored against the ground truth.
fn run(
    dir: &Path,
    format: DatasetFormat,
    profile: &str,
    frontend: FrontendKind,
) -> (VoMetrics, LoopStats, ClosureCheck) {
    let config = visual::session_settings(frontend, format, Some(profile), None, true).unwrap();
    let dataset = Dataset::open(dir, format).unwrap();
    let mut session = VisualSlam::new(&config, visual::rig_of(&dataset)).unwrap();
    let result = visual::run(
        &mut session,
        dataset.observations(),
        RunOptions::default(),
        |_| {},
    )
    .unwrap();
    let gt = dataset.ground_truth().unwrap();
    let (stats, closures) = session.loop_closures().unwrap();
    let check = visual::check_closures(&closures, gt);
    // the map a run saves holds its keyframes where loop closure left them
    let worst = session
        .map()
        .keyframes
        .iter()
        .map(|k| {
            let frame = result
                .trajectory
                .poses
                .iter()
                .find(|p| p.timestamp == k.timestamp)
                .expect("a keyframe is a tracked frame");
            (frame.pose.inverse() * k.pose).translation.vector.norm()
        })
        .fold(0.0, f64::max);
    assert!(
        worst < 1e-6,
        "a saved keyframe is {worst} m off its corrected pose"
    );
    let metrics = evaluate(&result.trajectory, gt).unwrap();
    eprintln!(
        "{profile} {frontend:?} --slam: ATE {:.4} m, {stats:?}, {check:?}",
        metrics.ate.rmse
    );
    (metrics, stats, check)
}

/// 7-Scenes RedKitchen 0-599 with `frontend` and loop closure: at least one closure, none
/// wrong, the ATE at most `max_ate_m`.
fn redkitchen_closes_its_loop(test: &str, frontend: FrontendKind, max_ate_m: f64) {
    let Some(dir) = data(test, "rgbd/7scenes_redkitchen_frames_0000-0599") else {
        return;
    };
    let (m, stats, check) = run(&dir, DatasetFormat::SevenScenes, "kinect-v1", frontend);
    assert!(stats.accepted >= 1, "{stats:?}");
    assert_eq!((check.checked, check.wrong), (stats.accepted, 0));
    assert!(m.ate.rmse <= max_ate_m, "ATE {}", m.ate.rmse);
}

#[test]
fn seven_scenes_redkitchen_closes_its_loop_klt() {
    // measured 0.0351 m (0.0329 m without loop closure: the one closure is right to 1.3 cm
    // and 0.7°, but frames 0-180 are never revisited and carry most of the error)
    redkitchen_closes_its_loop(
        "seven_scenes_redkitchen_closes_its_loop_klt",
        FrontendKind::Klt,
        0.038,
    );
}

#[test]
fn seven_scenes_redkitchen_closes_its_loop_orb() {
    // measured 0.0446 m (0.070 m without loop closure)
    redkitchen_closes_its_loop(
        "seven_scenes_redkitchen_closes_its_loop_orb",
        FrontendKind::Orb,
        0.048,
    );
}

#[test]
fn kitti_06_clip_has_no_loop_to_close() {
    let Some(dir) = data(
        "kitti_06_clip_has_no_loop_to_close",
        "stereo/kitti_odometry_06_0000-0050",
    ) else {
        return;
    };
    // KLT: issue 20's bar, 0.07 m
    for (frontend, bound) in [(FrontendKind::Klt, 0.07), (FrontendKind::Orb, 0.14)] {
        let (m, stats, _) = run(&dir, DatasetFormat::Kitti, "stereo", frontend);
        // a straight drive: every frame a keyframe (~1 m apart), no place seen twice
        assert_eq!(stats.accepted, 0, "{stats:?}");
        assert!(stats.keyframes >= 45, "{stats:?}");
        // measured 0.0606 / 0.1328 m, the same as without loop closure
        assert!(m.ate.rmse <= bound, "{frontend:?}: ATE {}", m.ate.rmse);
    }
}

/// 7-Scenes RedKitchen 0-599 played forward, backward and forward again (frames renumbered
/// 1/30 s apart), one [`visual::run`] per pass on the same session. Pass 1 closes its loop;
/// passes 2 and 3 see only places of the map, so their frames due to become keyframes are
/// localised against the existing keyframes instead: the map (keyframes, bytes) stays within
/// 10 % of pass 1's, no closure or localisation is wrong, the ATE does not grow
/// (BENCHMARKS.md, "Visual SLAM").
///
/// 1800 frames, 215 s in release (2026-11-27): a measurement, not a CI test; the same rule is
/// checked in CI by `three_laps_keep_the_keyframes_of_the_first` (the slam crate's unit
/// tests, a synthetic 3-lap drive, under 1 s).
#[test]
#[ignore = "1800 frames of 7-Scenes, 215 s: docs/experiments/visual-slam.md"]
fn seven_scenes_played_three_times_closes_loops_on_every_revisit() {
    let Some(dir) = data(
        "seven_scenes_played_three_times_closes_loops_on_every_revisit",
        "rgbd/7scenes_redkitchen_frames_0000-0599",
    ) else {
        return;
    };
    let dataset = Dataset::open(&dir, DatasetFormat::SevenScenes).unwrap();
    let mut config = Profile::builtin("kinect-v1")
        .unwrap()
        .apply("vo", VoConfig::default())
        .unwrap();
    config.loop_closure.enabled = true;
    let n = dataset.len();
    let passes: [Vec<usize>; 3] = [
        (0..n).collect(),
        (0..n - 1).rev().collect(),
        (1..n).collect(),
    ];
    let gt = dataset.ground_truth().unwrap();
    let times = dataset.timestamps();
    let mut truth = Trajectory::new();
    let mut session = VisualSlam::new(&config, visual::rig_of(&dataset)).unwrap();
    let mut first_pass: Option<(usize, usize)> = None;
    let mut localised = 0;
    for (pass, frames) in passes.iter().enumerate() {
        let first = truth.len();
        for (k, &i) in frames.iter().enumerate() {
            let pose = gt.poses.iter().find(|p| p.timestamp == times[i]).unwrap();
            truth.push((first + k) as f64 / 30.0, pose.pose);
        }
        let source = frames.iter().enumerate().map(|(k, &i)| {
            dataset.observation(i).unwrap().map(|mut o| {
                if let Observation::Rgbd(f) = &mut o {
                    f.timestamp = (first + k) as f64 / 30.0;
                }
                o
            })
        });
        let result = visual::run(&mut session, source, RunOptions::default(), |_| {}).unwrap();
        let (stats, closures) = session.loop_closures().unwrap();
        let check = visual::check_closures(&closures, &truth);
        let in_map = visual::check_closures(&session.map_localisations().unwrap(), &truth);
        let file = session.map().to_map_file(Rig::Rgbd).unwrap();
        let bytes: usize = file.sections.iter().map(|s| s.data.len()).sum();
        let ate = evaluate(&result.trajectory, &truth).unwrap().ate.rmse;
        let peak_rss = slamkit_slam::memory::peak_rss_bytes().unwrap_or(0);
        eprintln!(
            "pass {}: {} keyframes, {} map points, map {:.3} MiB ({:.1} KiB a keyframe), \
             peak RSS {:.0} MiB, ATE {ate:.4} m, {stats:?}, closures {check:?}, \
             localisations {in_map:?}",
            pass + 1,
            stats.keyframes,
            stats.map_points,
            bytes as f64 / (1 << 20) as f64,
            bytes as f64 / 1024.0 / stats.keyframes as f64,
            peak_rss as f64 / (1 << 20) as f64,
        );
        assert_eq!((check.checked, check.wrong), (stats.accepted, 0));
        assert_eq!((in_map.checked, in_map.wrong), (stats.localised, 0));
        assert!(ate <= 0.038, "pass {}: ATE {ate}", pass + 1);
        match first_pass {
            None => {
                assert!(stats.accepted >= 1, "pass 1: {stats:?}");
                first_pass = Some((stats.keyframes, bytes));
            }
            Some((keyframes, first_bytes)) => {
                // revisits are recognised (localised in the map) and the map stays bounded
                assert!(
                    stats.localised >= localised + keyframes / 2,
                    "pass {}: {stats:?}",
                    pass + 1
                );
                assert!(
                    10 * stats.keyframes <= 11 * keyframes && 10 * bytes <= 11 * first_bytes,
                    "pass {}: {stats:?}, {bytes} bytes",
                    pass + 1
                );
            }
        }
        localised = stats.localised;
    }
}
