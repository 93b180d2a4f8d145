//! RGB-D visual odometry on a simulated TUM RGB-D sequence (issue #5: "RGB-D visual odometry on
//! a simulated 60 s TUM-format sequence in `office`: ATE RMSE ≤ 0.02 m"), end to end through the
//! command line: `slamkit sim` writes the folder, `slamkit vo` reads it like any TUM sequence
//! and saves its map (`--save-map`).
//!
//! The camera rides the ground robot along the office's drive path at 0.25 m/s (the speed of
//! issue #6's closed loop), 0.3 m above the floor, looking ahead; it runs at 15 Hz instead of
//! the default 30 Hz to keep the test under a minute (30 Hz gives a similar error: see
//! BENCHMARKS.md, "Simulated cameras"). Needs no data set; runs only in release builds.

use std::path::Path;
use std::process::Command;

fn slamkit(args: &[&str], out: &Path) {
    let run = Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "slamkit {args:?}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
}

#[test]
fn rgbd_vo_on_a_simulated_60_s_office_sequence_is_within_2_cm() {
    if cfg!(debug_assertions) {
        eprintln!("skipped: rgbd_vo_on_a_simulated_60_s_office_sequence: run with --release");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("sim.toml");
    std::fs::write(
        &config,
        "[rgbd]\nrate_hz = 15.0\n[diff_drive]\nspeed_mps = 0.25\n",
    )
    .unwrap();
    let sim_out = dir.path().join("sim");
    let config = config.to_str().unwrap();
    slamkit(
        &[
            "sim",
            "--world",
            "office",
            "--robot",
            "diff-drive",
            "--sensors",
            "rgbd",
            "--duration",
            "60",
            "--seed",
            "1",
            "--config",
            config,
        ],
        &sim_out,
    );
    let sequence = sim_out.join("tum_rgbd_fr1");
    let vo_out = dir.path().join("vo");
    let map = dir.path().join("office.skmap");
    slamkit(
        &[
            "vo",
            sequence.to_str().unwrap(),
            "--save-map",
            map.to_str().unwrap(),
        ],
        &vo_out,
    );

    let text = std::fs::read_to_string(vo_out.join("report.json")).unwrap();
    let report: serde_json::Value = serde_json::from_str(&text).unwrap();
    let frames = &report["frames"];
    assert_eq!(frames["frames"], 900, "{frames}"); // 60 s at 15 Hz
    assert!(frames["failed"].as_u64().unwrap() <= 9, "{frames}");
    let metrics = &report["metrics"];
    let ate = metrics["ate"]["rmse"].as_f64().unwrap();
    let length = metrics["path_length_m"].as_f64().unwrap();
    eprintln!("ATE RMSE {ate:.4} m over {length:.1} m");
    // the robot really travelled: drive path with turns, about 11 m in 60 s
    assert!(length > 10.0, "path {length} m");
    assert!(ate <= 0.02, "ATE RMSE {ate} m > 0.02 m");
    // report.html: the truth and the aligned estimate from above, the error over time
    let page = std::fs::read_to_string(vo_out.join("report.html")).unwrap();
    for part in [
        "Trajectory from above",
        "Position error over time",
        "Time per stage",
    ] {
        assert!(page.contains(part), "report.html lacks {part}");
    }
    // the map file holds the session's keyframes, each with its points
    let file = slamkit_slam::map_file::MapFile::load(&map).unwrap();
    let keyframes = report["map"]["keyframes"].as_u64().unwrap() as usize;
    assert!(keyframes > 100, "{keyframes} keyframes");
    assert_eq!(file.header.keyframes, keyframes);
    assert_eq!(file.header.rig, slamkit_slam::map_file::Rig::Rgbd);
    let visual =
        slamkit_slam::visual::VisualMap::from_map_file(&file, slamkit_slam::map_file::Rig::Rgbd)
            .unwrap();
    assert!(visual.keyframes.iter().all(|k| !k.points.is_empty()));
}

/// Settings of the simulated office laps of issue 20 (`slamkit sim --path loop3`): the camera at
/// 10 Hz (the lowest rate the issue allows; the TUM reader's 640×480 Freiburg 1 camera, with the
/// sensor noise model), the ground robot at its default 0.2 m/s.
const LAPS_CONFIG: &str = "[rgbd]\nrate_hz = 10.0\n";

/// Simulates `slamkit sim --world office --robot diff-drive --path loop3` with `seed` into
/// `dir`; returns the TUM RGB-D folder.
fn office_laps(dir: &Path, seed: u64) -> std::path::PathBuf {
    let config = dir.join("laps.toml");
    std::fs::write(&config, LAPS_CONFIG).unwrap();
    let seed = seed.to_string();
    let config = config.to_str().unwrap();
    #[rustfmt::skip]
    let args = [
        "sim", "--world", "office", "--robot", "diff-drive", "--path", "loop3", "--sensors",
        "rgbd", "--seed", &seed, "--config", config,
    ];
    let out = dir.join("sim");
    slamkit(&args, &out);
    out.join("tum_rgbd_fr1")
}

/// `slamkit vo SEQUENCE [--slam] [--save-map MAP]` into `out`; returns its report.
fn vo(sequence: &Path, slam: bool, map: Option<&Path>, out: &Path) -> serde_json::Value {
    let mut args = vec!["vo", sequence.to_str().unwrap()];
    if slam {
        args.push("--slam");
    }
    if let Some(map) = map {
        args.extend(["--save-map", map.to_str().unwrap()]);
    }
    slamkit(&args, out);
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

/// Loops closed and wrong closures of a `--slam` report.
fn closures(report: &serde_json::Value) -> (u64, u64) {
    let loops = &report["loop_closure"];
    let accepted = loops["stats"]["accepted"].as_u64().unwrap();
    let wrong = loops["against_ground_truth"]["wrong"].as_u64().unwrap();
    (accepted, wrong)
}

fn ate(report: &serde_json::Value) -> f64 {
    report["metrics"]["ate"]["rmse"].as_f64().unwrap()
}

/// Issue 20's measure on the simulated 3-loop office sequence, seeds 1–5 (BENCHMARKS.md,
/// "Visual SLAM"): each run closes a loop, accepts no wrong closure and has an ATE at least 3×
/// lower than visual odometry's; prints keyframes, map file size and peak memory.
#[test]
#[ignore = "5 seeds × 277 s at 10 Hz, 640×480: cargo test --release -p slamkit --test cli vo_sim:: -- --ignored --nocapture"]
fn three_office_laps_seeds_1_to_5_close_loops_and_cut_the_error_three_times() {
    for seed in 1..=5 {
        let dir = tempfile::tempdir().unwrap();
        let sequence = office_laps(dir.path(), seed);
        let odometry = vo(&sequence, false, None, &dir.path().join("vo"));
        let map = dir.path().join("laps.skmap");
        let slam = vo(&sequence, true, Some(&map), &dir.path().join("slam"));
        let (accepted, wrong) = closures(&slam);
        let keyframes = slam["map"]["keyframes"].as_u64().unwrap();
        let map_bytes = map.metadata().unwrap().len() as f64;
        let rss = slam["peak_rss_bytes"].as_f64().unwrap();
        let stats = &slam["loop_closure"]["stats"];
        eprintln!(
            "seed {seed}: ATE {:.4} -> {:.4} m, closures {accepted} (wrong {wrong}), \
             localisations {}, keyframes {keyframes}, map file {:.3} MiB ({:.1} KiB per keyframe), \
             peak RSS {:.0} MiB, frames {}",
            ate(&odometry),
            ate(&slam),
            stats["localised"],
            map_bytes / 1048576.0,
            map_bytes / 1024.0 / keyframes as f64,
            rss / 1048576.0,
            slam["frames"]["frames"],
        );
        assert!(
            accepted >= 1 && wrong == 0,
            "seed {seed}: {}",
            slam["loop_closure"]
        );
        assert!(3.0 * ate(&slam) <= ate(&odometry), "seed {seed}");
    }
}
