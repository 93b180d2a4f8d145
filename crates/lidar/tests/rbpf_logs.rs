//! Particle-filter SLAM on the Freiburg 2D SLAM benchmark logs (Kümmerle et al. 2009), scored
//! with the relations metric, and Monte Carlo localisation from a global start in the Intel map
//! it builds. Logs: Intel Research Lab and ACES (CARMEN text decoded from the benchmark's ROS
//! bags), MIT CSAIL (original CARMEN log); see `$SLAMKIT_DATA/lidar2d/SOURCES.md`.
//!
//! All runs use 10 particles (MRPT's rbpf-slam example count) and the default configuration;
//! the bounds are the targets (the better of GMapping and MRPT's rbpf-slam: Intel
//! ≤ 0.065, ACES ≤ 0.060, MIT CSAIL ≤ 0.049 m mean translational relations error). Intel and
//! CSAIL run seed 1 (measured 0.0309 and 0.0416 m with `slamkit lidar LOG --method rbpf
//! --particles 10`, which prints the relations metric); ACES, whose loops close by
//! relocalisation at a few seeds' luck, checks the median of seeds 1–3 (measured 0.0719,
//! 0.0472, 0.0561 m: median 0.0561 m; seeds 1–10 in docs/experiments/pf-seeds.md).
//! Skipped when `SLAMKIT_DATA` is not set; run with `--release`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test helpers fail loudly

mod common;

use common::{data_dir, relations_mean_error};
use slamkit_core::LaserScan;
use slamkit_lidar::mcl::{run_mcl, MclConfig};
use slamkit_lidar::rbpf::{run_rbpf, RbpfConfig, RbpfOutput};
use std::path::Path;
use std::sync::{Mutex, OnceLock, PoisonError};

fn config() -> RbpfConfig {
    RbpfConfig {
        particles: 10,
        ..RbpfConfig::default()
    }
}

fn read_scans(path: &Path) -> Vec<LaserScan> {
    slamkit_io::carmen::read_carmen(path).unwrap().scans
}

/// Runs the filter on `log` and returns its scans, output and mean relations error.
fn run(
    dir: &Path,
    log: &str,
    relations: &str,
    config: &RbpfConfig,
) -> (Vec<LaserScan>, RbpfOutput, f64) {
    let scans = read_scans(&dir.join(log));
    let out = run_rbpf(&scans, config, |_| {}).unwrap();
    assert_eq!(out.trajectory.len(), scans.len(), "one pose per scan");
    assert_eq!(out.stats.scans_skipped, 0);
    let err = relations_mean_error(log, &dir.join(relations), &out.trajectory);
    (scans, out, err)
}

/// The Intel run, shared by the SLAM and the localisation tests (the first to ask runs it).
fn intel(dir: &Path) -> &'static (Vec<LaserScan>, RbpfOutput, f64) {
    static INTEL: OnceLock<(Vec<LaserScan>, RbpfOutput, f64)> = OnceLock::new();
    INTEL.get_or_init(|| {
        run(
            dir,
            "intel/intel.fromrosbag.clf.gz",
            "intel/intel.relations",
            &config(),
        )
    })
}

#[test]
fn rbpf_intel() {
    let Some(dir) = data_dir("rbpf_intel") else {
        return;
    };
    let (_, out, err) = intel(&dir);
    assert!(*err <= 0.065, "Intel mean error {err} m");
    // Copy-on-write tiles: the 10 maps together take far less than 10 separate maps.
    let m = out.stats.memory_end;
    assert!(m.shared_bytes * 4 < m.unshared_bytes, "{m:?}");
}

/// ACES's errors of the seeds run so far, for the median check of the last of them.
static ACES_ERRORS: Mutex<Vec<f64>> = Mutex::new(Vec::new());

/// ACES at `seed`, one test per seed so that the two test threads share the three runs with the
/// Intel and CSAIL runs (the tests start in name order: CSAIL's and the Intel one first).
/// No seed may lose a loop (a lost closure costs 0.1-0.3 m of mean error); the test that
/// completes the three seeds checks their median.
fn rbpf_aces(name: &str, seed: u64) {
    let Some(dir) = data_dir(name) else {
        return;
    };
    let config = RbpfConfig { seed, ..config() };
    let log = "aces/aces.fromrosbag.clf.gz";
    let err = run(&dir, log, "aces/aces.relations", &config).2;
    eprintln!("ACES seed {seed}: mean error {err} m");
    assert!(err < 0.08, "ACES seed {seed} mean error {err} m");
    let mut errors = ACES_ERRORS.lock().unwrap_or_else(PoisonError::into_inner);
    errors.push(err);
    if errors.len() == 3 {
        errors.sort_by(f64::total_cmp);
        assert!(errors[1] <= 0.060, "ACES median error of {errors:?} m");
    }
}

#[test]
fn rbpf_aces_seed_1() {
    rbpf_aces("rbpf_aces_seed_1", 1);
}

#[test]
fn rbpf_aces_seed_2() {
    rbpf_aces("rbpf_aces_seed_2", 2);
}

#[test]
fn rbpf_aces_seed_3() {
    rbpf_aces("rbpf_aces_seed_3", 3);
}

/// Named to sort before the ACES tests, so that it starts beside the Intel run.
#[test]
fn mit_csail_rbpf() {
    let Some(dir) = data_dir("mit_csail_rbpf") else {
        return;
    };
    let (_, _, err) = run(
        &dir,
        "mit-csail/mit-csail.clf",
        "mit-csail/mit-csail.relations",
        &config(),
    );
    assert!(err <= 0.049, "MIT CSAIL mean error {err} m");
}

/// Global localisation in the map particle-filter SLAM built from the Intel log: a stretch of
/// 1500 scans (about 5 minutes) from the middle of the log, started with no prior over the whole
/// map, must converge within 50 scans and then stay within 0.2 m of the SLAM poses (both live in
/// the map's frame). Measured: converged at scan 6; from scan 50 on, median error 0.041 m,
/// largest 0.161 m.
#[test]
fn mcl_converges_from_anywhere_in_the_intel_map() {
    let Some(dir) = data_dir("mcl_converges_from_anywhere_in_the_intel_map") else {
        return;
    };
    let (scans, out, _) = intel(&dir);
    let map = out.map.as_ref().expect("a map");
    let (start, len, settle) = (6000, 1500, 50);
    let stretch = &scans[start..start + len];
    let mcl = run_mcl(stretch, map, &MclConfig::default(), |_| {}).unwrap();
    let first = mcl.stats.first_converged_scan.expect("converges");
    eprintln!(
        "MCL: {} global particles over {:.0} m² of free space, converged at scan {first}",
        mcl.stats.global_particles, mcl.stats.free_area_m2
    );
    assert!(mcl.stats.global_particles > 30_000, "{:?}", mcl.stats);
    assert!(first < settle, "converged only at scan {first}");
    let mut errors: Vec<f64> = mcl.poses[settle..]
        .iter()
        .zip(&out.poses[start + settle..start + len])
        .map(|(a, b)| (a.translation.vector - b.translation.vector).norm())
        .collect();
    errors.sort_by(f64::total_cmp);
    let (median, worst) = (errors[errors.len() / 2], errors[errors.len() - 1]);
    eprintln!("MCL error after scan {settle}: median {median:.3} m, largest {worst:.3} m");
    assert!(
        median < 0.1 && worst < 0.2,
        "median {median} m, largest {worst} m"
    );
}
