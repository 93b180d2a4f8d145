//! `slamkit fleet robot|merger` as separate processes on loopback (issue 22, items 2 and 4):
//! a merger and two robots, each its own `slamkit` process and Zenoh peer on explicit
//! `tcp/127.0.0.1:PORT` endpoints with multicast scouting off (no packet leaves the machine),
//! playing two overlapping parts of the Intel log at 20× real time. Robot `a` drops 30 % of its
//! publications on purpose and is killed (SIGKILL) mid-run and started again: it resumes from
//! the messages in its store, and the merger fetches by query what it missed. Then the merger
//! is killed and a new one started on the same endpoint: it fetches everything the robots had
//! sent by query. The merged map
//! must equal the offline `slamkit map merge` of the maps the robots' messages build (the same
//! closures, every keyframe within 1e-6). Every merged map goes back to the robots: each ends
//! with the merger's last map file byte for byte (the restarted robot `a` fetched one by
//! query), and in a robot's copy `slamkit lidar --localize` finds a stretch of robot `b`'s log
//! from an unknown start on `b`'s merged trajectory, and `slamkit plan` finds a path from
//! where `a` started to where `b` ended. Prints the latencies and bytes for BENCHMARKS.md.
//! Skipped when `SLAMKIT_DATA` is not set; run with `--release`.

use slamkit_slam::lidar::LidarMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Starts `slamkit ARGS`, its output in `<log>.out` and `<log>.err`.
fn spawn(args: &[String], log: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(log.with_extension("out")).unwrap())
        .stderr(std::fs::File::create(log.with_extension("err")).unwrap())
        .spawn()
        .unwrap()
}

fn outputs(log: &Path) -> String {
    let read = |ext| std::fs::read_to_string(log.with_extension(ext)).unwrap_or_default();
    format!("{}: {}{}", log.display(), read("out"), read("err"))
}

/// Scans `from..to` of a CARMEN log's lines as a log of its own: the header, the last
/// odometry line before its first scan (so that scan has odometry), then its lines.
fn cut(lines: &[String], from: usize, to: usize, path: &Path) {
    let scans: Vec<usize> = (0..lines.len())
        .filter(|&i| {
            ["RAWLASER1", "FLASER", "ROBOTLASER1"]
                .iter()
                .any(|t| lines[i].starts_with(t))
        })
        .collect();
    let (start, end) = (scans[from], scans.get(to).copied().unwrap_or(lines.len()));
    let head = lines.iter().filter(|l| l.starts_with('#'));
    let odom = lines[..start].iter().rfind(|l| l.starts_with("ODOM"));
    let body = lines[start..end].iter().filter(|l| !l.starts_with('#'));
    let mut text = String::new();
    for line in head.chain(odom).chain(body) {
        text.push_str(line);
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

/// Messages in a robot's store file (whole records).
fn stored(path: &Path) -> usize {
    let bytes = std::fs::read(path).unwrap_or_default();
    let (mut at, mut n) = (0, 0);
    while let Some(len) = bytes.get(at..at + 4) {
        at += 4 + u32::from_le_bytes(len.try_into().unwrap()) as usize;
        n += usize::from(at <= bytes.len());
    }
    n
}

fn wait_for(what: &str, timeout: Duration, mut done: impl FnMut() -> bool) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < timeout, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The rows of a TUM trajectory file: time, x, y, z, qx, qy, qz, qw.
fn tum(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect()
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The closures of a merge report: keyframes joined and what became of each.
fn closures(report: &serde_json::Value) -> Vec<String> {
    report["closures"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            format!(
                "{}:{} {}:{} {}",
                c["from"], c["from_keyframe"], c["to"], c["to_keyframe"], c["status"]
            )
        })
        .collect()
}

#[test]
fn robot_and_merger_processes_killed_and_restarted_merge_as_offline() {
    let Some(dir) = slamkit_testdata::data(
        "robot_and_merger_processes_killed_and_restarted_merge_as_offline",
        "lidar2d/intel",
    ) else {
        return;
    };
    let started = Instant::now();
    let mut text = String::new();
    flate2::read::GzDecoder::new(std::fs::File::open(dir.join("intel.fromrosbag.clf.gz")).unwrap())
        .read_to_string(&mut text)
        .unwrap();
    let lines: Vec<String> = text.lines().map(str::to_string).collect();
    let tmp = tempfile::tempdir().unwrap();
    let at = |name: &str| -> PathBuf { tmp.path().join(name) };
    let s = |p: PathBuf| p.to_str().unwrap().to_string();
    cut(&lines, 0, 1200, &at("a.clf"));
    cut(&lines, 800, 2000, &at("b.clf"));

    let port = slamkit_testdata::free_loopback_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let merger_args: Vec<String> = ["fleet", "merger", "--fleet", "intel", "--listen", &endpoint]
        .iter()
        .map(|a| a.to_string())
        .chain([
            "--merge-every".into(),
            "3".into(),
            "--out".into(),
            s(at("merged")),
        ])
        .collect();
    let mut merger = spawn(&merger_args, &at("merger.log"));
    wait_for("the merger's endpoint", Duration::from_secs(20), || {
        std::net::TcpStream::connect(("127.0.0.1", port)).is_ok()
    });
    let robot_args = |name: &str, loss: Option<&str>| -> Vec<String> {
        let mut args: Vec<String> = ["fleet", "robot", &s(at(&format!("{name}.clf")))]
            .iter()
            .map(|a| a.to_string())
            .collect();
        for (flag, value) in [
            ("--fleet", "intel".to_string()),
            ("--robot", name.to_string()),
            ("--connect", endpoint.clone()),
            ("--rate", "20".to_string()),
            ("--out", s(at(name))),
        ] {
            args.extend([flag.to_string(), value]);
        }
        if let Some(loss) = loss {
            args.extend(["--loss".to_string(), loss.to_string()]);
        }
        if name == "b" {
            args.extend(["--config".to_string(), s(at("b.toml"))]);
        }
        args
    };
    // robot b's ICP-SLAM settings from a file, as slamkit lidar takes them (a value no Intel
    // scan comes near: the run is the default one's)
    std::fs::write(at("b.toml"), "min_scan_points = 21\n").unwrap();
    let mut a = spawn(&robot_args("a", Some("0.3")), &at("a1.log"));
    let mut b = spawn(&robot_args("b", None), &at("b.log"));

    // robot a killed once it has stored a few messages and holds a merged map, then started
    // again on the same store: the new process gets the merged map again
    let store = at("a").join("updates.skmu");
    let merged_a = at("a").join("merged.skmap");
    wait_for("robot a's first messages", Duration::from_secs(60), || {
        stored(&store) >= 5 && merged_a.exists()
    });
    a.kill().unwrap();
    a.wait().unwrap();
    let before = stored(&store);
    std::fs::remove_file(&merged_a).unwrap();
    let mut a = spawn(&robot_args("a", Some("0.3")), &at("a2.log"));

    // the merger killed too, once robot b has sent a few messages more; a new merger on the
    // same endpoint asks the robots for their status and fetches everything they sent
    let store_b = at("b").join("updates.skmu");
    let b_then = stored(&store_b);
    wait_for("robot b's next messages", Duration::from_secs(60), || {
        stored(&store_b) >= b_then + 3 && merged_a.exists()
    });
    merger.kill().unwrap();
    merger.wait().unwrap();
    std::thread::sleep(Duration::from_secs(2));
    let mut merger = spawn(&merger_args, &at("merger2.log"));
    for (name, log) in [("a", "a2.log"), ("b", "b.log")] {
        let report = at(name).join("report.json");
        wait_for(&outputs(&at(log)), Duration::from_secs(120), || {
            report.exists()
        });
    }
    let status = Command::new("kill")
        .args(["-INT", &merger.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let merged_at = Instant::now();
    let exit = loop {
        if let Some(exit) = merger.try_wait().unwrap() {
            break exit;
        }
        assert!(
            merged_at.elapsed() < Duration::from_secs(60),
            "merger never stopped"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    assert!(exit.success(), "{}", outputs(&at("merger2.log")));

    // the merger's last map reaches both robots; stopped, they write their reports again
    let merged_map = std::fs::read(at("merged").join("map.skmap")).unwrap();
    for name in ["a", "b"] {
        let copy = at(name).join("merged.skmap");
        wait_for(
            &format!("robot {name}'s merged map"),
            Duration::from_secs(20),
            || std::fs::read(&copy).is_ok_and(|bytes| bytes == merged_map),
        );
    }
    for robot in [&mut a, &mut b] {
        let status = Command::new("kill")
            .args(["-INT", &robot.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
        assert!(robot.wait().unwrap().success());
    }

    let robot_a = json(&at("a").join("report.json"));
    let robot_b = json(&at("b").join("report.json"));
    assert_eq!(robot_a["fleet"]["resumed_from_message"], before as u64);
    assert_eq!(robot_a["config"]["icp"]["min_scan_points"], 20);
    assert_eq!(robot_b["config"]["icp"]["min_scan_points"], 21);
    for robot in [&robot_a, &robot_b] {
        let received = &robot["fleet"]["merged_map"];
        assert!(received["kept"].as_u64().unwrap() >= 1, "{received}");
        assert_eq!(received["rejected"], 0, "{received}");
    }
    assert!(
        robot_a["fleet"]["merged_map"]["fetched"].as_u64().unwrap() >= 1,
        "{}",
        robot_a["fleet"]["merged_map"]
    );
    let report = json(&at("merged").join("report.json"));
    let fleet = &report["fleet"];
    assert_eq!(fleet["missing"], 0);
    assert_eq!(fleet["rejected"], 0);
    assert!(
        fleet["robots"]["a"]["fetched"].as_u64().unwrap() > 0,
        "{fleet}"
    );

    // the offline merge of the maps the robots' messages build
    for name in ["a", "b"] {
        std::fs::copy(at(name).join("sent.skmap"), at(&format!("{name}.skmap"))).unwrap();
    }
    let offline = Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .args([
            "map",
            "merge",
            &s(at("a.skmap")),
            &s(at("b.skmap")),
            "--out",
        ])
        .arg(at("offline"))
        .output()
        .unwrap();
    assert!(offline.status.success(), "{offline:?}");
    let offline_report = json(&at("offline").join("report.json"));
    assert_eq!(closures(&report), closures(&offline_report));
    assert!(report["closures_accepted"].as_u64().unwrap() > 0);
    assert_eq!(report["unmerged"], serde_json::json!([]));
    let (online, _) = LidarMap::load(&at("merged").join("map.skmap")).unwrap();
    let (offline, _) = LidarMap::load(&at("offline").join("map.skmap")).unwrap();
    assert_eq!(online.keyframes.len(), offline.keyframes.len());
    assert_eq!(online.edges.len(), offline.edges.len());
    for (x, y) in online.keyframes.iter().zip(&offline.keyframes) {
        let d = x.world_from_base.inverse() * y.world_from_base;
        assert!(d.translation.vector.norm() < 1e-6 && d.rotation.angle().abs() < 1e-6);
    }
    // robot b's scans 1500-1599, found in robot a's copy of the merged map from an unknown
    // start, on b's keyframes in the merged frame
    cut(&lines, 1500, 1600, &at("late.clf"));
    let localised = Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .args(["lidar", &s(at("late.clf")), "--localize"])
        .arg(at("a").join("merged.skmap"))
        .arg("--out")
        .arg(at("localised"))
        .output()
        .unwrap();
    assert!(localised.status.success(), "{localised:?}");
    let merged_b = tum(&at("merged").join("trajectory_b.tum"));
    let found = tum(&at("localised").join("trajectory.tum"));
    let mut errors: Vec<f64> = found
        .iter()
        .filter_map(|p| {
            let q = merged_b.iter().find(|q| (q[0] - p[0]).abs() < 1e-4)?;
            Some((p[1] - q[1]).hypot(p[2] - q[2]))
        })
        .collect();
    errors.sort_by(f64::total_cmp);
    // the merged trajectories hold the keyframes' poses (what the robots' messages carry)
    assert!(errors.len() >= 10, "{} poses matched", errors.len());
    let localised_median = errors[errors.len() / 2];
    assert!(localised_median < 0.1, "median {localised_median} m");

    // a path across both robots' parts on robot b's copy of the grid
    let start = tum(&at("merged").join("trajectory_a.tum"))[0].clone();
    let goal = merged_b.last().unwrap().clone();
    let plan = Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .arg("plan")
        .arg("--map")
        .arg(at("b").join("merged.skmap"))
        .args([
            "--start",
            &format!("{},{}", start[1], start[2]),
            "--goal",
            &format!("{},{}", goal[1], goal[2]),
            "--out",
            &s(at("plan")),
        ])
        .output()
        .unwrap();
    assert!(plan.status.success(), "{plan:?}");
    let planned = json(&at("plan").join("report.json"));
    assert_eq!(planned["metrics"]["through_unknown"], false, "{planned}");

    eprintln!(
        "fleet on loopback in {:.1} s: robot a resumed from message {before}, {} fetched by \
         query; publish→receipt {}; receipt→merged published {}; {} merges; update bytes per \
         log second a {:.0} / b {:.0} (laser scans {:.0} / {:.0}); closures {} accepted; \
         merged maps taken by a {} / b {}; localised in a's copy: median {localised_median:.3} m \
         over {} keyframes; path {} m",
        started.elapsed().as_secs_f64(),
        fleet["robots"]["a"]["fetched"],
        fleet["publish_to_receipt_ms"],
        fleet["receipt_to_merged_ms"],
        fleet["merges"],
        robot_a["fleet"]["update_bytes_per_log_second"]
            .as_f64()
            .unwrap(),
        robot_b["fleet"]["update_bytes_per_log_second"]
            .as_f64()
            .unwrap(),
        robot_a["fleet"]["laser_scan_bytes_per_log_second"]
            .as_f64()
            .unwrap(),
        robot_b["fleet"]["laser_scan_bytes_per_log_second"]
            .as_f64()
            .unwrap(),
        report["closures_accepted"],
        robot_a["fleet"]["merged_map"],
        robot_b["fleet"]["merged_map"],
        errors.len(),
        planned["metrics"]["length_m"],
    );
}

/// `fleet robot --profile/--config` are `slamkit lidar`'s: the same settings code, so the same
/// one-line errors, before any log is read or peer opened.
#[test]
fn a_robot_takes_its_settings_as_slamkit_lidar_does() {
    let tmp = tempfile::tempdir().unwrap();
    let config = tmp.path().join("bad.toml");
    std::fs::write(&config, "nope = 1\n").unwrap();
    let config = config.to_str().unwrap();
    let log = tmp.path().join("never-read.clf");
    let log = log.to_str().unwrap();
    let stderr = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_slamkit"))
            .args(args)
            .output()
            .unwrap();
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    for settings in [["--config", config], ["--profile", "no-such-robot"]] {
        let robot = stderr(&[&["fleet", "robot", log, "--robot", "r1"], &settings[..]].concat());
        let lidar = stderr(&[&["lidar", log], &settings[..]].concat());
        assert_eq!(robot, lidar);
        assert_eq!(robot.lines().count(), 1, "{robot}");
    }
}
