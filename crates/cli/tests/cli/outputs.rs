//! What every command does with its output folder and arguments (issue 25 items 11, 12 and
//! 13): the folder is checked before the run; outputs are staged and renamed into place, so a
//! failed run leaves the earlier outputs as they were, and files an earlier run wrote that this
//! one does not are removed (the user's own files stay); a path within one cell is 0 m, not
//! "-0.00 m"; help text names fields, not Rust types. Generated data, except where named.

use std::path::Path;
use std::process::{Command, Output};

fn slamkit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .args(args)
        .output()
        .unwrap()
}

fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A ROS map_server map of `cells` × `cells` free cells at `resolution_m`, origin (0, 0).
fn free_map(dir: &Path, cells: usize, resolution_m: f64) -> String {
    let mut pgm = format!("P5\n{cells} {cells}\n255\n").into_bytes();
    pgm.extend(std::iter::repeat(254u8).take(cells * cells));
    std::fs::write(dir.join("map.pgm"), pgm).unwrap();
    let yaml = format!(
        "image: map.pgm\nresolution: {resolution_m}\norigin: [0, 0, 0]\nnegate: 0\n\
         occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    );
    let path = dir.join("map.yaml");
    std::fs::write(&path, yaml).unwrap();
    path.to_str().unwrap().to_string()
}

#[test]
fn an_earlier_runs_files_are_removed_and_the_users_kept() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let out_s = out.to_str().unwrap();
    let sim = |sensors: &str| {
        let run = slamkit(&[
            "sim",
            "--world",
            "small",
            "--sensors",
            sensors,
            "--duration",
            "1",
            "--out",
            out_s,
        ]);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        String::from_utf8_lossy(&run.stderr).into_owned()
    };
    sim("lidar2d,range");
    assert!(out.join("ranges.csv").exists());
    std::fs::write(out.join("notes.txt"), "the user's").unwrap();
    let stderr = sim("lidar2d");
    assert!(
        stderr.contains("removed") && stderr.contains("ranges.csv"),
        "{stderr}"
    );
    assert_eq!(
        names(&out),
        [
            "groundtruth.tum",
            "lidar.clf",
            "lidar.relations",
            "notes.txt",
            "report.json",
            "world.toml"
        ]
    );
}

#[test]
fn a_failed_run_leaves_the_earlier_outputs_as_they_were() {
    let dir = tempfile::tempdir().unwrap();
    let map = free_map(dir.path(), 40, 0.1);
    let out = dir.path().join("plan");
    let out_s = out.to_str().unwrap();
    let plan = |goal: &str| {
        slamkit(&[
            "plan", "--map", &map, "--start", "1,1", "--goal", goal, "--out", out_s,
        ])
    };
    assert!(plan("3,2").status.success());
    let before = std::fs::read(out.join("path.csv")).unwrap();
    let failed = plan("30,2"); // outside the 4 m map
    assert_eq!(failed.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&failed.stderr).contains("outside the map"));
    assert_eq!(std::fs::read(out.join("path.csv")).unwrap(), before);
    assert_eq!(names(&out), ["map.png", "path.csv", "report.json"]);
}

#[test]
fn an_out_that_is_a_file_is_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("taken");
    std::fs::write(&file, "").unwrap();
    let f = file.to_str().unwrap();
    let map = free_map(dir.path(), 10, 0.1);
    let missing = dir.path().join("no-dataset");
    for args in [
        vec!["sim", "--world", "small", "--out", f],
        vec!["nav", "--world", "small", "--out", f],
        vec![
            "plan", "--map", &map, "--start", "0.2,0.2", "--goal", "0.5,0.5", "--out", f,
        ],
        vec![
            "vo",
            missing.to_str().unwrap(),
            "--format",
            "tum",
            "--out",
            f,
        ],
    ] {
        let run = slamkit(&args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains("taken") && stderr.contains("is a file"),
            "{args:?}: {stderr}"
        );
    }
}

/// A 1000 m/cell map: start and goal 400 m apart in one cell. The path is that cell, 0 m long,
/// said as such (the sum of no segments printed "-0.00 m").
#[test]
fn a_path_within_one_cell_is_zero_metres_and_said_so() {
    let dir = tempfile::tempdir().unwrap();
    let map = free_map(dir.path(), 2, 1000.0);
    let out = dir.path().join("plan");
    let run = slamkit(&[
        "plan",
        "--map",
        &map,
        "--start",
        "100,100",
        "--goal",
        "500,400",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(
        stdout.contains("path: 0.00 m") && !stdout.contains("-0.00"),
        "{stdout}"
    );
    assert!(
        stdout.contains("one cell of the map (1000 m a side)"),
        "{stdout}"
    );
}

#[test]
fn help_names_fields_not_rust_types() {
    let commands: [&[&str]; 12] = [
        &["demo"],
        &["vo"],
        &["lidar"],
        &["map", "info"],
        &["map", "export"],
        &["map", "merge"],
        &["eval", "ate"],
        &["eval", "rpe"],
        &["eval", "relations"],
        &["plan"],
        &["sim"],
        &["nav"],
    ];
    for command in commands {
        let run = slamkit(&[command, &["--help"]].concat());
        let help = String::from_utf8_lossy(&run.stdout);
        assert!(
            run.status.success() && help.contains("Usage"),
            "{command:?}"
        );
        for rust in [
            "\\[", "\\]", "Option<", "Vec<", "PathBuf", "f64", "usize", "Config ",
        ] {
            assert!(
                !help.contains(rust),
                "{command:?} help shows `{rust}`:\n{help}"
            );
        }
        let type_name = help
            .split(|c: char| !c.is_alphanumeric())
            .find(|w| w.len() > 6 && w.ends_with("Config") && w.starts_with(char::is_uppercase));
        assert_eq!(
            type_name, None,
            "{command:?} help names a Rust type:\n{help}"
        );
    }
}

/// Five frames of the Redwood test data move the camera a few centimetres: the end-point error
/// is given in metres, not as a percentage of a path too short for one (it printed "26 % of
/// 0.0 m").
#[test]
fn vo_on_a_tiny_path_gives_the_end_point_error_not_a_percentage() {
    let Some(data) = slamkit_testdata::data(
        "vo_on_a_tiny_path_gives_the_end_point_error_not_a_percentage",
        "rgbd/open3d_testdata_redwood_5frames",
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .arg("vo")
        .arg(&data)
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(
        stdout.contains("end-point error") && stdout.contains("too short for a percentage"),
        "{stdout}"
    );
    assert!(!stdout.contains("% of"), "{stdout}");
}

#[test]
fn map_merge_refuses_a_file_that_is_not_a_map_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("robot2.skmap");
    std::fs::write(&bad, "not a map").unwrap();
    let run = slamkit(&[
        "map",
        "merge",
        bad.to_str().unwrap(),
        bad.to_str().unwrap(),
        "--out",
        dir.path().join("out").to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("robot2.skmap") && stderr.contains("not a slamkit map"),
        "{stderr}"
    );
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    // one map is not a merge
    let run = slamkit(&["map", "merge", bad.to_str().unwrap(), "--out", "x"]);
    assert_eq!(run.status.code(), Some(2));
}
