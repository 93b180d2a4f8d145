//! `slamkit demo` end to end: the simulated drone flight, layered ICP-SLAM and particle-filter
//! SLAM, checked against the seed work's mean position errors (issue #5: ICP-SLAM / PF-SLAM
//! small 0.13 / 0.24 m, large 0.29 / 0.33 m, office 0.17 / 0.31 m), and the outputs it
//! promises. Needs no data set; runs only in release builds (a debug build takes many minutes).
//! All three worlds are held here on the default seed; BENCHMARKS.md ("Simulated drone")
//! has every world on more seeds.

use crate::recording;

use std::path::Path;
use std::process::Command;

/// Runs the demo on `world` into a fresh folder, checks the mean errors against the bounds
/// `[icp, pf]` (see [`check_bounds`]) and returns its report, or `None` in debug builds.
fn demo(
    world: &str,
    out: &Path,
    record: Option<&Path>,
    bounds_m: [f64; 2],
) -> Option<serde_json::Value> {
    if cfg!(debug_assertions) {
        eprintln!("skipped: demo {world}: run with --release");
        return None;
    }
    let run = Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .args(["demo", "--world", world, "--out"])
        .arg(out)
        .args(record.iter().flat_map(|r| [Path::new("--record"), r]))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "slamkit demo --world {world}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    // the table of errors
    assert!(stdout.contains("layered ICP-SLAM") && stdout.contains("particle-filter SLAM"));
    let text = std::fs::read_to_string(out.join("report.json")).unwrap();
    let report = serde_json::from_str(&text).unwrap();
    check_bounds(&report, bounds_m[0], bounds_m[1]);
    Some(report)
}

fn metric(report: &serde_json::Value, method: &str, name: &str) -> f64 {
    report["metrics"][method][name]
        .as_f64()
        .unwrap_or_else(|| panic!("metrics.{method}.{name} missing"))
}

/// Mean errors at most the seed's, maxima finite and not below the means.
fn check_bounds(report: &serde_json::Value, icp_mean_m: f64, pf_mean_m: f64) {
    for (method, bound) in [("icp", icp_mean_m), ("pf", pf_mean_m)] {
        let mean = metric(report, method, "position_error_mean_m");
        let max = metric(report, method, "position_error_max_m");
        eprintln!("{method}: mean {mean:.3} m (bound {bound} m), max {max:.3} m");
        assert!(mean <= bound, "{method} mean error {mean} m > {bound} m");
        assert!(max.is_finite() && max >= mean);
    }
}

/// The kidnapped-drone check (`metrics.layer_localisation`): the hypothesis whose particles
/// spread least started in a layer within one of the true layer and ends within one of it
/// (held on seeds 1–5 of `small`, `large` and `office`, BENCHMARKS.md, "Where it stands").
/// Its position is checked only where `max_error_m` is given: in `small` the particles can
/// settle on a quarter-turn image of the pose about the room's central pillar (3.2–3.6 m off
/// in seeds 1, 3, 4, 5), and in `office` on the layer maps' own error (0.73 m in seed 1).
fn check_layer_choice(report: &serde_json::Value, max_error_m: Option<f64>) {
    let found = &report["metrics"]["layer_localisation"];
    let chosen = found["chosen_layer"].as_i64().expect("a chosen layer");
    let truth = found["true_layer"].as_i64().unwrap();
    let chosen_end = found["chosen_layer_end"].as_i64().unwrap();
    let truth_end = found["true_layer_end"].as_i64().unwrap();
    let candidates = found["candidates"].as_array().unwrap().len();
    let error = found["position_error_m"]["end"].as_f64().unwrap();
    eprintln!(
        "layer choice: {chosen} (true {truth}) of {candidates} candidates, at the end \
         {chosen_end} (true {truth_end}), error {error:.3} m"
    );
    assert!(candidates >= 1);
    assert!(
        (chosen - truth).abs() <= 1 && (chosen_end - truth_end).abs() <= 1,
        "chose layer {chosen} (true {truth}), at the end {chosen_end} (true {truth_end})"
    );
    assert!(error.is_finite());
    if let Some(max) = max_error_m {
        assert!(error < max, "position error {error} m");
    }
}

#[test]
fn demo_small_within_the_seed_errors_and_writes_every_output() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("demo.mcap");
    let Some(report) = demo("small", dir.path(), Some(&mcap), [0.13, 0.24]) else {
        return;
    };
    for file in [
        "report.html",
        "trajectory.tum",
        "trajectory_pf.tum",
        "groundtruth.tum",
        "map.pgm",
        "map.yaml",
        "map.png",
        "map_pf.png",
        "cloud.ply",
        "errors_icp.png",
        "errors_pf.png",
    ] {
        let len = std::fs::metadata(dir.path().join(file))
            .map(|m| m.len())
            .unwrap_or(0);
        assert!(len > 0, "{file} missing or empty");
    }
    check_layer_choice(&report, None);
    let layers = report["layers"]["count"].as_u64().unwrap();
    assert!(layers >= 2, "the flight crosses height layers: {layers}");
    let html = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
    // the map of every layer, zoomable, with the truth and each method's trajectory on it (VO's
    // anchored at the camera's start), the error over time, the time per stage, and every
    // other image embedded: one error plot per method (errors_*.png), the particle filter's
    // map, one map per layer
    for part in [
        "<h2>Map</h2>",
        "<svg class=\"zoomable\"",
        "ground truth",
        "trajectory_pf",
        "trajectory_vo",
        "Position error over time",
        "Time per stage",
        "icp.",
        "layer choice by particles: layer ",
    ] {
        assert!(html.contains(part), "report.html lacks {part}");
    }
    let plots = std::fs::read_dir(dir.path())
        .unwrap()
        .filter(|e| {
            let name = e.as_ref().unwrap().file_name();
            let name = name.to_string_lossy();
            name.starts_with("errors_") && name.ends_with(".png")
        })
        .count();
    assert!(plots >= 3, "{plots} error plots");
    let images = html.matches("src=\"data:image/png;base64,").count();
    assert_eq!(images, plots + 1 + layers as usize);

    // the recording: every scan with its poses and truth, the maps as they grew, every camera
    // frame, the paths and the cloud at the end
    let recorded = recording::read(&mcap);
    assert_eq!(recorded.counts, recording::reported_counts(&report));
    let c = |topic: &str| recorded.counts.get(topic).copied().unwrap_or(0);
    let scans = report["frames"]["read"].as_u64().unwrap();
    for topic in ["/scan", "/groundtruth", "/pose", "/tf", "/pose_pf"] {
        assert_eq!(c(topic), scans, "{topic}");
    }
    assert!((2..=10).contains(&c("/map")) && c("/path") == c("/map"));
    let frames = &report["vo"]["frames"];
    assert_eq!(c("/camera/image"), frames["frames"].as_u64().unwrap());
    assert!(c("/camera/pose") > 0 && c("/camera/pose") <= c("/camera/image"));
    assert_eq!((c("/path_pf"), c("/cloud")), (1, 1));
    assert_eq!(recorded.schemas["/cloud"], "foxglove.PointCloud");
}

#[test]
fn demo_large_within_the_seed_errors() {
    let Some(report) = demo(
        "large",
        tempfile::tempdir().unwrap().path(),
        None,
        [0.29, 0.33],
    ) else {
        return;
    };
    // the error includes the layer map's own (layered ICP-SLAM's) error: 0.27 m in seed 1
    check_layer_choice(&report, Some(0.6));
}

#[test]
fn demo_office_within_the_seed_errors() {
    let Some(report) = demo(
        "office",
        tempfile::tempdir().unwrap().path(),
        None,
        [0.17, 0.31],
    ) else {
        return;
    };
    check_layer_choice(&report, None);
}
