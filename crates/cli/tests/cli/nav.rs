//! `slamkit nav` end to end: the simulated ground robot, localised by RGB-D visual odometry,
//! drives to the office world's built-in goal and writes every output; goals off the world or
//! inside an obstacle, and bad settings files, exit non-zero with a message that says why.

use crate::recording;

use std::path::Path;
use std::process::{Command, Output};

fn nav(args: &[&str], out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .arg("nav")
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn office_seed_1_reaches_the_built_in_goal() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("nav");
    let mcap = dir.path().join("nav.mcap");
    let record = ["--record", mcap.to_str().unwrap()];
    let result = nav(
        &[&["--world", "office", "--seed", "1"][..], &record].concat(),
        &out,
    );
    assert!(result.status.success(), "{result:?}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["localisation"], "RGB-D visual odometry");
    assert_eq!(report["input"]["goal_m"], serde_json::json!([11.5, 5.0]));
    let m = &report["metrics"];
    assert_eq!(m["reached"], true, "{m}");
    let length = m["path_length_m"].as_f64().unwrap();
    let optimal = m["optimal_length_m"].as_f64().unwrap();
    assert!(length > 0.8 * optimal && length < 1.25 * optimal, "{m}");
    assert!(m["max_cross_track_m"].as_f64().unwrap() <= 0.17, "{m}");
    assert!(m["time_s"].as_f64().unwrap() < 120.0, "{m}");
    for file in [
        "map.png",
        "trajectory.tum",
        "groundtruth.tum",
        "frames.csv",
        "report.html",
    ] {
        assert!(out.join(file).metadata().unwrap().len() > 100, "{file}");
    }
    let tum = std::fs::read_to_string(out.join("trajectory.tum")).unwrap();
    let poses = tum.lines().filter(|l| !l.starts_with('#')).count();
    let frames = &report["frames"];
    assert_eq!(poses, frames["tracked"].as_u64().unwrap() as usize);
    // the recording: every frame's image and true pose, each estimate, the plans, the map
    let recorded = recording::read(&mcap);
    assert_eq!(recorded.counts, recording::reported_counts(&report));
    let c = |topic: &str| recorded.counts.get(topic).copied().unwrap_or(0) as usize;
    let frame_count = frames["frames"].as_u64().unwrap() as usize;
    assert_eq!(
        (c("/camera/image"), c("/groundtruth")),
        (frame_count, frame_count)
    );
    assert_eq!((c("/pose"), c("/tf")), (poses, poses));
    assert!(c("/plan") >= 1 && c("/map") >= 2 && c("/path") == c("/map"));
    assert_eq!(recorded.schemas["/map"], "foxglove.Grid");
    let map = &recorded.last["/map"];
    assert!(map["column_count"].as_u64().unwrap() > 10, "{map}");
    let path = recorded.last["/path"]["poses"].as_array().unwrap().len();
    assert_eq!(path, poses);
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    assert_eq!(
        csv.lines().count(),
        1 + frames["frames"].as_u64().unwrap() as usize
    );
    // the robot's map, saved, is one `slamkit plan` plans on: from its start to the goal
    let first = tum.lines().find(|l| !l.starts_with('#')).unwrap();
    let xy: Vec<&str> = first.split_whitespace().skip(1).take(2).collect();
    let plan = Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .args(["plan", "--map"])
        .arg(out.join("map.skmap"))
        .args(["--start", &xy.join(","), "--goal", "11.5,5.0", "--out"])
        .arg(dir.path().join("plan"))
        .output()
        .unwrap();
    assert!(plan.status.success(), "{plan:?}");
}

#[test]
fn bad_goals_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("40,3", "outside the map"),
        ("0.5,x", "not a number"),
        ("1.5,3.5", "lies in an obstacle"),
    ];
    for (goal, message) in cases {
        let result = nav(&["--world", "small", "--goal", goal], &dir.path().join("o"));
        assert!(!result.status.success(), "{goal}");
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert!(stderr.contains(message), "{goal}: {stderr}");
    }
    let result = nav(&["--world", "nowhere"], &dir.path().join("o"));
    assert!(!result.status.success());
    let config = dir.path().join("bad.toml");
    std::fs::write(&config, "robot_radius_m = -1.0\n").unwrap();
    let config = config.to_str().unwrap();
    let result = nav(
        &["--world", "small", "--config", config],
        &dir.path().join("o"),
    );
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(
        !result.status.success() && stderr.contains("robot_radius_m"),
        "{stderr}"
    );
    std::fs::write(dir.path().join("bad.toml"), "nope = 1\n").unwrap();
    let result = nav(
        &["--world", "small", "--config", config],
        &dir.path().join("o"),
    );
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(
        !result.status.success() && stderr.contains("unknown field `nope`"),
        "{stderr}"
    );
}
