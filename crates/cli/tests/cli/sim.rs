//! `slamkit sim` end to end: the same seed writes the same files byte for byte, another seed
//! other noise, and the dataset readers give back exactly what the simulator produced (issue
//! #5: "the readers round-trip what `sim` writes"): CARMEN and relations for the lidar, TUM
//! RGB-D for the RGB-D camera, KITTI odometry for the stereo pair. Needs no data set.

use slamkit_core::pose::{pose2_to_pose3, pose3_to_pose2};
use slamkit_io::carmen::read_carmen;
use slamkit_io::read_trajectory;
use slamkit_io::relations::read_relations;
use slamkit_io::{Dataset, DatasetFormat};
use slamkit_sim::{RobotKind, SimConfig, Simulation, World};
use std::path::{Path, PathBuf};
use std::process::Command;

const WORLD: &str = "small";

fn sim(seed: u64, out: &Path) {
    sim_with(seed, out, &["--world", WORLD, "--sensors", "lidar2d,range"]);
}

/// Camera runs: half a second of the ground robot in the office.
const CAMERA_ARGS: [&str; 8] = [
    "--sensors",
    "rgbd,stereo",
    "--world",
    "office",
    "--robot",
    "diff-drive",
    "--duration",
    "0.5",
];

/// Runs `slamkit sim` with `args` (which name the world and sensors) and a seed into `out`.
fn sim_with(seed: u64, out: &Path, extra: &[&str]) {
    let run = Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .arg("sim")
        .args(extra)
        .args(["--seed", &seed.to_string(), "--out"])
        .arg(out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "slamkit sim: {}",
        String::from_utf8_lossy(&run.stderr)
    );
}

/// Every dataset file (not report.json, which holds wall time and memory).
const FILES: [&str; 5] = [
    "world.toml",
    "groundtruth.tum",
    "lidar.clf",
    "lidar.relations",
    "ranges.csv",
];

#[test]
fn same_seed_same_bytes_other_seed_other_noise() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b, c) = (
        dir.path().join("a"),
        dir.path().join("b"),
        dir.path().join("c"),
    );
    sim(7, &a);
    sim(7, &b);
    sim(8, &c);
    for file in FILES {
        let bytes_a = std::fs::read(a.join(file)).unwrap();
        assert!(!bytes_a.is_empty(), "{file} is empty");
        assert!(
            bytes_a == std::fs::read(b.join(file)).unwrap(),
            "{file} differs"
        );
    }
    for file in ["lidar.clf", "ranges.csv"] {
        let (x, y) = (std::fs::read(a.join(file)), std::fs::read(c.join(file)));
        assert!(
            x.unwrap() != y.unwrap(),
            "{file} does not depend on the seed"
        );
    }
}

#[test]
fn readers_give_back_what_the_simulator_produced() {
    let dir = tempfile::tempdir().unwrap();
    let seed = 3;
    sim(seed, dir.path());
    let config = SimConfig::default();
    let simulation = Simulation::new(World::builtin(WORLD).unwrap(), config.clone(), seed).unwrap();
    let times = simulation.sample_times(config.lidar.rate_hz);
    let scans = simulation.lidar_scans(&times);
    let truth = simulation.ground_truth(&times);

    // CARMEN log: timestamps (whole µs) and ranges exact, odometry to the 9 decimals written
    let log = read_carmen(&dir.path().join("lidar.clf")).unwrap();
    assert!(log.skipped.is_empty(), "{:?}", log.skipped.first());
    assert_eq!(log.scans.len(), scans.len());
    for (read, made) in log.scans.iter().zip(&scans) {
        assert_eq!(read.timestamp, made.timestamp);
        assert_eq!(read.ranges_m, made.ranges_m);
        assert!((read.angle_min_rad - made.angle_min_rad).abs() < 1e-9);
        assert!((read.angle_increment_rad - made.angle_increment_rad).abs() < 1e-9);
        let (r, m) = (read.odometry.unwrap(), made.odometry.unwrap());
        assert!((r.translation.vector - m.translation.vector).norm() < 1e-8);
        assert!((r.rotation.angle() - m.rotation.angle()).abs() < 1e-8);
    }

    // ground truth (TUM): same times, poses to the printed precision
    let (read, _) = read_trajectory(&dir.path().join("groundtruth.tum")).unwrap();
    assert_eq!(read.poses.len(), truth.poses.len());
    for (r, t) in read.poses.iter().zip(&truth.poses) {
        assert_eq!(r.timestamp, t.timestamp);
        assert!((r.pose.translation.vector - t.pose.translation.vector).norm() < 1e-6);
        assert!(r.pose.rotation.angle_to(&t.pose.rotation) < 1e-6);
    }

    // relations: each one the planar true motion between its two scan times
    let relations = read_relations(&dir.path().join("lidar.relations")).unwrap();
    assert!(relations.len() >= 10);
    let pose_at = |t: f64| {
        let k = times.iter().position(|&x| x == t).unwrap();
        pose2_to_pose3(&pose3_to_pose2(&truth.poses[k].pose))
    };
    for rel in &relations {
        let expected = pose_at(rel.t1).inverse() * pose_at(rel.t2);
        let diff = expected.inverse() * rel.t1_from_t2;
        assert!(diff.translation.vector.norm() < 1e-6 && diff.rotation.angle() < 1e-6);
    }

    // range finders: one CSV row per reading, empty fields for no return
    let text = std::fs::read_to_string(dir.path().join("ranges.csv")).unwrap();
    let readings = simulation.range_readings(&simulation.sample_times(config.range_finder.rate_hz));
    let rows: Vec<&str> = text.lines().skip(1).collect();
    assert_eq!(rows.len(), readings.len());
    let field = |s: &str| (!s.is_empty()).then(|| s.parse::<f64>().unwrap());
    for (row, reading) in rows.iter().zip(&readings) {
        let cols: Vec<&str> = row.split(',').collect();
        assert_eq!(cols.len(), 3, "{row}");
        assert_eq!(cols[0].parse::<f64>().unwrap(), reading.timestamp);
        assert_eq!(field(cols[1]), reading.up_m);
        assert_eq!(field(cols[2]), reading.down_m);
    }
}

/// Every file under `dir`, relative to it, sorted.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                files.push(path.strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    files.sort();
    files
}

#[test]
fn camera_folders_same_seed_same_bytes_other_seed_other_noise() {
    let dir = tempfile::tempdir().unwrap();
    let runs: Vec<PathBuf> = ["a", "b", "c"].iter().map(|n| dir.path().join(n)).collect();
    for (run, seed) in runs.iter().zip([4, 4, 5]) {
        sim_with(seed, run, &CAMERA_ARGS);
    }
    let files: Vec<PathBuf> = files_under(&runs[0])
        .into_iter()
        .filter(|f| f.as_os_str() != "report.json")
        .collect();
    // 16 frames at 30 Hz (2 images each), 6 pairs at 10 Hz, and the list and calibration files
    assert_eq!(files.len(), 32 + 4 + 12 + 3 + 2, "{files:?}");
    assert_eq!(
        files,
        files_under(&runs[1])
            .into_iter()
            .filter(|f| f.as_os_str() != "report.json")
            .collect::<Vec<_>>()
    );
    for file in &files {
        let bytes = std::fs::read(runs[0].join(file)).unwrap();
        assert!(
            bytes == std::fs::read(runs[1].join(file)).unwrap(),
            "{file:?} differs"
        );
    }
    for file in [
        "tum_rgbd_fr1/rgb/0.000000.png",
        "tum_rgbd_fr1/depth/0.000000.png",
        "kitti_stereo/image_1/000000.png",
    ] {
        let (x, y) = (
            std::fs::read(runs[0].join(file)),
            std::fs::read(runs[2].join(file)),
        );
        assert!(
            x.unwrap() != y.unwrap(),
            "{file} does not depend on the seed"
        );
    }
}

#[test]
fn camera_readers_give_back_what_the_simulator_produced() {
    let dir = tempfile::tempdir().unwrap();
    let seed = 9;
    sim_with(seed, dir.path(), &CAMERA_ARGS);
    let config = SimConfig {
        robot: RobotKind::DiffDrive,
        ..SimConfig::default()
    };
    let simulation =
        Simulation::new(World::builtin("office").unwrap(), config.clone(), seed).unwrap();

    // TUM RGB-D: the folder name selects the Freiburg 1 intrinsics the camera was rendered with
    let Dataset::Rgbd(tum) =
        Dataset::open(&dir.path().join("tum_rgbd_fr1"), DatasetFormat::Tum).unwrap()
    else {
        panic!("not RGB-D");
    };
    assert_eq!(tum.color_camera.intrinsics, config.rgbd.intrinsics);
    let times = slamkit_sim::sample_times(0.5, config.rgbd.rate_hz);
    assert_eq!(tum.frames.len(), times.len());
    let truth = tum.ground_truth.as_ref().unwrap();
    for (i, frame) in tum.frames.iter().enumerate() {
        let made = simulation.rgbd_frame(i, times[i]);
        assert_eq!(frame.timestamp, made.timestamp);
        let read = tum.load(frame).unwrap();
        assert!(
            read.color == made.color && read.depth_m == made.depth_m,
            "frame {i}"
        );
        let pose = truth.poses[i].pose;
        assert_eq!(truth.poses[i].timestamp, made.timestamp);
        let diff = made.world_from_camera.inverse() * pose;
        assert!(diff.translation.vector.norm() < 1e-9 && diff.rotation.angle() < 1e-9);
    }

    // KITTI: images, times, calibration, poses relative to the first left camera
    let Dataset::Stereo(kitti) =
        Dataset::open(&dir.path().join("kitti_stereo"), DatasetFormat::Kitti).unwrap()
    else {
        panic!("not stereo");
    };
    assert_eq!(kitti.left_camera.intrinsics, config.stereo.intrinsics);
    assert!((kitti.baseline_m() - config.stereo.baseline_m).abs() < 1e-15);
    let times = slamkit_sim::sample_times(0.5, config.stereo.rate_hz);
    assert_eq!(kitti.frames.len(), times.len());
    let poses = kitti.ground_truth.as_ref().unwrap();
    let first = simulation.stereo_frame(0, 0.0).world_from_left.inverse();
    for (i, frame) in kitti.frames.iter().enumerate() {
        let made = simulation.stereo_frame(i, times[i]);
        assert_eq!(frame.timestamp, made.timestamp);
        let read = kitti.load(frame).unwrap();
        assert!(
            read.left == made.left && read.right == made.right,
            "pair {i}"
        );
        let diff = (first * made.world_from_left).inverse() * poses.poses[i].pose;
        assert!(diff.translation.vector.norm() < 1e-9 && diff.rotation.angle() < 1e-9);
    }
}

#[test]
fn unknown_sensors_and_bad_durations_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    for (args, message) in [
        (vec!["--sensors", "sonar"], "unknown sensor"),
        (vec!["--duration=-1"], "--duration"),
        (vec!["--duration=nan"], "--duration"),
    ] {
        let run = Command::new(env!("CARGO_BIN_EXE_slamkit"))
            .args(["sim", "--world", WORLD])
            .args(args)
            .arg("--out")
            .arg(dir.path())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(
            !run.status.success() && stderr.contains(message),
            "{stderr}"
        );
    }
}
