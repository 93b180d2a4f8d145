//! The 2D lidar benchmark logs read end to end, checked against the counts in
//! `$SLAMKIT_DATA/lidar2d/SOURCES.md`: Freiburg SLAM benchmark logs (Kümmerle et al. 2009) via
//! github.com/INESCTEC/ricoslam, MRPT sample rawlogs via github.com/MRPT/mrpt.

use slamkit_core::LaserScan;
use slamkit_io::carmen::{read_carmen, CarmenLog};
use slamkit_io::mrpt_text::{read_mrpt_ground_truth, read_mrpt_text};
use slamkit_io::relations::{read_relations, Relation};
use std::path::PathBuf;

fn lidar_dir(test: &str) -> Option<PathBuf> {
    slamkit_testdata::data(test, "lidar2d")
}

fn backward_steps(scans: &[LaserScan]) -> usize {
    scans
        .windows(2)
        .filter(|w| w[1].timestamp < w[0].timestamp)
        .count()
}

/// Distinct relation timestamps, and how many of them equal a scan timestamp within `tol_s`.
fn matched_relation_stamps(
    relations: &[Relation],
    scans: &[LaserScan],
    tol_s: f64,
) -> (usize, usize) {
    let mut scan_times: Vec<f64> = scans.iter().map(|s| s.timestamp).collect();
    scan_times.sort_by(f64::total_cmp);
    let mut stamps: Vec<f64> = relations.iter().flat_map(|r| [r.t1, r.t2]).collect();
    stamps.sort_by(f64::total_cmp);
    stamps.dedup();
    let matched = stamps
        .iter()
        .filter(|&&t| {
            let i = scan_times.partition_point(|&s| s < t - tol_s);
            scan_times.get(i).is_some_and(|&s| (s - t).abs() <= tol_s)
        })
        .count();
    (stamps.len(), matched)
}

fn time_span(scans: &[LaserScan]) -> (f64, f64) {
    let ts = scans.iter().map(|s| s.timestamp);
    (
        ts.clone().fold(f64::INFINITY, f64::min),
        ts.fold(f64::NEG_INFINITY, f64::max),
    )
}

/// Beams at the log's "no return" value are flagged, not hits; every other reading is below
/// the threshold.
fn check_no_return(log: &CarmenLog, no_return_m: f64, max_range_m: f64) {
    let mut no_returns = 0;
    for s in &log.scans {
        assert_eq!(s.max_range_m, max_range_m);
        for (i, &r) in s.ranges_m.iter().enumerate() {
            if (r - no_return_m).abs() < 1e-9 {
                no_returns += 1;
                assert!(!s.is_hit(i));
            } else {
                assert!(r < max_range_m, "reading {r} at t {}", s.timestamp);
            }
        }
    }
    assert!(no_returns > 1000, "{no_returns} no-return readings");
}

#[test]
fn intel_log_keeps_file_order_and_matches_relations() {
    let Some(dir) = lidar_dir("intel_log_keeps_file_order_and_matches_relations") else {
        return;
    };
    let log = read_carmen(&dir.join("intel/intel.fromrosbag.clf.gz")).unwrap();
    assert_eq!(log.scans.len(), 13631);
    assert_eq!(log.odometry_lines, 26915);
    assert!(log.skipped.is_empty(), "{:?}", log.skipped.first());
    assert!(log
        .scans
        .iter()
        .all(|s| s.ranges_m.len() == 180 && s.odometry.is_some()));
    assert_eq!(backward_steps(&log.scans), 631);
    // the reader's own count, shown in reports; file order kept
    assert_eq!(log.time_order.backward_steps, 631);
    assert_eq!(log.time_order.steps, 13630);
    assert!(!log.time_order.is_mostly_out_of_order());
    let first = &log.scans[0];
    assert!((first.beam_angle_rad(0) + 90f64.to_radians()).abs() < 1e-6);
    // the log writes the 1° step rounded to 6 decimals (0.017453)
    assert!((first.beam_angle_rad(179) - 89f64.to_radians()).abs() < 1e-4);
    let (t0, t1) = time_span(&log.scans);
    assert!((t0 - 976052857.34).abs() < 0.01 && (t1 - 976055548.63).abs() < 0.01);
    check_no_return(&log, 81.83, 30.0);

    let relations = read_relations(&dir.join("intel/intel.relations")).unwrap();
    assert_eq!(relations.len(), 2984);
    assert_eq!(
        matched_relation_stamps(&relations, &log.scans, 0.0),
        (1791, 1791)
    );
}

#[test]
fn aces_log_and_relations() {
    let Some(dir) = lidar_dir("aces_log_and_relations") else {
        return;
    };
    let log = read_carmen(&dir.join("aces/aces.fromrosbag.clf.gz")).unwrap();
    assert_eq!(log.scans.len(), 7374);
    assert_eq!(log.odometry_lines, 7375);
    assert!(log.skipped.is_empty(), "{:?}", log.skipped.first());
    assert!(log
        .scans
        .iter()
        .all(|s| s.ranges_m.len() == 180 && s.odometry.is_some()));
    let (t0, t1) = time_span(&log.scans);
    assert!((t0 - 70.29).abs() < 0.01 && (t1 - 1435.81).abs() < 0.01);
    check_no_return(&log, 50.0, 50.0);

    let relations = read_relations(&dir.join("aces/aces.relations")).unwrap();
    assert_eq!(relations.len(), 1279);
    assert_eq!(
        matched_relation_stamps(&relations, &log.scans, 0.0),
        (1218, 1218)
    );
}

#[test]
fn mit_csail_flaser_log_and_relations() {
    let Some(dir) = lidar_dir("mit_csail_flaser_log_and_relations") else {
        return;
    };
    let log = read_carmen(&dir.join("mit-csail/mit-csail.clf")).unwrap();
    assert_eq!(log.scans.len(), 1988);
    assert_eq!(log.odometry_lines, 0);
    assert!(log.skipped.is_empty(), "{:?}", log.skipped.first());
    assert!(log.scans.iter().all(|s| s.ranges_m.len() == 361));
    let first = &log.scans[0];
    assert!((first.angle_increment_rad - 0.5f64.to_radians()).abs() < 1e-12);
    let odom = first.odometry.unwrap();
    assert!((odom.translation.x - 576.536523).abs() < 1e-9);
    assert!((odom.rotation.angle() + 2.255213).abs() < 1e-9);
    let (t0, t1) = time_span(&log.scans);
    assert!((t0 - 1134864629.90).abs() < 0.01 && (t1 - 1134865053.89).abs() < 0.01);
    check_no_return(&log, 81.91, 80.0);

    let relations = read_relations(&dir.join("mit-csail/mit-csail.relations")).unwrap();
    assert_eq!(relations.len(), 1172);
    // the relations carry 5 decimals, the log 6
    assert_eq!(
        matched_relation_stamps(&relations, &log.scans, 5.1e-6),
        (1045, 1045)
    );
    let killian = read_relations(&dir.join("mit-killian/mit-killian.relations")).unwrap();
    assert_eq!(killian.len(), 4677);
}

#[test]
fn mrpt_simul_odometry_and_ground_truth() {
    let Some(dir) = lidar_dir("mrpt_simul_odometry_and_ground_truth") else {
        return;
    };
    let log = read_mrpt_text(&dir.join("mrpt/simul.fromrawlog.txt")).unwrap();
    assert_eq!(log.scans.len(), 1733);
    assert_eq!(log.odometry_increments, 1733);
    assert!(log.skipped.is_empty(), "{:?}", log.skipped.first());
    assert!(log.scans.iter().all(|s| s.ranges_m.len() == 361));
    assert_eq!(log.scans[0].base_from_laser.translation.x, 0.2);
    // SOURCES.md: 200 chained increments give (14.42, 1.49, 0.153 rad)
    let odom = log.scans[200].odometry.unwrap();
    assert!((odom.translation.x - 14.42).abs() < 0.01, "{odom}");
    assert!((odom.translation.y - 1.49).abs() < 0.01, "{odom}");
    assert!((odom.rotation.angle() - 0.153).abs() < 0.001, "{odom}");

    let gt = read_mrpt_ground_truth(&dir.join("mrpt/simul.rawlog.GT.txt")).unwrap();
    assert_eq!(gt.len(), 1734);
    let gt_times: Vec<f64> = gt.poses.iter().map(|p| p.timestamp).collect();
    for s in &log.scans {
        assert!(
            gt_times.iter().any(|t| (t - s.timestamp).abs() < 1e-5),
            "{}",
            s.timestamp
        );
    }
    let at_200 = gt
        .poses
        .iter()
        .find(|p| (p.timestamp - log.scans[200].timestamp).abs() < 1e-5)
        .unwrap();
    assert!((at_200.pose.translation.x - 14.367).abs() < 1e-6);
}

#[test]
fn mrpt_telecom_faculty_real_log() {
    let Some(dir) = lidar_dir("mrpt_telecom_faculty_real_log") else {
        return;
    };
    let file = "mrpt/2006-01ENE-21-SENA_Telecom_Faculty_one_loop_only.fromrawlog.txt";
    let log = read_mrpt_text(&dir.join(file)).unwrap();
    assert_eq!(log.scans.len(), 225);
    assert_eq!(log.odometry_increments, 224);
    assert!(log.skipped.is_empty());
    assert_eq!(log.scans[0].base_from_laser.translation.x, 0.78);
    // invalid beams are the SICK overflow codes: kept as no-return readings
    assert!(log
        .scans
        .iter()
        .flat_map(|s| &s.ranges_m)
        .all(|r| r.is_finite()));
    assert!(log.scans.iter().all(|s| s.hit_count() > 100));
}
