//! The files both `slamkit demo` and `slamkit lidar --ranges` write from a [`DroneSlam`]
//! session, and its run over a flight with a progress bar.

use crate::output::{progress_bar, write_grid};
use anyhow::Context;
use nalgebra::Point3;
use slamkit_core::Observation;
use slamkit_slam::drone::grids::LayerGrids;
use slamkit_slam::DroneSlam;
use std::path::{Path, PathBuf};

/// Feeds `observations` (in time order) to `session`, with a progress bar over the scans.
pub fn run_session(observations: Vec<Observation>, mut session: DroneSlam) -> DroneSlam {
    let scans = observations
        .iter()
        .filter(|o| matches!(o, Observation::Scan(_)))
        .count();
    let bar = progress_bar(scans as u64, "drone-slam");
    for observation in observations {
        if session.push(observation).is_some() {
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    session
}

/// A height layer's grid map written to disk.
pub struct LayerFile {
    /// Layer index.
    pub layer: i64,
    /// Bottom and top of the layer \[m\].
    pub z_range_m: [f64; 2],
    /// Scans inserted.
    pub scans: usize,
    /// The PNG image.
    pub png: PathBuf,
}

/// Writes the grid of every scan (`map.*`) and one per height layer (`maps/layer_NNN.*`).
pub fn write_grids(out: &Path, grids: &LayerGrids) -> anyhow::Result<Vec<LayerFile>> {
    write_grid(&grids.all, &out.join("map"))?;
    let dir = out.join("maps");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut files = Vec::new();
    for (layer, l) in &grids.layers {
        let stem = dir.join(format!("layer_{layer:03}"));
        write_grid(&l.grid, &stem)?;
        let png = stem.with_extension("png");
        files.push(LayerFile {
            layer: *layer,
            z_range_m: l.z_range_m,
            scans: l.scans,
            png,
        });
    }
    Ok(files)
}

/// Writes the merged layer maps as an ASCII PLY point cloud.
pub fn write_ply(path: &Path, points: &[Point3<f64>]) -> anyhow::Result<()> {
    let comment = "slamkit: merged height-layer maps";
    Ok(slamkit_io::ply::write_ply(path, points, comment)?)
}
