//! Which height layer is the drone in? The seed method's particle-filter variant: particles are
//! initialised in every layer the up and down range finders allow, each layer's particles are
//! weighted by the scans against that layer's map, and the layer whose particles spread least
//! is picked.
//!
//! The range finders bound the height without knowing what is under or over the drone: the
//! surface below is at or above the floor, so the base is at least `down + down_offset` high;
//! the surface above is at or below the ceiling, so the base is at most
//! `ceiling − up − up_offset`. Every mapped layer whose height span meets that interval is a
//! candidate. Each candidate runs Monte Carlo localisation ([`crate::mcl`], globally
//! initialised over its map) on the same scans and motion increments; the layer whose map
//! explains the scans gathers its particles, the others stay spread (their maps lack what the
//! scan sees, or are ambiguous). The spread is the particles' RMS distance to their weighted
//! mean ([`MclEstimate::spread_m`]).

use super::height::HeightConfig;
use crate::mcl::{Mcl, MclConfig, MclEstimate};
use crate::LidarError;
use slamkit_core::{LaserScan, Pose2};
use slamkit_map::OccupancyGrid;
use std::collections::BTreeMap;

/// The layers among `mapped` whose height span `[k, k + 1) · layer_height_m` meets the heights
/// the range readings allow under a ceiling at `ceiling_m` (heights above the floor \[m\]). A
/// missing or non-finite reading does not bound its side; bounds that cross (noisy readings)
/// are taken the other way round.
pub fn candidate_layers(
    mapped: impl IntoIterator<Item = i64>,
    up_m: Option<f64>,
    down_m: Option<f64>,
    ceiling_m: f64,
    height: &HeightConfig,
) -> Vec<i64> {
    let ok = |r: Option<f64>| r.filter(|v| v.is_finite() && *v >= 0.0);
    let lowest = ok(down_m).map_or(f64::NEG_INFINITY, |d| d + height.down_offset_m);
    let highest = ok(up_m).map_or(f64::INFINITY, |u| ceiling_m - u - height.up_offset_m);
    // readings that disagree by their noise (or a tilt, which lengthens both) can put the
    // lower bound above the upper one: the height is then between them
    let (lowest, highest) = (lowest.min(highest), lowest.max(highest));
    let h = height.layer_height_m;
    mapped
        .into_iter()
        .filter(|&k| {
            let bottom = k as f64 * h;
            bottom <= highest && bottom + h >= lowest
        })
        .collect()
}

/// One Monte Carlo localiser per candidate layer, run side by side.
pub struct LayerLocaliser {
    filters: Vec<(i64, Mcl)>,
    latest: BTreeMap<i64, MclEstimate>,
}

impl LayerLocaliser {
    /// Particles spread over the map of every layer in `candidates` (layers without a map in
    /// `maps` are left out). Fails when no candidate has a map, or a map has no free space.
    pub fn new(
        maps: &BTreeMap<i64, OccupancyGrid>,
        candidates: &[i64],
        config: &MclConfig,
    ) -> Result<Self, LidarError> {
        let filters = candidates
            .iter()
            .filter_map(|k| maps.get(k).map(|map| (*k, map)))
            .map(|(k, map)| Mcl::new(map, config.clone()).map(|mcl| (k, mcl)))
            .collect::<Result<Vec<_>, _>>()?;
        if filters.is_empty() {
            return Err(LidarError::TooFewPoints { got: 0, min: 1 });
        }
        Ok(Self {
            filters,
            latest: BTreeMap::new(),
        })
    }

    /// Moves every layer's particles by the motion `increment` (previous base from current)
    /// and weights them by `scan`.
    pub fn update(&mut self, increment: &Pose2, scan: &LaserScan) {
        for (layer, mcl) in &mut self.filters {
            mcl.predict(increment);
            if let Some(estimate) = mcl.correct(scan) {
                self.latest.insert(*layer, estimate);
            }
        }
    }

    /// Particles of each candidate layer's global initialisation, in layer order.
    pub fn global_particles(&self) -> Vec<usize> {
        self.filters
            .iter()
            .map(|(_, mcl)| mcl.stats().global_particles)
            .collect()
    }

    /// The latest estimate of every candidate layer that has one.
    pub fn estimates(&self) -> &BTreeMap<i64, MclEstimate> {
        &self.latest
    }

    /// The layer whose particles spread least, with its estimate.
    pub fn best(&self) -> Option<(i64, MclEstimate)> {
        self.latest
            .iter()
            .min_by(|a, b| a.1.spread_m.total_cmp(&b.1.spread_m))
            .map(|(k, e)| (*k, *e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossing_bounds_still_give_the_layer_between_them() {
        let h = HeightConfig::default();
        // 1 m ceiling, true height 0.40 m: down 0.371 (+0.03 = 0.401), up 0.571 (0.399 max)
        let layers = candidate_layers(0..20, Some(0.571), Some(0.371), 1.0, &h);
        assert_eq!(layers, vec![7, 8]);
        // consistent readings: 0.32 to 0.33 m is layer 6 only
        let layers = candidate_layers(0..20, Some(0.64), Some(0.29), 1.0, &h);
        assert_eq!(layers, vec![6]);
    }
}
