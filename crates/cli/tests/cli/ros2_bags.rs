//! `slamkit lidar` and `slamkit bag info` on ROS 2 bags converted from the Freiburg benchmark's
//! ROS 1 bags by an independent tool (PyPI `rosbags`, `scripts/make_ros2_bags.sh`, which
//! `.ci/run` calls before the tests): an MCAP bag with zstd chunks and an SQLite `.db3` bag
//! of each of Intel and ACES, in `target/ros2-bags/`.
//!
//! What is compared: what `slamkit lidar` reads from the MCAP and `.db3` bags (each scan with
//! its interpolated odometry and the laser's mounting, in order) equals, bit for bit, what it
//! reads from the original ROS 1 bag; and end to end on ACES, `slamkit lidar` on the MCAP bag
//! gives the ROS 1 bag's trajectory, relation by relation within 1e-3 m (Intel's, measured
//! 2026-11-27: 0 m over its 2984 relations; its input is checked equal, so CI does not repeat
//! its two longer runs). `bag.rs` checks the
//! ROS 1 bag's run against the CARMEN log's, so the ROS 2 bags' runs match the CARMEN runs.
//! The bags keep the ROS 1 bag's order (the order its recorder received the messages): Intel's
//! scan stamps step back 631 times, by up to 0.9 s, in that order, and a bag sorted by those
//! stamps (what `rosbags-convert` writes) is another sequence of scans and another run
//! (relations error 0.978 m against 0.016 m, measured 2026-11-27).
//!
//! Skipped only when the converted bags are absent and `SLAMKIT_DATA` is unset; with
//! `SLAMKIT_DATA` set, missing bags are a failure (run the script).

use crate::bag::{largest_relation_difference, slamkit};
use slamkit_io::bag::{read_scan_log, ScanTopics};
use std::path::{Path, PathBuf};

/// The converted bag `target/ros2-bags/<name>`, or `None` (skipped) when it is absent and
/// `SLAMKIT_DATA` is unset.
fn converted(test: &str, name: &str) -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../target/ros2-bags")
        .join(name);
    if dir.join("metadata.yaml").is_file() {
        return Some(dir);
    }
    slamkit_testdata::data(test, "")?;
    panic!(
        "{}: missing although SLAMKIT_DATA is set; run scripts/make_ros2_bags.sh",
        dir.display()
    );
}

/// What `slamkit lidar` reads from `bag`: every scan with its interpolated odometry, in
/// order, and the mounting. Debug prints every f64 so that it reads back to the same bits (NaN
/// included).
fn read(bag: &Path) -> String {
    let log = read_scan_log(bag, &ScanTopics::default()).unwrap();
    format!("{:?} {:?}", log.log.scans, log.mounting)
}

fn ros2_matches_ros1(name: &str, relations: usize, end_to_end: bool) {
    let test = format!("ros2_bag_{name}");
    let (Some(mcap), Some(db3)) = (
        converted(&test, &format!("{name}_mcap")),
        converted(&test, &format!("{name}_db3")),
    ) else {
        return;
    };
    let dir = slamkit_testdata::data(&test, &format!("lidar2d/{name}")).unwrap();
    let ros1 = dir.join(format!("{name}.clf.orig.bag"));
    let want = read(&ros1);
    assert!(
        read(&mcap) == want,
        "{name}: MCAP log differs from the ROS 1 bag's"
    );
    assert!(
        read(&db3) == want,
        "{name}: .db3 log differs from the ROS 1 bag's"
    );
    // end to end through the CLI: the same input gives the same trajectory
    if !end_to_end {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let mut outs = Vec::new();
    for (label, bag) in [("ros1", &ros1), ("mcap", &mcap)] {
        let out = tmp.path().join(label);
        let stdout = slamkit(&[
            "lidar",
            bag.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(
            stdout.contains("scans on /scan, odometry /odom"),
            "{stdout}"
        );
        outs.push(out.join("trajectory.tum"));
    }
    let rel = dir.join(format!("{name}.relations"));
    let (worst, n) = largest_relation_difference(&outs[0], &outs[1], &rel);
    println!("{name}: MCAP run vs the ROS 1 bag's: {worst:.3e} m over {n} relations");
    assert_eq!(n, relations);
    assert!(worst < 1e-3, "{name}: MCAP run differs by {worst} m");
}

#[test]
fn intel_ros2_bags_match_the_ros1_bag() {
    ros2_matches_ros1("intel", 2984, false);
}

#[test]
fn aces_ros2_bags_match_the_ros1_bag() {
    ros2_matches_ros1("aces", 1279, true);
}

#[test]
fn bag_info_on_ros2_bags() {
    let Some(mcap) = converted("ros2_bag_info", "aces_mcap") else {
        return;
    };
    for bag in [mcap.clone(), mcap.with_file_name("aces_db3")] {
        let info: serde_json::Value =
            serde_json::from_str(&slamkit(&["bag", "info", bag.to_str().unwrap(), "--json"]))
                .unwrap();
        let topics: Vec<(String, String, u64)> = info["topics"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| {
                (
                    t["topic"].as_str().unwrap().to_string(),
                    t["message_type"].as_str().unwrap().to_string(),
                    t["messages"].as_u64().unwrap(),
                )
            })
            .collect();
        // the ROS 1 bag's counts (cli/tests/cli/bag.rs), types in ROS 2 spelling
        let want = [
            ("/odom", "nav_msgs/msg/Odometry", 7375),
            ("/scan", "sensor_msgs/msg/LaserScan", 7374),
            ("/tf", "tf2_msgs/msg/TFMessage", 7375),
            ("/tf_static", "tf2_msgs/msg/TFMessage", 1),
        ];
        assert_eq!(
            topics,
            want.map(|(t, ty, n)| (t.to_string(), ty.to_string(), n))
        );
        assert!((info["start_s"].as_f64().unwrap() - 70.1797).abs() < 1e-3);
        assert!((info["end_s"].as_f64().unwrap() - 1435.9).abs() < 1e-3);
    }
}
