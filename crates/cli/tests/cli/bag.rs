//! `slamkit lidar` on the Freiburg benchmark's ROS 1 bags (`$SLAMKIT_DATA/lidar2d/{intel,aces}/
//! *.clf.orig.bag`) gives the trajectory it gives on the CARMEN logs derived from them
//! (`*.fromrosbag.clf.gz`, SOURCES.md §2.3), relation by relation within 1e-3 m, once the
//! text's rounding of the bag's float32 numbers is undone; and `slamkit bag info` lists the
//! bags' topics.
//!
//! Why the rounding must be undone: the CARMEN text prints the bag's float32 ranges with 2 or
//! 3 decimals and its float32 beam angles with 6 (`-1.570796 … 0.017453` for
//! `-1.5707963705 … 0.0174532924`); everything else (order, timestamps, odometry) is the same
//! numbers (`slamkit-io`'s `ros1_bags` test checks each difference against its rounding
//! bound). ICP-SLAM is sensitive at that level: on the unmodified text the relations metric
//! moves from 0.0161 to 0.0153 m (Intel) and 0.0399 to 0.0386 m (ACES), single relations up
//! to 0.22 / 0.45 m. With the bag's float32 values written back into the same text (every
//! other field and line kept) the runs agree to 1e-12 m.

use slamkit_io::bag::{read_scan_log, ScanTopics};
use slamkit_io::relations::read_relations;
use slamkit_io::trajectory_file::read_trajectory;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::io::Read as _;
use std::path::Path;
use std::process::Command;

/// Runs the CLI with `args`, which must succeed, and returns what it printed.
pub(crate) fn slamkit(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "slamkit {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// The CARMEN text of `clf_gz` with each RAWLASER1 line's start angle, angular resolution
/// and ranges replaced by the float32 values of the bag's scan of the same rank; all other
/// fields and lines as they are.
fn carmen_with_bag_floats(clf_gz: &Path, bag: &Path) -> String {
    let scans = read_scan_log(bag, &ScanTopics::default())
        .unwrap()
        .log
        .scans;
    let mut text = String::new();
    flate2::read::MultiGzDecoder::new(std::fs::File::open(clf_gz).unwrap())
        .read_to_string(&mut text)
        .unwrap();
    let mut out = String::with_capacity(text.len() * 2);
    let mut k = 0;
    for line in text.lines() {
        if !line.starts_with("RAWLASER1 ") {
            out.push_str(line);
            out.push('\n');
            continue;
        }
        let mut f: Vec<String> = line.split(' ').map(str::to_string).collect();
        let scan = &scans[k];
        let n: usize = f[8].parse().unwrap();
        assert_eq!(n, scan.ranges_m.len());
        // `{}` writes the shortest text that parses back to the same f64.
        f[2] = format!("{}", scan.angle_min_rad);
        f[4] = format!("{}", scan.angle_increment_rad);
        for (i, r) in scan.ranges_m.iter().enumerate() {
            f[9 + i] = format!("{r}");
        }
        writeln!(out, "{}", f.join(" ")).unwrap();
        k += 1;
    }
    assert_eq!(k, scans.len());
    out
}

/// Largest difference between the two trajectories' relative motions over the benchmark's
/// relations \[m\], and the number of relations compared.
pub(crate) fn largest_relation_difference(a: &Path, b: &Path, relations: &Path) -> (f64, usize) {
    let load = |p: &Path| -> HashMap<u64, slamkit_core::Pose3> {
        let (traj, _) = read_trajectory(p).unwrap();
        traj.poses
            .iter()
            .map(|p| (p.timestamp.to_bits(), p.pose))
            .collect()
    };
    let (a, b) = (load(a), load(b));
    let mut worst = 0.0f64;
    let mut n = 0;
    for rel in read_relations(relations).unwrap() {
        let (k1, k2) = (rel.t1.to_bits(), rel.t2.to_bits());
        let (Some(a1), Some(a2), Some(b1), Some(b2)) =
            (a.get(&k1), a.get(&k2), b.get(&k1), b.get(&k2))
        else {
            continue;
        };
        let d = (a1.inverse() * a2).translation.vector - (b1.inverse() * b2).translation.vector;
        worst = worst.max(d.norm());
        n += 1;
    }
    (worst, n)
}

fn same_trajectory_as_carmen(name: &str, relations: usize) {
    let Some(dir) =
        slamkit_testdata::data(&format!("lidar_bag_{name}"), &format!("lidar2d/{name}"))
    else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let bag = dir.join(format!("{name}.clf.orig.bag"));
    let rel = dir.join(format!("{name}.relations"));
    let clf = tmp.path().join(format!("{name}.bagfloats.clf"));
    std::fs::write(
        &clf,
        carmen_with_bag_floats(&dir.join(format!("{name}.fromrosbag.clf.gz")), &bag),
    )
    .unwrap();
    let (out_bag, out_clf) = (tmp.path().join("bag"), tmp.path().join("clf"));
    let stdout = slamkit(&[
        "lidar",
        bag.to_str().unwrap(),
        "--out",
        out_bag.to_str().unwrap(),
    ]);
    assert!(
        stdout.contains("scans on /scan, odometry /odom"),
        "{stdout}"
    );
    slamkit(&[
        "lidar",
        clf.to_str().unwrap(),
        "--relations",
        rel.to_str().unwrap(),
        "--out",
        out_clf.to_str().unwrap(),
    ]);
    let (worst, n) = largest_relation_difference(
        &out_bag.join("trajectory.tum"),
        &out_clf.join("trajectory.tum"),
        &rel,
    );
    println!("{name}: {n} relations, largest difference bag vs CARMEN run {worst:.3e} m");
    assert_eq!(n, relations);
    assert!(worst < 1e-3, "{name}: {worst} m");
    // the report scores the bag run against <stem>.relations beside it
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_bag.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["metrics"]["relations"]["count"], relations);
}

/// Intel's two runs are one of the cli binary's longest tests. Its input is checked equal at
/// the reader (`slamkit-io`'s `ros1_bags`: every scan and odometry against the CARMEN log
/// within the text's rounding) and ACES runs this same path end to end, so CI does not repeat
/// it (it passed at c3bced9, 2026-11-27, in 137 s at load 7: `cargo test --release -p slamkit
/// --test cli bag:: -- --ignored`).
#[test]
#[ignore = "Intel's input is checked at the reader and ACES runs the path; see the doc comment"]
fn intel_bag_run_equals_carmen_run() {
    same_trajectory_as_carmen("intel", 2984);
}

#[test]
fn aces_bag_run_equals_carmen_run() {
    same_trajectory_as_carmen("aces", 1279);
}

#[test]
fn bag_info_lists_topics() {
    let Some(dir) = slamkit_testdata::data("bag_info_aces", "lidar2d/aces") else {
        return;
    };
    let bag = dir.join("aces.clf.orig.bag");
    let info: serde_json::Value =
        serde_json::from_str(&slamkit(&["bag", "info", bag.to_str().unwrap(), "--json"])).unwrap();
    let topics: Vec<(String, u64)> = info["topics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                t["topic"].as_str().unwrap().to_string(),
                t["messages"].as_u64().unwrap(),
            )
        })
        .collect();
    let want = [
        ("/odom", 7375),
        ("/scan", 7374),
        ("/tf", 7375),
        ("/tf_static", 1),
    ];
    assert_eq!(topics, want.map(|(t, n)| (t.to_string(), n)));
    assert_eq!(info["index"]["state"], "indexed");
    // SOURCES.md: ACES scans span 70.29–1435.81 s (the first odometry is at 70.18 s)
    assert!((info["start_s"].as_f64().unwrap() - 70.1797).abs() < 1e-3);
    assert!((info["end_s"].as_f64().unwrap() - 1435.9).abs() < 1e-3);
    let text = slamkit(&["bag", "info", bag.to_str().unwrap()]);
    assert!(
        text.contains("/scan") && text.contains("sensor_msgs/LaserScan"),
        "{text}"
    );
}

/// The bags `slamkit-io`'s tests use (written by PyPI `rosbags`, see
/// `scripts/make_ros1_bag_fixtures.py`).
fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../io/tests/data/ros1")
        .join(name)
}

#[test]
fn bag_errors_are_one_line_and_name_the_choice() {
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_slamkit"))
            .args(args)
            .output()
            .unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let two = fixture("two_lasers.bag");
    let (code, err) = run(&[
        "lidar",
        two.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(1));
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("(/scan, /scan_rear): choose one with --scan-topic"),
        "{err}"
    );
    let text = tmp.path().join("log.clf");
    std::fs::write(&text, "ODOM 0 0 0 0 0 0 1 h 0\n").unwrap();
    let (code, err) = run(&[
        "lidar",
        text.to_str().unwrap(),
        "--scan-topic",
        "/scan",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(1));
    assert!(
        err.contains("--scan-topic and --odom-topic apply to bags"),
        "{err}"
    );
    let (code, err) = run(&["bag", "info", text.to_str().unwrap()]);
    assert_eq!(code, Some(1));
    assert!(err.contains("not a ROS 1 bag"), "{err}");
    let info = slamkit(&["bag", "info", fixture("robot_lz4.bag").to_str().unwrap()]);
    for want in [
        "/scan",
        "20 msgs  sensor_msgs/LaserScan",
        "/tf_static",
        "latched",
        "indexed",
    ] {
        assert!(info.contains(want), "{want}: {info}");
    }
}
