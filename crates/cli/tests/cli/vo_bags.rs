//! `slamkit vo` on ROS 2 bags of a real RGB-D sequence written by an independent tool (PyPI
//! `rosbags`, `scripts/rgbd_to_ros2_bags.py`, which `scripts/make_ros2_bags.sh` runs before
//! the tests in `.ci/run`): the first 60 frames of 7-Scenes RedKitchen
//! (`$SLAMKIT_DATA/rgbd/7scenes_redkitchen_frames_0000-0599`) as an MCAP bag (rgb8 colour,
//! 16UC1 depth in mm, one CameraInfo topic) and an SQLite `.db3` bag (bgr8 colour, 32FC1 depth
//! in m with NaN holes, a CameraInfo topic per camera), depth stamped 4 ms after colour.
//!
//! Each bag must give the trajectory of the same frames read as a 7-Scenes folder,
//! `redkitchen_ref/`, whose colour images are the pixels the bags carry (Pillow's decoding of
//! the JPEGs, stored as PNG): slamkit's JPEG decoder rounds some pixels differently from
//! Pillow's, so the original folder is not the reference for raw-image bags. The frames' times
//! differ by the bags' nanosecond stamps (N/30 s rounded to 1 ns).
//!
//! Skipped only when the bags are absent and `SLAMKIT_DATA` is unset; with `SLAMKIT_DATA` set,
//! missing bags are a failure (run the script).

use slamkit_io::trajectory_file::read_trajectory;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn slamkit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .args(args)
        .output()
        .unwrap()
}

fn vo(input: &Path, out: &Path, more: &[&str]) -> String {
    let mut args = vec![
        "vo",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(more);
    let run = slamkit(&args);
    assert!(
        run.status.success(),
        "slamkit {args:?}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    String::from_utf8(run.stdout).unwrap()
}

/// `target/ros2-bags/<name>` (a bag, or the reference folder), or `None` (skipped) when it is
/// absent and `SLAMKIT_DATA` is unset.
fn written(test: &str, name: &str, marker: &str) -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../target/ros2-bags")
        .join(name);
    if dir.join(marker).exists() {
        return Some(dir);
    }
    slamkit_testdata::data(test, "")?;
    panic!(
        "{}: missing although SLAMKIT_DATA is set; run scripts/make_ros2_bags.sh",
        dir.display()
    );
}

/// Largest position difference between two trajectories frame by frame \[m\], and the largest
/// time difference \[s\]; they must have the same frames.
fn largest_difference(a: &Path, b: &Path) -> (f64, f64, usize) {
    let (a, _) = read_trajectory(a).unwrap();
    let (b, _) = read_trajectory(b).unwrap();
    assert_eq!(a.poses.len(), b.poses.len());
    let mut worst = (0.0f64, 0.0f64);
    for (p, q) in a.poses.iter().zip(&b.poses) {
        let d = (p.pose.translation.vector - q.pose.translation.vector).norm();
        worst = (
            worst.0.max(d),
            worst.1.max((p.timestamp - q.timestamp).abs()),
        );
    }
    (worst.0, worst.1, a.poses.len())
}

#[test]
fn vo_on_rgbd_bags_gives_the_folder_trajectory() {
    let test = "vo_on_rgbd_bags_gives_the_folder_trajectory";
    let Some(reference) = written(test, "redkitchen_ref", "camera-intrinsics.txt") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let folder_out = tmp.path().join("folder");
    vo(&reference, &folder_out, &[]);
    for (bag, topics) in [
        ("redkitchen_mcap", "colour /camera/color/image_raw, depth /camera/aligned_depth_to_color/image_raw, camera /camera/color/camera_info"),
        ("redkitchen_db3", "colour /camera/rgb/image_color, depth /camera/depth_registered/image, camera /camera/rgb/camera_info"),
    ] {
        let path = written(test, bag, "metadata.yaml").unwrap();
        let out = tmp.path().join(bag);
        let stdout = vo(&path, &out, &["--profile", "kinect-v1"]);
        assert_same_run(bag, &stdout, topics, 60, &folder_out, &out);
    }
}

/// The bag run `bag_out` (its printed `stdout`) read `topics` and paired all `frames` frames,
/// and its trajectory is the folder run's `folder_out`, pose by pose, to 1e-6 m and 1e-6 s.
fn assert_same_run(
    label: &str,
    stdout: &str,
    topics: &str,
    frames: usize,
    folder_out: &Path,
    bag_out: &Path,
) {
    assert!(stdout.contains(topics), "{label}: {stdout}");
    let paired = format!("{frames} frames, 0 colour and 0 depth images unpaired");
    assert!(stdout.contains(&paired), "{label}: {stdout}");
    let (dx, dt, n) = largest_difference(
        &folder_out.join("trajectory.tum"),
        &bag_out.join("trajectory.tum"),
    );
    println!("{label}: {n} poses, largest difference {dx:.3e} m, {dt:.3e} s");
    assert_eq!(n, frames, "{label}");
    assert!(dx <= 1e-6, "{label}: {dx} m");
    assert!(dt <= 1e-6, "{label}: {dt} s");
}

/// A simulated camera (`slamkit sim`, the office's ground robot for 23 s: a straight, a
/// quarter turn in place, a straight; RGB-D at 10 Hz) written by `rosbags` as an MCAP bag of a
/// RealSense driver's compressed topics: the folder's PNG colour images as
/// `sensor_msgs/CompressedImage`, depth as 32FC1 metres with NaN holes. The bag and the folder
/// give the same trajectory (measured: the same poses, 0 m; the folder run's ATE 0.010 m).
#[test]
fn vo_on_a_simulated_camera_bag_gives_the_folder_trajectory() {
    let test = "vo_on_a_simulated_camera_bag_gives_the_folder_trajectory";
    let Some(sim) = written(test, "sim_office", "mcap/metadata.yaml") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let folder_out = tmp.path().join("folder");
    vo(&sim.join("folder/tum_rgbd_fr1"), &folder_out, &[]);
    let bag_out = tmp.path().join("bag");
    let stdout = vo(&sim.join("mcap"), &bag_out, &[]);
    let topics = "colour /camera/color/image_raw/compressed, depth \
                  /camera/aligned_depth_to_color/image_raw, camera /camera/color/camera_info";
    assert_same_run(
        "simulated camera bag",
        &stdout,
        topics,
        231,
        &folder_out,
        &bag_out,
    );
}

#[test]
fn a_wrong_camera_topic_is_a_clear_error() {
    let test = "a_wrong_camera_topic_is_a_clear_error";
    let Some(bag) = written(test, "redkitchen_db3", "metadata.yaml") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let bag = bag.to_str().unwrap();
    let out = tmp.path().to_str().unwrap();
    let run = slamkit(&[
        "vo",
        bag,
        "--rgb-topic",
        "/camera/depth_registered/image",
        "--out",
        out,
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(
        stderr.contains("holds 32FC1 images, not colour"),
        "{stderr}"
    );
    let run = slamkit(&["vo", bag, "--camera-info-topic", "/nothing", "--out", out]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("no topic /nothing"), "{stderr}");
}
