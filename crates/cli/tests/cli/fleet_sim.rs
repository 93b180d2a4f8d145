//! `slamkit fleet sim` (issue 22): two simulated ground robots in the `office` world, each a
//! `slamkit fleet robot` process, and a merger process, all on 127.0.0.1 with multicast
//! scouting off, started and stopped by `fleet sim` itself. Both robots' senders drop 30 % of
//! their publications, the second robot is off the network (its Zenoh session closed) for 30
//! simulated seconds and joins again, robot 0 is killed and restarted mid-run and so is the
//! merger. The merged map must still be the loss-free one (the offline `slamkit map merge` of
//! the maps the robots' messages build, every keyframe within 1e-6), within 0.15 m of the
//! truth on average, with no wrong inter-robot closure accepted. Needs no data; run with
//! `--release`.

use slamkit_slam::lidar::LidarMap;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn a_lossy_fleet_with_a_disconnection_and_crashes_merges_as_a_loss_free_one() {
    let started = Instant::now();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("fleet");
    let run = Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .args([
            "fleet", "sim", "--world", "office", "--robots", "2", "--seed", "1",
        ])
        .args([
            "--loss",
            "0.3",
            "--disconnect",
            "30",
            "--restart",
            "--rate",
            "20",
        ])
        .args(["--merge-every", "1", "--fleet", "ci", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{run:?}");
    let report = json(&out.join("report.json"));
    let metrics = &report["metrics"];
    assert_eq!(metrics["unmerged"], serde_json::json!([]), "{metrics}");
    assert_eq!(metrics["messages_missing_at_merger"], 0, "{metrics}");
    let error = metrics["merged_mean_position_error_m"].as_f64().unwrap();
    assert!(error <= 0.15, "merged map mean position error {error} m");
    assert!(
        metrics["inter_robot_closures_accepted"].as_u64().unwrap() > 0,
        "{metrics}"
    );
    assert_eq!(
        metrics["inter_robot_closures_accepted_wrong"], 0,
        "{metrics}"
    );
    let robots = report["robots"].as_array().unwrap();
    assert!(
        robots[0]["resumed_from_message"].as_u64().unwrap() > 0,
        "{}",
        robots[0]
    );
    assert!(
        robots[1]["messages_held_back_while_disconnected"]
            .as_u64()
            .unwrap()
            > 0
    );
    for robot in robots {
        assert!(
            robot["messages_dropped_on_purpose"].as_u64().unwrap() > 0,
            "{robot}"
        );
    }
    assert_eq!(report["restarts"].as_array().unwrap().len(), 2);

    // the loss-free merge: offline, of the maps the robots' messages build
    let mut offline = Command::new(env!("CARGO_BIN_EXE_slamkit"));
    offline.args(["map", "merge", "--config"]);
    offline.arg(out.join("merge.toml"));
    for name in ["robot_0", "robot_1"] {
        let copy = tmp.path().join(format!("{name}.skmap"));
        std::fs::copy(out.join(name).join("sent.skmap"), &copy).unwrap();
        offline.arg(copy);
    }
    let offline = offline
        .arg("--out")
        .arg(tmp.path().join("offline"))
        .output()
        .unwrap();
    assert!(offline.status.success(), "{offline:?}");
    let (online, _) = LidarMap::load(&out.join("merger").join("map.skmap")).unwrap();
    let (offline, _) = LidarMap::load(&tmp.path().join("offline").join("map.skmap")).unwrap();
    assert_eq!(online.keyframes.len(), offline.keyframes.len());
    for (x, y) in online.keyframes.iter().zip(&offline.keyframes) {
        let d = x.world_from_base.inverse() * y.world_from_base;
        assert!(d.translation.vector.norm() < 1e-6 && d.rotation.angle().abs() < 1e-6);
    }
    eprintln!(
        "fleet sim on loopback in {:.1} s: merged error {error:.3} m; {}",
        started.elapsed().as_secs_f64(),
        metrics
    );
}
