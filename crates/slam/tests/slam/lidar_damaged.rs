//! Damaged 2D lidar logs through the session (issue 25): a log is often a truncated copy, a
//! dead sensor, a corrupt line; a session says so and keeps going rather than running away.

use flate2::read::GzDecoder;
use slamkit_core::{LaserScan, Pose2, Trajectory};
use slamkit_eval::relations::GroundTruthRelation;
use slamkit_map::OccupancyGridConfig;
use slamkit_slam::lidar::grid_of_scans;
use slamkit_slam::{LidarMethod, LidarSlam, LidarSlamConfig};
use std::io::Read;

/// Scans of the Intel log up to about `seconds` into it, with the `corrupt_odom`-th ODOM line's
/// x replaced by 10⁶ m when given (one corrupt reading, as a bad copy or a driver glitch
/// gives).
fn intel(test: &str, seconds: f64, corrupt_odom: Option<usize>) -> Option<Vec<LaserScan>> {
    let dir = slamkit_testdata::data(test, "lidar2d/intel")?;
    let mut text = String::new();
    GzDecoder::new(std::fs::File::open(dir.join("intel.fromrosbag.clf.gz")).unwrap())
        .read_to_string(&mut text)
        .unwrap();
    let mut odom = 0;
    let lines: Vec<String> = text
        .lines()
        .map(|line| {
            if line.starts_with("ODOM ") {
                odom += 1;
                if Some(odom) == corrupt_odom {
                    let mut fields: Vec<&str> = line.split(' ').collect();
                    fields[1] = "1000000";
                    return fields.join(" ");
                }
            }
            line.to_owned()
        })
        .collect();
    let file = tempfile::NamedTempFile::new().unwrap();
    std::fs::write(file.path(), lines.join("\n")).unwrap();
    let scans = slamkit_io::carmen::read_carmen(file.path()).unwrap().scans;
    let start = scans[0].timestamp;
    Some(
        scans
            .into_iter()
            .take_while(|s| s.timestamp - start < seconds)
            .collect(),
    )
}

fn run(config: &LidarSlamConfig, scans: &[LaserScan]) -> LidarSlam {
    let mut session = LidarSlam::new(config.clone(), Pose2::identity()).unwrap();
    for scan in scans {
        session.push_scan(scan.clone());
    }
    session
}

/// The benchmark's relations between times before `end` \[s\].
fn relations(test: &str, end: f64) -> Option<Vec<GroundTruthRelation>> {
    let dir = slamkit_testdata::data(test, "lidar2d/intel")?;
    let all = slamkit_io::relations::read_relations(&dir.join("intel.relations")).unwrap();
    Some(all.into_iter().filter(|r| r.t1.max(r.t2) < end).collect())
}

fn relations_error(relations: &[GroundTruthRelation], trajectory: &Trajectory) -> f64 {
    slamkit_eval::relations_error(relations, trajectory)
        .unwrap()
        .trans_mean
}

/// One ODOM line at x = 10⁶ m (issue 25 item 1: `slamkit lidar` aborted after 34 s asking
/// for 5 TB; the particle filter climbed past 6 GB): the jump and its return are taken as
/// no motion and counted, the trajectory follows the clean log's, and the map stays in the
/// building.
#[test]
fn an_odometry_jump_is_taken_as_no_motion() {
    let test = "an_odometry_jump_is_taken_as_no_motion";
    let (Some(clean), Some(jumped)) = (intel(test, 600.0, None), intel(test, 600.0, Some(1500)))
    else {
        return;
    };
    let end = clean.last().unwrap().timestamp;
    let relations = relations(test, end).unwrap();
    for method in [LidarMethod::Icp, LidarMethod::Rbpf] {
        let mut config = LidarSlamConfig {
            method,
            ..LidarSlamConfig::default()
        };
        config.rbpf.particles = 5;
        let reference = run(&config, &clean).trajectory();
        let session = run(&config, &jumped);
        assert_eq!(session.stats().odometry_rejected, 2, "{method:?}");
        let (clean_error, jumped_error) = (
            relations_error(&relations, &reference),
            relations_error(&relations, &session.trajectory()),
        );
        eprintln!("{method:?}: relations error {jumped_error:.4} m, clean log {clean_error:.4} m");
        assert!(
            jumped_error < 1.3 * clean_error,
            "{method:?}: {jumped_error} m against {clean_error} m"
        );
        let grid = grid_of_scans(
            jumped.iter().zip(session.poses().into_iter().flatten()),
            OccupancyGridConfig::default(),
        )
        .unwrap();
        assert!(
            grid.tile_stats().bytes < 64 << 20,
            "{:?}",
            grid.tile_stats()
        );
    }
}
