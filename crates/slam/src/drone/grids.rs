//! Occupancy grids of a drone session's scans: one per height layer and one of every scan,
//! each matched scan inserted at its estimated pose. They are what a user looks at (one PGM
//! per layer) and what the kidnapped-drone check localises in
//! ([`super::kidnapped`]); the session itself keeps point maps, not grids.

use super::DroneSlam;
use crate::lidar::{grid_of_scans, FrameCounts};
use crate::SlamError;
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{LaserScan, Pose2, Pose3};
use slamkit_lidar::icp_slam::ScanStatus;
use slamkit_lidar::layers::LayerScanStatus;
use slamkit_map::{save_grid_files, OccupancyGrid, OccupancyGridConfig};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One height layer's grid.
#[derive(Debug, Clone)]
pub struct LayerGrid {
    /// Bottom and top of the layer \[m\].
    pub z_range_m: [f64; 2],
    /// Scans inserted.
    pub scans: usize,
    /// The grid.
    pub grid: OccupancyGrid,
}

/// The grids of a session's scans.
#[derive(Debug, Clone)]
pub struct LayerGrids {
    /// Every matched scan in one grid.
    pub all: OccupancyGrid,
    /// One grid per height layer with a matched scan, by layer index.
    pub layers: BTreeMap<i64, LayerGrid>,
}

/// A height layer's grid written to disk by [`LayerGrids::write`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LayerFile {
    /// Layer index.
    pub layer: i64,
    /// Bottom and top of the layer \[m\].
    pub z_range_m: [f64; 2],
    /// Scans inserted.
    pub scans: usize,
    /// The PNG image.
    #[serde(skip)]
    pub png: PathBuf,
}

impl LayerGrids {
    /// Writes the grid of every scan as `out/map.{pgm,yaml,png}` and one per height layer as
    /// `out/maps/layer_NNN.{pgm,yaml,png}`; returns the layers written, in layer order.
    pub fn write(&self, out: &Path) -> Result<Vec<LayerFile>, SlamError> {
        save_grid_files(&self.all, &out.join("map"))?;
        let dir = out.join("maps");
        std::fs::create_dir_all(&dir).map_err(|error| {
            SlamError::Io(slamkit_io::IoError::Io {
                path: dir.clone(),
                error,
            })
        })?;
        let mut files = Vec::new();
        for (layer, l) in &self.layers {
            let stem = dir.join(format!("layer_{layer:03}"));
            save_grid_files(&l.grid, &stem)?;
            files.push(LayerFile {
                layer: *layer,
                z_range_m: l.z_range_m,
                scans: l.scans,
                png: stem.with_extension("png"),
            });
        }
        Ok(files)
    }

    /// The layer grids alone, by layer index (what [`super::layer_choice`] takes).
    pub fn into_layer_maps(self) -> BTreeMap<i64, OccupancyGrid> {
        self.layers.into_iter().map(|(k, l)| (k, l.grid)).collect()
    }
}

impl DroneSlam {
    /// Grids of `scans` (the scans pushed, in order; those before the drone was found in a
    /// saved map are left out) at the poses estimated for them, seen
    /// from `frame` (`frame_from_world`, the world being the first scan's frame; give
    /// [`DroneSlam::map_from_world`] for the map frame): one of every scan matched in a layer
    /// and one per layer. Scans not matched (tilted, no height) are left out.
    pub fn layer_grids(
        &self,
        scans: &[LaserScan],
        frame: &Pose3,
        config: &OccupancyGridConfig,
    ) -> Result<LayerGrids, SlamError> {
        let mut posed: BTreeMap<i64, Vec<(&LaserScan, Pose2)>> = BTreeMap::new();
        let mut every = Vec::new();
        for (scan, record) in scans.iter().skip(self.unplaced_scans()).zip(self.scans()) {
            let est = &record.estimate;
            let (LayerScanStatus::Slam(_), Some(layer)) = (est.status, est.layer) else {
                continue;
            };
            let world_from_base = pose3_to_pose2(&(frame * est.world_from_base));
            posed
                .entry(layer)
                .or_default()
                .push((scan, world_from_base));
            every.push((scan, world_from_base));
        }
        let layer_height_m = self.config().layers.height.layer_height_m;
        let mut layers = BTreeMap::new();
        for (layer, scans) in posed {
            let bottom = layer as f64 * layer_height_m;
            let count = scans.len();
            layers.insert(
                layer,
                LayerGrid {
                    z_range_m: [bottom, bottom + layer_height_m],
                    scans: count,
                    grid: grid_of_scans(scans, config.clone())?,
                },
            );
        }
        Ok(LayerGrids {
            all: grid_of_scans(every, config.clone())?,
            layers,
        })
    }

    /// Scans matched in a layer, skipped (tilted, or with no height yet) and whose match
    /// failed (their pose is a prediction), so far.
    pub fn frame_counts(&self) -> FrameCounts {
        let slam = |s: &LayerScanStatus| matches!(s, LayerScanStatus::Slam(_));
        let stats = self.stats();
        FrameCounts {
            processed: self
                .scans()
                .iter()
                .filter(|r| slam(&r.estimate.status))
                .count(),
            skipped: stats.scans_tilted + stats.scans_without_height,
            failed: self
                .scans()
                .iter()
                .filter(|r| r.estimate.status == LayerScanStatus::Slam(ScanStatus::MatchFailed))
                .count(),
        }
    }
}
