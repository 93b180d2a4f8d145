//! The kidnapped-drone check of the simulated flight (`slamkit demo`): after the flight, the
//! particle-filter layer choice ([`super::layer_choice`]) re-localises the drone with no pose
//! prior on the per-layer grid maps layered ICP-SLAM built, from a start scan in the second
//! half of the flight to its end. The chosen start layer is compared with the true layer (true
//! height over layer height) at the start, its layer at the end with the true one then, and its
//! position with the ground truth. Like the simulated closed loop, it scores against the
//! simulator's truth, which the localiser never sees.

use super::layer_choice::LayerChoice;
use super::ScanRecord;
use nalgebra::Vector2;
use serde_json::json;
use slamkit_core::Pose2;
use slamkit_lidar::layers::height::HeightConfig;
use slamkit_lidar::layers::layer_pf::{LayerHypothesis, LayerPfConfig, LayerPfError};
use slamkit_lidar::layers::LayerScanStatus;
use slamkit_map::OccupancyGrid;
use slamkit_sim::LidarRun;
use std::collections::BTreeMap;

/// The start scan is the first one after this share of the flight whose true layer has a map.
pub const START_FRACTION: f64 = 0.6;
/// The position error is also reported after this many scans.
pub const EARLY_SCANS: usize = 50;
/// The best hypothesis counts as converged once its particles' spread after an update is below
/// this \[m\].
pub const CONVERGED_SPREAD_M: f64 = 0.3;

/// What the re-localisation found.
pub struct LayerLocalisation {
    /// Index of the start scan.
    pub start_scan: usize,
    /// Candidate layers from the start scan's range readings (those with a map).
    pub candidates: Vec<i64>,
    /// Every hypothesis after the last update, with its horizontal error \[m\].
    pub hypotheses: Vec<(LayerHypothesis, Option<f64>)>,
    /// The hypothesis whose particles spread least (mean over its updates) at the end.
    pub chosen: Option<LayerHypothesis>,
    /// Layer of the true height at the start scan (the one the candidates are for).
    pub true_layer: i64,
    /// Layer of the true height at the last update.
    pub true_layer_end: i64,
    /// Filter updates run.
    pub updates: usize,
    /// Scans until the best hypothesis's spread first fell below [`CONVERGED_SPREAD_M`].
    pub converged_after_scans: Option<usize>,
    /// Horizontal error of the best hypothesis's position after [`EARLY_SCANS`] scans \[m\].
    pub error_early_m: Option<f64>,
    /// Horizontal error of the best hypothesis's position at the last update \[m\].
    pub error_end_m: Option<f64>,
    /// Scans from the start to the last update.
    pub scans: usize,
    /// Particles of each candidate's global initialisation.
    pub particles: Vec<usize>,
    /// Wall time of the localisers \[s\].
    pub seconds: f64,
}

/// Why the re-localisation did not run.
pub enum NotRun {
    /// No scan after the start share is matched in a layer that has a map.
    NoStartScan,
    /// The start scan's readings allow no layer with a map.
    NoMappedCandidate(Vec<i64>),
    /// The localiser refused a map or its settings.
    Failed(LayerPfError),
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

/// The localiser's settings: the published defaults with the demo's seed.
fn config(seed: u64) -> LayerPfConfig {
    let mut config = LayerPfConfig::default();
    config.mcl.seed = seed;
    config
}

/// The first scan after [`START_FRACTION`] of the flight matched in a layer whose true layer
/// has a map.
fn start_scan(
    run: &LidarRun,
    scans: &[ScanRecord],
    maps: &BTreeMap<i64, OccupancyGrid>,
    layer_height_m: f64,
) -> Option<usize> {
    let first = (run.scans.len() as f64 * START_FRACTION) as usize;
    (first..run.scans.len()).find(|&i| {
        true_layer(run, i, layer_height_m).is_some_and(|k| maps.contains_key(&k))
            && scans.get(i).is_some_and(|s| {
                s.estimate.layer.is_some() && matches!(s.estimate.status, LayerScanStatus::Slam(_))
            })
    })
}

/// Runs the layer choice on `maps` (the layer grids in the simulator's frame), with the layers
/// and range-finder offsets of `height` (those layered ICP-SLAM ran with), from the start
/// scan to the end of the flight, noting the best hypothesis after each update.
pub fn relocalise(
    run: &LidarRun,
    scans: &[ScanRecord],
    maps: &BTreeMap<i64, OccupancyGrid>,
    height: &HeightConfig,
    ceiling_m: f64,
    seed: u64,
) -> Result<LayerLocalisation, NotRun> {
    let started = std::time::Instant::now();
    let h = height.layer_height_m;
    let start = start_scan(run, scans, maps, h).ok_or(NotRun::NoStartScan)?;
    let range = scans.get(start).ok_or(NotRun::NoStartScan)?.range;
    let mut choice = match LayerChoice::new(maps, range, ceiling_m, height, config(seed)) {
        Ok(c) => c,
        Err(LayerPfError::NoMappedCandidate { candidates }) => {
            return Err(NotRun::NoMappedCandidate(candidates))
        }
        Err(e) => return Err(NotRun::Failed(e)),
    };
    let mut found = LayerLocalisation {
        start_scan: start,
        candidates: choice.candidates().to_vec(),
        hypotheses: Vec::new(),
        chosen: None,
        true_layer: true_layer(run, start, h).unwrap_or_default(),
        true_layer_end: 0,
        updates: 0,
        converged_after_scans: None,
        error_early_m: None,
        error_end_m: None,
        scans: 0,
        particles: choice.global_particles(),
        seconds: 0.0,
    };
    let mut last = None;
    for (i, (scan, record)) in run.scans.iter().zip(scans).enumerate().skip(start) {
        if choice.push(scan, &record.estimate) {
            last = Some(i);
            note(run, i, choice.best(), &mut found);
        }
    }
    found.updates = choice.updates();
    if let Some(last) = last {
        found.true_layer_end = true_layer(run, last, h).unwrap_or_default();
        found.hypotheses = choice
            .hypotheses()
            .into_iter()
            .map(|hyp| (hyp, error_m(run, last, &hyp.estimate.world_from_base)))
            .collect();
    }
    found.seconds = started.elapsed().as_secs_f64();
    Ok(found)
}

/// Notes `best`, the best hypothesis after the update at scan `i`.
fn note(run: &LidarRun, i: usize, best: Option<LayerHypothesis>, found: &mut LayerLocalisation) {
    let Some(best) = best else {
        return;
    };
    let scans = i + 1 - found.start_scan;
    if found.converged_after_scans.is_none() && best.spread_now_m < CONVERGED_SPREAD_M {
        found.converged_after_scans = Some(scans);
    }
    let error = error_m(run, i, &best.estimate.world_from_base);
    if found.error_early_m.is_none() && scans >= EARLY_SCANS {
        found.error_early_m = error;
    }
    found.chosen = Some(best);
    found.error_end_m = error;
    found.scans = scans;
}

/// `metrics.layer_localisation` of `report.json`.
pub fn metrics_json(found: Result<&LayerLocalisation, &NotRun>) -> serde_json::Value {
    let f = match found {
        Ok(f) => f,
        Err(NotRun::Failed(e)) => return json!({ "error": e.to_string() }),
        Err(why) => return json!({ "not_run": reason(why) }),
    };
    let hypotheses: Vec<_> = f
        .hypotheses
        .iter()
        .map(|(hyp, error)| {
            json!({
                "start_layer": hyp.start_layer,
                "layer": hyp.layer,
                "spread_m": hyp.spread_m,
                "spread_now_m": hyp.spread_now_m,
                "mapped": hyp.mapped,
                "particles": hyp.estimate.particles,
                "position_error_m": error,
            })
        })
        .collect();
    json!({
        "start_scan": f.start_scan,
        "scans": f.scans,
        "candidates": f.candidates,
        "particles_per_candidate": f.particles,
        "chosen_layer": f.chosen.map(|c| c.start_layer),
        "chosen_layer_end": f.chosen.map(|c| c.layer),
        "true_layer": f.true_layer,
        "true_layer_end": f.true_layer_end,
        "updates": f.updates,
        "converged_after_scans": f.converged_after_scans,
        "position_error_m": {
            format!("after_{EARLY_SCANS}_scans"): f.error_early_m,
            "end": f.error_end_m,
        },
        "hypotheses": hypotheses,
        "seconds": f.seconds,
    })
}

/// Why it did not run, in words.
fn reason(why: &NotRun) -> String {
    match why {
        NotRun::NoStartScan => "no start scan in a mapped layer".to_owned(),
        NotRun::NoMappedCandidate(c) => format!("no candidate layer with a map ({c:?})"),
        NotRun::Failed(e) => format!("failed: {e}"),
    }
}

/// One line for the printed table.
pub fn summary(found: Result<&LayerLocalisation, &NotRun>) -> String {
    let f = match found {
        Ok(f) => f,
        Err(why) => return format!("layer choice by particles: {}", reason(why)),
    };
    let opt = |v: Option<f64>| v.map_or("-".to_owned(), |v| format!("{v:.3} m"));
    let layer = |v: Option<i64>| v.map_or("-".to_owned(), |k| k.to_string());
    format!(
        "layer choice by particles: layer {} (true {}) of {} candidates, at the end {} (true {}), \
         converged after {} scans, error {} after {EARLY_SCANS} scans, {} after {}",
        layer(f.chosen.map(|c| c.start_layer)),
        f.true_layer,
        f.candidates.len(),
        layer(f.chosen.map(|c| c.layer)),
        f.true_layer_end,
        f.converged_after_scans
            .map_or("-".to_owned(), |n| n.to_string()),
        opt(f.error_early_m),
        opt(f.error_end_m),
        f.scans,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_core::Trajectory;

    #[test]
    fn without_a_mapped_layer_it_says_why_it_did_not_run() {
        let run = LidarRun {
            scans: vec![],
            ranges: vec![],
            attitudes: vec![],
            flows: vec![],
            ground_truth: Trajectory::new(),
        };
        let found = relocalise(
            &run,
            &[],
            &BTreeMap::new(),
            &HeightConfig::default(),
            2.5,
            1,
        );
        assert!(matches!(found, Err(NotRun::NoStartScan)));
        let found = found.as_ref();
        let json = metrics_json(found);
        assert_eq!(json["not_run"], "no start scan in a mapped layer");
        assert_eq!(
            summary(found),
            "layer choice by particles: no start scan in a mapped layer"
        );
    }
}
