//! What the benchmark-log tests share: where the logs are, and the relations metric of a
//! trajectory against a log's `.relations` file.

use slamkit_core::Trajectory;
use slamkit_eval::{relations_error, GroundTruthRelation};
use std::path::{Path, PathBuf};

/// `$SLAMKIT_DATA/lidar2d`, or `None` (with a skip message naming `test`) when it is unset.
pub fn data_dir(test: &str) -> Option<PathBuf> {
    slamkit_testdata::data(test, "lidar2d")
}

/// Mean translational relations error of `trajectory` against `relations` \[m\]; every
/// relation stamp must be a pose stamp. Prints the full statistics under `log`'s name.
pub fn relations_mean_error(log: &str, relations: &Path, trajectory: &Trajectory) -> f64 {
    let relations: Vec<GroundTruthRelation> = slamkit_io::relations::read_relations(relations)
        .unwrap()
        .into_iter()
        .map(|r| GroundTruthRelation {
            t1: r.t1,
            t2: r.t2,
            t1_from_t2: r.t1_from_t2,
        })
        .collect();
    let stats = relations_error(&relations, trajectory).unwrap();
    assert_eq!(stats.missing, 0, "every relation stamp is a scan stamp");
    eprintln!(
        "{log}: {:.4} ± {:.4} m, {:.3} ± {:.3} deg, {} relations",
        stats.trans_mean, stats.trans_std, stats.rot_mean_deg, stats.rot_std_deg, stats.count
    );
    stats.trans_mean
}
