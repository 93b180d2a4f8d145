//! The kidnapped drone: after the flight, the particle-filter layer choice of issue #5
//! ([`slamkit_lidar::layers::layer_pf`]) re-localises the drone with no pose prior on the
//! per-layer grid maps layered ICP-SLAM built. From a start scan in the second half of the
//! flight, the up and down range readings give the candidate layers; one Monte Carlo
//! localiser per candidate (Dellaert et al., ICRA 1999), globally initialised over that
//! layer's map, then takes the following scans with the layered estimate's pose increments as
//! its motion. The layer whose particles spread least is chosen and compared with the true
//! layer (true height over layer height), and its position with the ground truth.

use super::latest_reading;
use nalgebra::Vector2;
use serde_json::json;
use slamkit_core::Pose2;
use slamkit_lidar::layers::layer_pf::{candidate_layers, LayerLocaliser};
use slamkit_lidar::layers::{LayerScanStatus, LayeredEstimate, LayeredSlamConfig};
use slamkit_lidar::mcl::MclConfig;
use slamkit_lidar::particles::moved_enough;
use slamkit_map::OccupancyGrid;
use slamkit_sim::LidarRun;
use std::collections::BTreeMap;

/// The start scan is the first one after this share of the flight whose true layer has a map.
const START_FRACTION: f64 = 0.6;
/// Scans given to the localisers after the start, at most (keeps the default demo short).
const WINDOW_SCANS: usize = 200;
/// The position error is also reported after this many scans.
const EARLY_SCANS: usize = 50;
/// The best layer counts as converged once its particles' spread is below this \[m\].
const CONVERGED_SPREAD_M: f64 = 0.3;

/// What the re-localisation found.
pub struct LayerLocalisation {
    /// Index of the start scan.
    pub start_scan: usize,
    /// Candidate layers from the start scan's range readings (those with a map).
    pub candidates: Vec<i64>,
    /// Layer whose particles spread least at the end of the window.
    pub chosen_layer: Option<i64>,
    /// Layer of the true height at the start scan (the one the candidates are for).
    pub true_layer: i64,
    /// Layer of the true height at the last update.
    pub true_layer_end: i64,
    /// Filter updates run in the window.
    pub updates: usize,
    /// Scans until the best layer's spread first fell below [`CONVERGED_SPREAD_M`].
    pub converged_after_scans: Option<usize>,
    /// Horizontal error of the best layer's position after [`EARLY_SCANS`] scans \[m\].
    pub error_early_m: Option<f64>,
    /// Horizontal error of the best layer's position at the end of the window \[m\].
    pub error_end_m: Option<f64>,
    /// Scans from the start to the last update.
    pub scans: usize,
    /// Particles of each candidate's global initialisation.
    pub particles: Vec<usize>,
    /// Wall time of the localisers \[s\].
    pub seconds: f64,
}

/// The true layer of scan `i`.
fn true_layer(run: &LidarRun, i: usize, layer_height_m: f64) -> Option<i64> {
    let z = run.ground_truth.poses.get(i)?.pose.translation.z;
    Some((z / layer_height_m).floor() as i64)
}

/// Horizontal distance from `estimate` to the true position at scan `i`.
fn error_m(run: &LidarRun, i: usize, estimate: &Pose2) -> Option<f64> {
    let truth = run.ground_truth.poses.get(i)?.pose.translation.vector.xy();
    let position: Vector2<f64> = estimate.translation.vector;
    Some((position - truth).norm())
}

/// Runs the re-localisation on `maps` (the layer grids in the simulator's frame). `None` when
/// no scan after the start share is in a mapped layer, or its readings allow no mapped layer.
pub fn relocalise(
    run: &LidarRun,
    estimates: &[LayeredEstimate],
    maps: &BTreeMap<i64, OccupancyGrid>,
    ceiling_m: f64,
    seed: u64,
) -> Option<LayerLocalisation> {
    let started = std::time::Instant::now();
    let height = LayeredSlamConfig::default().height;
    let h = height.layer_height_m;
    let first = (run.scans.len() as f64 * START_FRACTION) as usize;
    let start = (first..run.scans.len()).find(|&i| {
        true_layer(run, i, h).is_some_and(|k| maps.contains_key(&k))
            && estimates
                .get(i)
                .is_some_and(|e| matches!(e.status, LayerScanStatus::Slam(_)))
    })?;
    let scan = run.scans.get(start)?;
    let start_estimate = estimates.get(start)?;
    let range = latest_reading(&run.ranges, scan.timestamp);
    let candidates = candidate_layers(
        maps.keys().copied(),
        range.and_then(|r| r.up_m),
        range.and_then(|r| r.down_m),
        ceiling_m,
        &height,
    );
    let config = MclConfig {
        seed,
        ..MclConfig::default()
    };
    // no candidate with a map (readings far off, e.g. over an unmapped stack): nothing to run
    let Ok(mut localiser) = LayerLocaliser::new(maps, &candidates, &config) else {
        return None;
    };
    let mut previous = start_estimate.smooth_world_from_base;
    let mut found = LayerLocalisation {
        start_scan: start,
        candidates,
        chosen_layer: None,
        true_layer: true_layer(run, start, h).unwrap_or_default(),
        true_layer_end: 0,
        updates: 0,
        converged_after_scans: None,
        error_early_m: None,
        error_end_m: None,
        scans: 0,
        particles: localiser.global_particles(),
        seconds: 0.0,
    };
    let end = (start + WINDOW_SCANS).min(run.scans.len());
    for i in start..end {
        let (Some(scan), Some(e)) = (run.scans.get(i), estimates.get(i)) else {
            break;
        };
        let increment = previous.inverse() * e.smooth_world_from_base;
        // as `run_mcl`: an update once the drone moved or turned enough (updating on every
        // scan of a hover counts the same view again and again); tilted scans cut the room at
        // a slant and are skipped, as layered ICP-SLAM skips them
        let due = i == start
            || moved_enough(
                &increment,
                config.update_linear_m,
                config.update_angular_rad,
            );
        if !due || !matches!(e.status, LayerScanStatus::Slam(_)) {
            continue;
        }
        localiser.update(&increment, scan);
        previous = e.smooth_world_from_base;
        found.updates += 1;
        let Some((layer, best)) = localiser.best() else {
            continue;
        };
        let scans = i + 1 - start;
        if found.converged_after_scans.is_none() && best.spread_m < CONVERGED_SPREAD_M {
            found.converged_after_scans = Some(scans);
        }
        let error = error_m(run, i, &best.world_from_base);
        if found.error_early_m.is_none() && scans >= EARLY_SCANS {
            found.error_early_m = error;
        }
        found.chosen_layer = Some(layer);
        found.error_end_m = error;
        found.scans = scans;
        found.true_layer_end = true_layer(run, i, h).unwrap_or_default();
    }
    found.seconds = started.elapsed().as_secs_f64();
    Some(found)
}

/// `metrics.layer_localisation` of `report.json`.
pub fn metrics_json(found: Option<&LayerLocalisation>) -> serde_json::Value {
    let Some(f) = found else {
        return serde_json::Value::Null;
    };
    json!({
        "start_scan": f.start_scan,
        "scans": f.scans,
        "candidates": f.candidates,
        "particles_per_candidate": f.particles,
        "chosen_layer": f.chosen_layer,
        "true_layer": f.true_layer,
        "true_layer_end": f.true_layer_end,
        "updates": f.updates,
        "converged_after_scans": f.converged_after_scans,
        "position_error_m": {
            format!("after_{EARLY_SCANS}_scans"): f.error_early_m,
            "end": f.error_end_m,
        },
        "seconds": f.seconds,
    })
}

/// One line for the printed table.
pub fn summary(found: Option<&LayerLocalisation>) -> String {
    let Some(f) = found else {
        return "layer choice by particles: no start scan with a mapped candidate layer".to_owned();
    };
    let opt = |v: Option<f64>| v.map_or("-".to_owned(), |v| format!("{v:.3} m"));
    format!(
        "layer choice by particles: layer {} (true {}) of {} candidates, converged after {} \
         scans, error {} after {EARLY_SCANS} scans, {} after {}",
        f.chosen_layer.map_or("-".to_owned(), |k| k.to_string()),
        f.true_layer,
        f.candidates.len(),
        f.converged_after_scans
            .map_or("-".to_owned(), |n| n.to_string()),
        opt(f.error_early_m),
        opt(f.error_end_m),
        f.scans,
    )
}
