//! ICP-SLAM on the Freiburg 2D SLAM benchmark logs (Kümmerle et al. 2009), scored with the
//! relations metric. Logs: Intel Research Lab and ACES (CARMEN text decoded from the benchmark's
//! ROS bags), MIT CSAIL (original CARMEN log); see `$SLAMKIT_DATA/lidar2d/SOURCES.md`.
//!
//! The bounds sit slightly above what the default configuration reaches (measured with
//! `slamkit lidar LOG --method icp` and `slamkit eval relations`: Intel 0.0158 m, ACES 0.0385 m,
//! MIT CSAIL 0.0268 m mean translational error since a match below `min_goodness` is scored
//! over the points the map can explain, docs/experiments/lidar-icp-slam.md "Degraded logs";
//! 0.0158 / 0.0383 / 0.0274 m before, and 0.0156 / 0.0387 / 0.0278 m before scans on mapped
//! ground were localised against its keyframes), all well inside the targets (the better
//! of Kümmerle 2009's scan matching and MRPT icp-slam: Intel ≤ 0.058, ACES ≤ 0.173,
//! CSAIL ≤ 0.106 m). Skipped when `SLAMKIT_DATA` is not set; run with `--release`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test helpers fail loudly

mod common;

use common::{data_dir, relations_mean_error};
use slamkit_core::LaserScan;
use slamkit_eval::relations::RELATION_STAMP_TOLERANCE_S;
use slamkit_eval::{relations_error, GroundTruthRelation};
use slamkit_io::degraded_log::Degradation;
use slamkit_lidar::icp_slam::{run_icp_slam, IcpSlamConfig};
use std::path::{Path, PathBuf};

/// Runs ICP-SLAM with the default configuration on `log` and returns its mean translational
/// relations error \[m\].
fn icp_slam_error(dir: PathBuf, log: &str, relations: &str) -> f64 {
    let scans = slamkit_io::carmen::read_carmen(&dir.join(log))
        .unwrap()
        .scans;
    let out = run_icp_slam(&scans, &IcpSlamConfig::default(), |_| {}).unwrap();
    assert_eq!(out.trajectory.len(), scans.len(), "one pose per scan");
    relations_mean_error(log, &dir.join(relations), &out.trajectory)
}

#[test]
fn icp_slam_intel() {
    let Some(dir) = data_dir("icp_slam_intel") else {
        return;
    };
    let err = icp_slam_error(
        dir,
        "intel/intel.fromrosbag.clf.gz",
        "intel/intel.relations",
    );
    assert!(err < 0.025, "Intel mean error {err} m");
}

#[test]
fn icp_slam_aces() {
    let Some(dir) = data_dir("icp_slam_aces") else {
        return;
    };
    let err = icp_slam_error(dir, "aces/aces.fromrosbag.clf.gz", "aces/aces.relations");
    assert!(err < 0.045, "ACES mean error {err} m");
}

#[test]
fn icp_slam_mit_csail() {
    let Some(dir) = data_dir("icp_slam_mit_csail") else {
        return;
    };
    let err = icp_slam_error(
        dir,
        "mit-csail/mit-csail.clf",
        "mit-csail/mit-csail.relations",
    );
    assert!(err < 0.035, "MIT CSAIL mean error {err} m");
}

/// Issue 24, item 4: ICP-SLAM with `surface_score` on each log degraded as a building outside the
/// benchmarks degrades it ([`slamkit_io::degraded_log::Degradation`]: one scan in 3–6 kept so
/// that about 1.6 are left per second, successive scans interlaced by a quarter of the angular
/// step, 10 % of the hits replaced by returns beyond the surface, 30 % of the beams lost).
/// Prints the share of failed scan matches and the relations error over the relations whose
/// two ends were kept, against the undegraded log's run over the same relations (the issue:
/// under 5 % failed, within 1.5×), for every degradation together and for each alone. A measurement, recorded in docs/experiments/lidar-icp-slam.md:
/// `SLAMKIT_DATA=/work/shared/data cargo test --release -p slamkit-lidar --test benchmark_logs
/// degraded -- --ignored --nocapture`.
#[test]
#[ignore = "a measurement: two ICP-SLAM runs of each benchmark log"]
fn icp_slam_on_degraded_logs() {
    let Some(dir) = data_dir("icp_slam_on_degraded_logs") else {
        return;
    };
    for (log, relations) in [
        ("intel/intel.fromrosbag.clf.gz", "intel/intel.relations"),
        ("aces/aces.fromrosbag.clf.gz", "aces/aces.relations"),
        ("mit-csail/mit-csail.clf", "mit-csail/mit-csail.relations"),
    ] {
        let scans = slamkit_io::carmen::read_carmen(&dir.join(log))
            .unwrap()
            .scans;
        let span = scans.last().unwrap().timestamp - scans[0].timestamp;
        let rate = (scans.len() - 1) as f64 / span;
        let every = Degradation {
            keep_every: Degradation::keep_every_for_rate(rate, 1.6),
            ..Degradation::default()
        };
        let none = Degradation {
            keep_every: 1,
            interlace: false,
            spurious_fraction: 0.0,
            dropout_fraction: 0.0,
            ..every.clone()
        };
        // every degradation together, then each alone (where the failures come from)
        let variants = [
            ("every degradation", every.clone()),
            (
                "fewer scans only",
                Degradation {
                    keep_every: every.keep_every,
                    ..none.clone()
                },
            ),
            (
                "interlaced only",
                Degradation {
                    interlace: true,
                    ..none.clone()
                },
            ),
            (
                "spurious returns only",
                Degradation {
                    spurious_fraction: every.spurious_fraction,
                    ..none.clone()
                },
            ),
            (
                "lost beams only",
                Degradation {
                    dropout_fraction: every.dropout_fraction,
                    ..none.clone()
                },
            ),
        ];
        // the relations both of whose ends every variant keeps (the fewest scans: one in
        // `keep_every`)
        let relations = kept_relations(&dir.join(relations), &every.apply(&scans));
        // the option made for such lasers (off by default: see its doc)
        let config = IcpSlamConfig {
            surface_score: true,
            ..IcpSlamConfig::default()
        };
        let run = |scans: &[LaserScan]| {
            let start = std::time::Instant::now();
            let out = run_icp_slam(scans, &config, |_| {}).unwrap();
            let error = relations_error(&relations, &out.trajectory).unwrap();
            (out.stats, error.trans_mean, start.elapsed().as_secs_f64())
        };
        let (stats, clean, seconds) = run(&scans);
        eprintln!(
            "{log}: {rate:.2} scans/s; {} relations with both ends in one scan of {}; \
             undegraded: failed matches {} of {}, relations error {clean:.4} m, {seconds:.1} s",
            relations.len(),
            every.keep_every,
            stats.matches_failed,
            stats.scans_processed,
        );
        for (label, degradation) in &variants {
            let (stats, error, seconds) = run(&degradation.apply(&scans));
            let failed = stats.matches_failed as f64 / stats.scans_processed.max(1) as f64;
            eprintln!(
                "  {label}: failed matches {} of {} ({:.1} %), relations error {error:.4} m \
                 ({:.2}×), {seconds:.1} s",
                stats.matches_failed,
                stats.scans_processed,
                100.0 * failed,
                error / clean,
            );
        }
    }
}

/// The relations of the file `relations` both of whose ends are scans of `kept`, matched as the
/// metric matches them (within [`RELATION_STAMP_TOLERANCE_S`]).
fn kept_relations(relations: &Path, kept: &[LaserScan]) -> Vec<GroundTruthRelation> {
    let mut stamps: Vec<f64> = kept.iter().map(|s| s.timestamp).collect();
    stamps.sort_by(f64::total_cmp);
    let near = |t: f64| {
        let i = stamps.partition_point(|&k| k < t);
        [i.wrapping_sub(1), i].iter().any(|&j| {
            stamps
                .get(j)
                .is_some_and(|k| (k - t).abs() <= RELATION_STAMP_TOLERANCE_S)
        })
    };
    slamkit_io::relations::read_relations(relations)
        .unwrap()
        .into_iter()
        .filter(|r| near(r.t1) && near(r.t2))
        .map(|r| GroundTruthRelation {
            t1: r.t1,
            t2: r.t2,
            t1_from_t2: r.t1_from_t2,
        })
        .collect()
}

/// Issue 24, item 4, in CI: the first 500 s of Intel, degraded as
/// [`icp_slam_on_degraded_logs`] degrades it (843 scans), mapped with `surface_score`: 0.5 %
/// of the matches failed and the relations error over the 150 relations kept was 0.0212 m
/// (the undegraded part 0.0143 m). Without it (the default), failed matches not scored over
/// the points the map can explain (`icp_slam::surface`): 33.5 % and 1.084 m. About 2 s in
/// release.
#[test]
fn icp_slam_on_degraded_intel_start() {
    let Some(dir) = data_dir("icp_slam_on_degraded_intel_start") else {
        return;
    };
    let scans = slamkit_io::carmen::read_carmen(&dir.join("intel/intel.fromrosbag.clf.gz"))
        .unwrap()
        .scans;
    let start = scans[0].timestamp;
    let part: Vec<LaserScan> = scans
        .into_iter()
        .take_while(|s| s.timestamp - start < 500.0)
        .collect();
    let degraded = Degradation::default().apply(&part);
    let relations = kept_relations(&dir.join("intel/intel.relations"), &degraded);
    let config = IcpSlamConfig {
        surface_score: true,
        ..IcpSlamConfig::default()
    };
    let out = run_icp_slam(&degraded, &config, |_| {}).unwrap();
    let error = relations_error(&relations, &out.trajectory).unwrap();
    let failed = out.stats.matches_failed as f64 / out.stats.scans_processed as f64;
    eprintln!(
        "degraded Intel, first 500 s: {} scans, {:.1} % failed, relations error {:.4} m over {}",
        degraded.len(),
        100.0 * failed,
        error.trans_mean,
        error.count
    );
    assert!(failed < 0.05, "{:.1} % failed matches", 100.0 * failed);
    assert!(
        error.trans_mean < 0.03,
        "relations error {} m",
        error.trans_mean
    );
}
