//! A Freiburg benchmark log and its relations, read once per test from `$SLAMKIT_DATA`.

use slamkit_core::LaserScan;
use slamkit_eval::relations::GroundTruthRelation;

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
