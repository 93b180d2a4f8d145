//! A Freiburg benchmark log and its relations, read from `$SLAMKIT_DATA`; and each log's
//! uninterrupted ICP-SLAM run at the defaults, made once per test binary for the tests that
//! need it.

use slamkit_core::{LaserScan, Pose2, Trajectory};
use slamkit_eval::relations::GroundTruthRelation;
use slamkit_slam::lidar::LidarMap;
use slamkit_slam::{LidarSlam, LidarSlamConfig, Session};
use std::sync::OnceLock;
use std::time::Instant;

pub(crate) struct Log {
    pub(crate) scans: Vec<LaserScan>,
    pub(crate) relations: Vec<GroundTruthRelation>,
}

/// The scans of `lidar2d/<name>/<file>` and `<name>.relations`, or `None` (the test skipped)
/// when `SLAMKIT_DATA` is unset.
pub(crate) fn log(test: &str, name: &str, file: &str) -> Option<Log> {
    let dir = slamkit_testdata::data(test, &format!("lidar2d/{name}"))?;
    let scans = slamkit_io::carmen::read_carmen(&dir.join(file))
        .unwrap()
        .scans;
    let relations =
        slamkit_io::relations::read_relations(&dir.join(format!("{name}.relations"))).unwrap();
    Some(Log { scans, relations })
}

/// A log mapped from start to end by one ICP-SLAM session at the defaults, with the session's
/// state saved on the way at the scans where tests cut the log.
pub(crate) struct Uninterrupted {
    pub(crate) log: Log,
    /// The run's trajectory.
    pub(crate) trajectory: Trajectory,
    /// The map at the end, as the session holds it.
    pub(crate) map: LidarMap,
    /// The map file the session saved at the end.
    pub(crate) file: Vec<u8>,
    /// After the first third of the scans: the first part of `lidar_merge`.
    pub(crate) third: Saved,
    /// After the first half: the first half of `lidar_lifecycle`'s continued map.
    pub(crate) half: Saved,
}

/// The session as it was after the first `scans` scans.
pub(crate) struct Saved {
    pub(crate) scans: usize,
    /// The map file it saved.
    pub(crate) file: Vec<u8>,
    /// Its trajectory.
    pub(crate) trajectory: Trajectory,
    /// Its map's keyframes.
    pub(crate) keyframes: usize,
}

/// The uninterrupted run of one of the logs `intel`, `aces` and `mit-csail`, or `None` when
/// `SLAMKIT_DATA` is unset. Mapping a log whole is the longest part of the lifecycle and merge
/// tests, and a session fed the first scans of a log is in the state a run of only those
/// scans ends in (it never looks ahead), so each log is mapped once for all of them: one and a
/// half mapping runs fewer per log in CI (docs/experiments/ci-time.md).
pub(crate) fn uninterrupted(test: &str, name: &str) -> Option<&'static Uninterrupted> {
    const LOGS: [(&str, &str); 3] = [
        ("intel", "intel.fromrosbag.clf.gz"),
        ("aces", "aces.fromrosbag.clf.gz"),
        ("mit-csail", "mit-csail.clf"),
    ];
    static RUNS: [OnceLock<Option<Uninterrupted>>; 3] =
        [OnceLock::new(), OnceLock::new(), OnceLock::new()];
    let k = LOGS
        .iter()
        .position(|(n, _)| *n == name)
        .unwrap_or_else(|| panic!("no benchmark log {name}"));
    RUNS[k]
        .get_or_init(|| run(log(test, name, LOGS[k].1)?, name))
        .as_ref()
}

fn run(log: Log, name: &str) -> Option<Uninterrupted> {
    let start = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let save = |session: &LidarSlam, label: &str| -> Vec<u8> {
        let path = dir.path().join(format!("{label}.skmap"));
        session.save(&path).unwrap();
        std::fs::read(&path).unwrap()
    };
    let cuts = [log.scans.len() / 3, log.scans.len() / 2];
    let mut session = LidarSlam::new(LidarSlamConfig::default(), Pose2::identity()).unwrap();
    let mut saved = Vec::new();
    for (i, scan) in log.scans.iter().enumerate() {
        if cuts.contains(&i) {
            saved.push(Saved {
                scans: i,
                file: save(&session, &format!("first{i}")),
                trajectory: session.trajectory(),
                keyframes: session.map().keyframes.len(),
            });
        }
        session.push_scan(scan.clone());
    }
    let half = saved.pop().unwrap();
    let third = saved.pop().unwrap();
    let run = Uninterrupted {
        trajectory: session.trajectory(),
        map: session.map(),
        file: save(&session, "whole"),
        log,
        third,
        half,
    };
    eprintln!(
        "{name}: mapped uninterrupted in {:.1} s",
        start.elapsed().as_secs_f64()
    );
    Some(run)
}
