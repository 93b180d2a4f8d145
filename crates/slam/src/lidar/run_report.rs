//! What a run of a [`LidarSlam`] session over a lidar log reports (`report.json` of `slamkit
//! lidar`): the session's settings, counters and timings, the log's broken lines, and the
//! relations metric when the benchmark's `.relations` file is known.

use super::LidarSlam;
use serde_json::{json, Value};
use slamkit_core::Trajectory;
use slamkit_io::carmen::CarmenLog;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

impl LidarSlam {
    /// The session's part of a run's report over `log` (the scans pushed): `config`,
    /// `frames` (read, processed, skipped, failed, unreadable lines), `scans` ([`Self::scan_counts`]),
    /// `session` (its counters), `stats` (the method's) and `timings_ms`.
    pub fn run_report(&self, log: &CarmenLog) -> Value {
        let counts = self.frame_counts();
        json!({
            "config": self.config(),
            "frames": {
                "read": log.scans.len(),
                "processed": counts.processed,
                "skipped": counts.skipped,
                "failed": counts.failed,
                "unreadable_lines": log.skipped.len(),
            },
            "scans": self.scan_counts(log),
            "session": self.stats(),
            "stats": self.method_stats(),
            "timings_ms": self.timings().summary(),
        })
    }

    /// The scans of `log` read and processed, and the broken ones skipped: scans the mapper
    /// could not use, by reason, and log lines the reader could not parse (truncated, NaN,
    /// garbage), by reason, with the log's time order (report.json's `scans`).
    pub fn scan_counts(&self, log: &CarmenLog) -> Value {
        let mut unreadable: BTreeMap<&str, usize> = BTreeMap::new();
        for line in &log.skipped {
            *unreadable.entry(line.reason.key()).or_default() += 1;
        }
        let broken = &self.method_stats()["skipped_broken"];
        let total: u64 = broken.as_object().map_or(0, |reasons| {
            reasons.values().filter_map(|v| v.as_u64()).sum()
        });
        json!({
            "read": log.scans.len(),
            "processed": self.frame_counts().processed,
            "skipped_broken": total,
            "skipped_broken_reasons": broken,
            "unreadable_lines": log.skipped.len(),
            "unreadable_line_reasons": unreadable,
            "time_order": log.time_order,
        })
    }
}

/// The relations metric of `trajectory` for a report: against `relations` when given, else
/// against the benchmark file beside the log (`<log stem>.relations`), `null` when there is
/// none. Scoring that fails leaves its error in `error` rather than failing the run, whose
/// other outputs are still worth keeping.
pub fn relations_metrics(relations: Option<&Path>, log: &Path, trajectory: &Trajectory) -> Value {
    let path: Option<PathBuf> = relations
        .map(Path::to_path_buf)
        .or_else(|| slamkit_io::relations::beside_log(log));
    let Some(path) = path else {
        return Value::Null;
    };
    let scored = slamkit_io::relations::read_relations(&path)
        .map_err(|e| format!("reading relations: {e}"))
        .and_then(|relations| {
            slamkit_eval::relations_error(&relations, trajectory)
                .map_err(|e| format!("scoring against {}: {e}", path.display()))
        });
    match scored {
        Ok(stats) => json!({ "relations_file": path, "relations": stats }),
        Err(error) => json!({ "relations_file": path, "error": error }),
    }
}
