//! Running a [`DroneSlam`] session over a recorded or simulated flight with a progress bar,
//! and the files both `slamkit demo` and `slamkit lidar --ranges` write from it: the
//! per-layer grids, the grid of every scan, the merged cloud.

use crate::output::progress_bar;
use anyhow::Context;
use nalgebra::Point3;
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{LaserScan, Observation, Pose2, Pose3};
use slamkit_lidar::layers::{LayerScanStatus, LayeredEstimate};
use slamkit_map::{save_map_yaml, save_png, OccupancyGrid, OccupancyGridConfig};
use slamkit_slam::{DroneSlam, DroneSlamConfig};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Feeds `observations` (in time order) to a new session with `config`, with a progress bar
/// over the scans.
pub fn run_session(
    observations: Vec<Observation>,
    config: DroneSlamConfig,
) -> anyhow::Result<DroneSlam> {
    let scans = observations
        .iter()
        .filter(|o| matches!(o, Observation::Scan(_)))
        .count();
    let mut session = DroneSlam::new(config)?;
    let bar = progress_bar(scans as u64, "drone-slam");
    for observation in observations {
        if session.push(observation).is_some() {
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    Ok(session)
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

/// Writes one grid per height layer (`maps/layer_NNN.*`) and one of every scan (`map.*`), each
/// matched scan inserted at its estimated pose seen from `frame` (`frame_from_world`, the
/// world being the session's first-scan frame); returns the files and the layer grids.
pub fn write_maps(
    out: &Path,
    scans: &[LaserScan],
    estimates: &[LayeredEstimate],
    frame: &Pose3,
    layer_height_m: f64,
) -> anyhow::Result<(Vec<LayerFile>, BTreeMap<i64, OccupancyGrid>)> {
    let grid_config = OccupancyGridConfig::default();
    let mut all = OccupancyGrid::new(grid_config.clone())?;
    let mut layers: BTreeMap<i64, (OccupancyGrid, usize)> = BTreeMap::new();
    for (scan, est) in scans.iter().zip(estimates) {
        let (LayerScanStatus::Slam(_), Some(layer)) = (est.status, est.layer) else {
            continue;
        };
        let world_from_base: Pose2 = pose3_to_pose2(&(frame * est.world_from_base));
        let world_from_laser = world_from_base * scan.base_from_laser;
        all.insert_scan(scan, &world_from_laser)?;
        let entry = match layers.entry(layer) {
            std::collections::btree_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::btree_map::Entry::Vacant(v) => {
                v.insert((OccupancyGrid::new(grid_config.clone())?, 0))
            }
        };
        entry.0.insert_scan(scan, &world_from_laser)?;
        entry.1 += 1;
    }
    save_map_yaml(&all, &out.join("map.yaml"))?;
    save_png(&all, &out.join("map.png"))?;
    let dir = out.join("maps");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut files = Vec::new();
    for (layer, (grid, scans)) in &layers {
        let stem = dir.join(format!("layer_{layer:03}"));
        save_map_yaml(grid, &stem.with_extension("yaml"))?;
        let png = stem.with_extension("png");
        save_png(grid, &png)?;
        let bottom = *layer as f64 * layer_height_m;
        files.push(LayerFile {
            layer: *layer,
            z_range_m: [bottom, bottom + layer_height_m],
            scans: *scans,
            png,
        });
    }
    let grids = layers.into_iter().map(|(k, (grid, _))| (k, grid)).collect();
    Ok((files, grids))
}

/// Writes `points` as an ASCII PLY point cloud.
pub fn write_ply(path: &Path, points: &[Point3<f64>]) -> anyhow::Result<()> {
    let mut text = format!(
        "ply\nformat ascii 1.0\ncomment slamkit: merged height-layer maps\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        points.len()
    );
    for p in points {
        let _ = writeln!(text, "{:.4} {:.4} {:.4}", p.x, p.y, p.z);
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// Scans the layered mapper matched (or tried to), and of them those whose match failed.
pub fn processed_and_failed(estimates: &[LayeredEstimate]) -> (usize, usize) {
    let processed = estimates
        .iter()
        .filter(|e| matches!(e.status, LayerScanStatus::Slam(_)))
        .count();
    let failed = estimates
        .iter()
        .filter(|e| {
            matches!(
                e.status,
                LayerScanStatus::Slam(slamkit_lidar::icp_slam::ScanStatus::MatchFailed)
            )
        })
        .count();
    (processed, failed)
}
