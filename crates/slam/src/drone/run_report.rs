//! What a run of a [`DroneSlam`] session over a recorded flight reports (`report.json` of
//! `slamkit lidar LOG --ranges ...`): its settings, counters, the search in a saved map, the
//! particle filter's counters and timings.

use super::DroneSlam;
use serde_json::{json, Value};
use slamkit_io::carmen::CarmenLog;

impl DroneSlam {
    /// The session's part of a run's report over `log` (the scans pushed): `config`, `frames`
    /// (read, processed, skipped, failed, odometry rejected, unreadable lines), `stats`,
    /// `in_map` (the search in a saved map, `null` for a new map), `pf` (the particle filter's
    /// counters and timings, `null` without one) and `timings_ms`.
    pub fn run_report(&self, log: &CarmenLog) -> Value {
        let counts = self.frame_counts();
        let pf = self
            .particle_filter()
            .map(|pf| json!({ "stats": pf.stats(), "timings_ms": pf.timings().summary() }));
        json!({
            "config": self.config(),
            "frames": {
                "read": log.scans.len(),
                "processed": counts.processed,
                "skipped": counts.skipped,
                "failed": counts.failed,
                "odometry_rejected": self.odometry_rejected(),
                "unreadable_lines": log.skipped.len(),
            },
            "stats": self.stats(),
            "in_map": self.in_map_stats(),
            "pf": pf,
            "timings_ms": self.timings().summary(),
        })
    }
}
