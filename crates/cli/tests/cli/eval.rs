//! `slamkit eval` end to end on real data, against published reference values:
//!
//! * evo 1.38 on its own test data (github.com/MichaelGrupp/evo, `test/data`):
//!   `evo_ape tum freiburg1_xyz-groundtruth.txt freiburg1_xyz-rgbdslam.txt -a --t_max_diff 0.02`
//!   gives RMSE 0.013473 m over 786 pairs, `evo_rpe ... --delta 1 --delta_unit f` 0.005759 m.
//! * The relations metric of MRPT's runs on the Intel and ACES benchmark logs, from
//!   `trajectories/mrpt/README.md` (an independent implementation of Kümmerle et al. 2009).
//!
//! Skipped when `SLAMKIT_DATA` is not set.

use slamkit_testdata::data;
use std::process::Command;

fn eval_json(args: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_slamkit"))
        .arg("eval")
        .args(args)
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "slamkit eval {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "one JSON object: {text}");
    serde_json::from_str(&text).unwrap()
}

fn assert_near(json: &serde_json::Value, key: &str, expected: f64, tol: f64) {
    let got = json[key].as_f64().unwrap_or(f64::NAN);
    assert!(
        (got - expected).abs() <= tol,
        "{key}: got {got}, expected {expected} ± {tol}"
    );
}

/// The paths of two files of evo's test data, or `None` (test skipped) without the data.
fn evo_files(test: &str, gt: &str, est: &str) -> Option<(String, String)> {
    let dir = data(test, "trajectories/evo_test_data")?;
    let path = |name: &str| dir.join(name).to_str().unwrap().to_string();
    Some((path(gt), path(est)))
}

#[test]
fn ate_and_rpe_match_evo_on_fr1_xyz() {
    let Some((gt, est)) = evo_files(
        "ate_and_rpe_match_evo_on_fr1_xyz",
        "freiburg1_xyz-groundtruth.txt",
        "freiburg1_xyz-rgbdslam.txt",
    ) else {
        return;
    };
    let (gt, est) = (gt.as_str(), est.as_str());
    let ate = eval_json(&["ate", "--gt", gt, "--est", est, "--align", "se3"]);
    assert_near(&ate, "rmse", 0.013473, 5e-7);
    assert_eq!(ate["pairs"], 786);
    for key in ["mean", "median", "std", "min", "max"] {
        assert!(ate[key].is_f64(), "missing {key}");
    }
    let rpe = eval_json(&[
        "rpe", "--gt", gt, "--est", est, "--delta", "1", "--unit", "frames",
    ]);
    assert_near(&rpe, "rmse", 0.005759, 5e-7);
    assert_eq!(rpe["pairs"], 785);

    let out = tempfile::tempdir().unwrap();
    for metric in ["ate", "rpe"] {
        let plot = out.path().join(format!("{metric}.svg"));
        let plot = plot.to_str().unwrap();
        eval_json(&[metric, "--gt", gt, "--est", est, "--plot", plot]);
        assert!(std::fs::metadata(plot).unwrap().len() > 1000, "{metric}");
    }
}

#[test]
fn kitti_pairs_by_index_like_evo() {
    // evo_ape kitti KITTI_00_gt.txt KITTI_00_ORB.txt -a (evo 1.38): RMSE 1.303449715 m
    let Some((gt, est)) = evo_files(
        "kitti_pairs_by_index_like_evo",
        "KITTI_00_gt.txt",
        "KITTI_00_ORB.txt",
    ) else {
        return;
    };
    let ate = eval_json(&["ate", "--gt", &gt, "--est", &est]);
    assert_near(&ate, "rmse", 1.303449715, 1e-8);
    assert_eq!(ate["pairs"], 4541);
}

#[test]
fn relations_metric_matches_mrpt_reference_values() {
    let Some(data) = data("relations_metric_matches_mrpt_reference_values", "") else {
        return;
    };
    // (relations, estimate, trans mean, trans std, rot mean, rot std, count) from the README
    let cases = [
        (
            "lidar2d/intel/intel.relations",
            "trajectories/mrpt/mrpt_intel_icpLM.tum",
            [0.0581078, 0.0666092, 1.0989798, 1.1127591],
            2984,
        ),
        (
            "lidar2d/aces/aces.relations",
            "trajectories/mrpt/mrpt_aces_rbpfICP.tum",
            [0.1719986, 0.6174905, 0.9287865, 1.2432707],
            1279,
        ),
    ];
    for (relations, est, [tm, ts, rm, rs], count) in cases {
        let rel = data.join(relations);
        let est = data.join(est);
        let json = eval_json(&[
            "relations",
            "--relations",
            rel.to_str().unwrap(),
            "--est",
            est.to_str().unwrap(),
        ]);
        assert_near(&json, "trans_mean", tm, 5e-8);
        assert_near(&json, "trans_std", ts, 5e-8);
        assert_near(&json, "rot_mean_deg", rm, 5e-8);
        assert_near(&json, "rot_std_deg", rs, 5e-8);
        assert_eq!(json["count"], count, "{relations}");
        assert_eq!(json["missing"], 0, "{relations}");
    }
}

#[test]
fn bad_input_fails_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let garbage = dir.path().join("garbage.txt");
    std::fs::write(&garbage, "not a trajectory\n").unwrap();
    let g = garbage.to_str().unwrap();
    for args in [
        vec!["ate", "--gt", g, "--est", g],
        vec!["ate", "--gt", "/nonexistent.tum", "--est", g],
        vec!["rpe", "--gt", g, "--est", g, "--unit", "parsecs"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_slamkit"))
            .arg("eval")
            .args(&args)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(!out.stderr.is_empty(), "{args:?} should say why");
    }
}

/// Issue 25 (13): each error is one line that names the file once, without Rust debug
/// output, and a value out of range says the valid range (negative values included, which
/// the argument parser used to take for options).
#[test]
fn error_messages_are_one_line_naming_the_file_once() {
    let dir = tempfile::tempdir().unwrap();
    let gt = dir.path().join("gt.tum");
    let poses: String = (0..10)
        .map(|i| format!("{i}.0 {i}.0 0 0 0 0 0 1\n"))
        .collect();
    std::fs::write(&gt, poses).unwrap();
    let g = gt.to_str().unwrap();
    let missing = dir.path().join("missing.tum");
    let m = missing.to_str().unwrap();
    let relations = dir.path().join("missing.relations");
    let r = relations.to_str().unwrap();
    for (args, expected) in [
        (
            vec!["ate", "--gt", m, "--est", g],
            format!("error: reading trajectory: {m}: "),
        ),
        (
            vec!["relations", "--relations", r, "--est", g],
            format!("error: reading relations: {r}: "),
        ),
        (
            vec!["rpe", "--gt", g, "--est", g, "--max-diff", "-1"],
            "error: --max-diff must be a non-negative number of seconds, got -1".to_string(),
        ),
        (
            vec!["rpe", "--gt", g, "--est", g, "--delta", "-1", "--unit", "m"],
            "error: computing RPE: invalid RPE delta -1 m: use a finite distance above 0 m"
                .to_string(),
        ),
        (
            vec!["rpe", "--gt", g, "--est", g, "--delta", "0.5"],
            "error: computing RPE: invalid RPE delta 0.5 frames: use a whole number of frames, \
             1 or more"
                .to_string(),
        ),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_slamkit"))
            .arg("eval")
            .args(&args)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{args:?} should fail");
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.starts_with(&expected), "{args:?}: {stderr}");
        assert!(
            !stderr.contains("Os {") && !stderr.contains("Error("),
            "{stderr}"
        );
        for path in [m, r] {
            assert!(stderr.matches(path).count() <= 1, "{stderr}");
        }
        assert!(stderr.matches("No such file").count() <= 1, "{stderr}");
    }
}
