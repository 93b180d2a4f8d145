//! `slamkit fleet robot|merger` as separate processes on loopback (issue 22, items 2 and 4):
//! a merger and two robots, each its own `slamkit` process and Zenoh peer on explicit
//! `tcp/127.0.0.1:PORT` endpoints with multicast scouting off (no packet leaves the machine),
//! playing two overlapping parts of the Intel log at 20× real time. Robot `a` drops 30 % of its
//! publications on purpose and is killed (SIGKILL) mid-run and started again: it resumes from
//! the messages in its store, and the merger fetches by query what it missed. Then the merger
//! is killed and a new one started on the same endpoint: it fetches everything the robots had
//! sent by query. The merged map
//! must equal the offline `slamkit map merge` of the maps the robots' messages build (the same
//! closures, every keyframe within 1e-6). Prints the latencies and bytes for BENCHMARKS.md.
//! Skipped when `SLAMKIT_DATA` is not set; run with `--release`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test helpers fail loudly

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
        args
    };
    let mut a = spawn(&robot_args("a", Some("0.3")), &at("a1.log"));
    let mut b = spawn(&robot_args("b", None), &at("b.log"));

    // robot a killed once it has stored a few messages, then started again on the same store
    let store = at("a").join("updates.skmu");
    wait_for("robot a's first messages", Duration::from_secs(60), || {
        stored(&store) >= 5
    });
    a.kill().unwrap();
    a.wait().unwrap();
    let before = stored(&store);
    let mut a = spawn(&robot_args("a", Some("0.3")), &at("a2.log"));

    // the merger killed too, once robot b has sent a few messages more; a new merger on the
    // same endpoint asks the robots for their status and fetches everything they sent
    let store_b = at("b").join("updates.skmu");
    let b_then = stored(&store_b);
    wait_for("robot b's next messages", Duration::from_secs(60), || {
        stored(&store_b) >= b_then + 3
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
    for robot in [&mut a, &mut b] {
        robot.kill().unwrap();
        robot.wait().unwrap();
    }
    assert!(exit.success(), "{}", outputs(&at("merger2.log")));

    let robot_a = json(&at("a").join("report.json"));
    let robot_b = json(&at("b").join("report.json"));
    assert_eq!(robot_a["fleet"]["resumed_from_message"], before as u64);
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
    eprintln!(
        "fleet on loopback in {:.1} s: robot a resumed from message {before}, {} fetched by \
         query; publish→receipt {}; receipt→merged published {}; {} merges; update bytes per \
         log second a {:.0} / b {:.0} (laser scans {:.0} / {:.0}); closures {} accepted",
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
    );
}
