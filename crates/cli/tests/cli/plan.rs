//! `slamkit plan` end to end on a generated map: a 6 m × 4 m room at 0.1 m with a wall across
//! it that leaves a gap at the top. Paths are written as CSV and drawn on map.png; unreachable,
//! blocked and out-of-map goals exit non-zero with a message that says why.

use std::path::Path;
use std::process::{Command, Output};

/// Writes `map.pgm` + `map.yaml`: 60 × 40 cells, a border of walls, a wall at column 30 from
/// the bottom up to row `wall_top` (exclusive, counted from the bottom), and the right-most
/// 10 columns unknown when `unknown_right`.
fn write_map(dir: &Path, wall_top: usize, unknown_right: bool) -> std::path::PathBuf {
    let (w, h) = (60usize, 40usize);
    let mut pixels = vec![254u8; w * h];
    for row in 0..h {
        for col in 0..w {
            let y = h - 1 - row;
            let border = col == 0 || row == 0 || col == w - 1 || row == h - 1;
            let wall = col == 30 && y < wall_top;
            if border || wall {
                pixels[row * w + col] = 0;
            } else if unknown_right && col >= 50 {
                pixels[row * w + col] = 205;
            }
        }
    }
    let mut pgm = format!("P5\n{w} {h}\n255\n").into_bytes();
    pgm.extend_from_slice(&pixels);
    std::fs::write(dir.join("map.pgm"), pgm).unwrap();
    let yaml = "image: map.pgm\nresolution: 0.1\norigin: [-1.0, -2.0, 0.0]\nnegate: 0\n\
                occupied_thresh: 0.65\nfree_thresh: 0.196\n";
    let path = dir.join("map.yaml");
    std::fs::write(&path, yaml).unwrap();
    path
}

fn plan(map: &Path, start: &str, goal: &str, planner: &str, out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .args(["plan", "--map"])
        .arg(map)
        .args([
            "--start",
            start,
            "--goal",
            goal,
            "--planner",
            planner,
            "--out",
        ])
        .arg(out)
        .output()
        .unwrap()
}

fn report(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

#[test]
fn plans_through_the_gap_with_both_planners() {
    let dir = tempfile::tempdir().unwrap();
    let map = write_map(dir.path(), 30, false);
    let mut lengths = Vec::new();
    for planner in ["bfs", "astar"] {
        let out = dir.path().join(planner);
        let o = plan(&map, "0.5,-1.5", "3.5,-1.5", planner, &out);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let csv = std::fs::read_to_string(out.join("path.csv")).unwrap();
        let points: Vec<(f64, f64)> = csv
            .lines()
            .skip(1)
            .map(|l| {
                let (x, y) = l.split_once(',').unwrap();
                (x.parse().unwrap(), y.parse().unwrap())
            })
            .collect();
        assert!((points[0].0 - 0.55).abs() < 1e-9 && (points[0].1 + 1.45).abs() < 1e-9);
        // The wall (x in [2, 2.1)) is crossed above its top (y = 1) plus the inflation.
        let crossing = points.iter().filter(|p| (p.0 - 2.05).abs() < 1e-6);
        assert!(crossing.clone().count() >= 1);
        assert!(crossing.clone().all(|p| p.1 > 1.2), "{points:?}");
        let r = report(&out);
        assert_eq!(r["metrics"]["through_unknown"], false);
        let length = r["metrics"]["length_m"].as_f64().unwrap();
        assert!(length > 6.0 && length < 9.0, "{length}");
        lengths.push(length);
        let png = image::open(out.join("map.png")).unwrap().to_rgb8();
        assert_eq!((png.width(), png.height()), (60, 40));
        let red = png.pixels().filter(|p| p.0 == [220, 30, 30]).count();
        assert!(red + 18 >= points.len(), "path drawn: {red} red pixels");
    }
    // A* is shortest in length; BFS only in moves.
    assert!(lengths[1] <= lengths[0] + 1e-9, "{lengths:?}");
}

#[test]
fn unknown_cells_are_used_only_when_needed() {
    let dir = tempfile::tempdir().unwrap();
    let map = write_map(dir.path(), 30, true);
    let out = dir.path().join("out");
    let o = plan(&map, "0.5,-1.5", "4.5,-1.5", "astar", &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(report(&out)["metrics"]["through_unknown"], true);
    let o = plan(&map, "0.5,-1.5", "3.5,-1.5", "astar", &out);
    assert!(o.status.success());
    assert_eq!(report(&out)["metrics"]["through_unknown"], false);
}

#[test]
fn bad_goals_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let closed = write_map(dir.path(), 40, false);
    let out = dir.path().join("out");
    let cases = [
        ("3.5,-1.5", "bfs", "unreachable"),
        ("30,1", "astar", "outside the map"),
        ("2.05,-1.5", "astar", "obstacle"),
        ("nan,1", "astar", "not finite"),
        ("1;2", "astar", "expected X,Y"),
    ];
    for (goal, planner, message) in cases {
        let o = plan(&closed, "0.5,-1.5", goal, planner, &out);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{goal}");
        assert!(stderr.contains(message), "{goal}: {stderr}");
        assert!(!stderr.contains("panicked"), "{goal}: {stderr}");
    }
    let missing = plan(&dir.path().join("none.yaml"), "0,0", "1,1", "bfs", &out);
    assert!(String::from_utf8_lossy(&missing.stderr).contains("none.yaml"));
}
