//! What a run of a [`DroneSlam`] session over a flight leaves: its maps as files (for `slamkit
//! lidar LOG --ranges ...` and the demo alike) and its report (`report.json`: its settings,
//! counters, the search in a saved map, the particle filter's counters and timings).

use super::grids::{LayerFile, LayerGrids};
use super::DroneSlam;
use crate::SlamError;
use nalgebra::Point3;
use serde_json::{json, Value};
use slamkit_core::{LaserScan, Pose3};
use slamkit_io::carmen::CarmenLog;
use slamkit_map::{save_grid_files, OccupancyGridConfig};
use std::path::Path;

/// The comment of the `cloud.ply` of a flight's height-layer maps.
pub const MERGED_CLOUD_COMMENT: &str = "slamkit: merged height-layer maps";

impl DroneSlam {
    /// Writes the flight's maps into `out`, given every scan pushed, in order, and the frame
    /// to draw them in (`frame_from_world`: [`Self::map_from_world`] for a recorded flight, the
    /// simulator's world for the demo): each height layer's grid and their union
    /// ([`LayerGrids::write`]: `maps/layer_NNN.*`, `map.*`), the layers' points as `cloud.ply`,
    /// and the particle filter's best map as `map_pf.*` when the session runs one. Returns the
    /// grids, for whatever needs the layers next, and the layers' files.
    pub fn write_maps(
        &self,
        out: &Path,
        scans: &[LaserScan],
        frame_from_world: &Pose3,
    ) -> Result<(LayerGrids, Vec<LayerFile>), SlamError> {
        let grids = self.layer_grids(scans, frame_from_world, &OccupancyGridConfig::default())?;
        let layer_files = grids.write(out)?;
        let cloud: Vec<Point3<f64>> = self
            .merged_cloud()
            .iter()
            .map(|p| frame_from_world * p)
            .collect();
        slamkit_io::ply::write_ply(&out.join("cloud.ply"), &cloud, MERGED_CLOUD_COMMENT)?;
        if let Some(grid) = self.particle_filter().and_then(|pf| pf.map()) {
            save_grid_files(grid, &out.join("map_pf"))?;
        }
        Ok((grids, layer_files))
    }

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
