//! What a run of a [`LidarSlam`] session over a lidar log leaves: its files (trajectory, grid,
//! map file) and its report (`report.json` of `slamkit lidar`: the session's settings, counters
//! and timings, the log's broken lines, and the relations metric when the benchmark's
//! `.relations` file is known).

use super::LidarSlam;
use crate::SlamError;
use serde_json::{json, Value};
use slamkit_core::{LaserScan, Trajectory};
use slamkit_io::carmen::CarmenLog;
use slamkit_lidar::mcl::{MclConfig, MclOutput};
use slamkit_map::save_grid_files;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

impl LidarSlam {
    /// Writes the run's files into `out` once every scan of `scans` was pushed in order:
    /// `trajectory.tum` (this run's poses), `trajectory_map.tum` when continuing a saved map
    /// (every run in the map, following the keyframes this run corrected), the grid as
    /// `map.{pgm,yaml,png}` ([`Self::output_grid`]) and the map as `map.skmap`, also saved to
    /// each of `save_map` (`--save-map`).
    pub fn write_run_files(
        &self,
        out: &Path,
        scans: &[LaserScan],
        save_map: &[&Path],
    ) -> Result<(), SlamError> {
        slamkit_io::trajectory_file::write_tum(&out.join("trajectory.tum"), &self.trajectory())?;
        if self.continues_a_map() {
            let path = out.join("trajectory_map.tum");
            slamkit_io::trajectory_file::write_tum(&path, &self.map().trajectory())?;
        }
        save_grid_files(&self.output_grid(scans)?, &out.join("map"))?;
        let map_file = self.map_file().map_err(|source| SlamError::MapFile {
            path: out.join("map.skmap"),
            source,
        })?;
        let in_folder = out.join("map.skmap");
        for path in std::iter::once(in_folder.as_path()).chain(save_map.iter().copied()) {
            map_file.save(path).map_err(|source| SlamError::MapFile {
                path: path.to_path_buf(),
                source,
            })?;
        }
        Ok(())
    }

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

/// What a Monte Carlo localisation over `log` in a grid map reports (`report.json` of `slamkit
/// lidar LOG --localize MAP.yaml`), in the fields every lidar run shares: `method` (`mcl`),
/// `config`, `stats`, `final_estimate`, `frames` (read, processed, skipped, failed: none,
/// unreadable lines) and `timings_ms`.
pub fn mcl_report(output: &MclOutput, config: &MclConfig, log: &CarmenLog) -> Value {
    let s = &output.stats;
    json!({
        "method": "mcl",
        "config": config,
        "stats": s,
        "final_estimate": output.estimates.last().copied().flatten(),
        "frames": {
            "read": log.scans.len(),
            "processed": s.updates,
            "skipped": s.scans_skipped,
            "failed": 0,
            "unreadable_lines": log.skipped.len(),
        },
        "timings_ms": output.timings.summary(),
    })
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

/// The lines a person reads at the end of a lidar run, from its `report` (as written to
/// report.json by any lidar method: ICP-SLAM, particle filter, localisation, the drone's
/// layers, Monte Carlo localisation): the scan counts and wall time, and the relations metric
/// when it was scored.
///
/// ```
/// let report = serde_json::json!({
///     "frames": { "read": 10, "processed": 9, "skipped": 1, "failed": 0, "unreadable_lines": 0 },
///     "wall_seconds": 1.25,
///     "metrics": null,
/// });
/// let text = slamkit_slam::lidar::run_report::summary(&report);
/// assert_eq!(text, "scans: 10 read, 9 processed, 1 skipped, 0 failed matches, 0 unreadable log lines; 1.2 s");
/// ```
pub fn summary(report: &Value) -> String {
    let f = &report["frames"];
    let mut text = format!(
        "scans: {} read, {} processed, {} skipped, {} failed matches, {} unreadable log lines; \
         {:.1} s",
        f["read"],
        f["processed"],
        f["skipped"],
        f["failed"],
        f["unreadable_lines"],
        report["wall_seconds"].as_f64().unwrap_or(f64::NAN)
    );
    let r = &report["metrics"]["relations"];
    if !r.is_null() {
        let number = |key: &str| r[key].as_f64().unwrap_or(f64::NAN);
        text += &format!(
            "\nrelations metric: {:.4} ± {:.4} m, {:.3} ± {:.3} deg over {} relations",
            number("trans_mean"),
            number("trans_std"),
            number("rot_mean_deg"),
            number("rot_std_deg"),
            r["count"]
        );
    }
    text
}
