//! The kidnapped drone: re-localising with no pose prior in the per-layer grid maps, by the
//! particle-filter layer choice ([`slamkit_lidar::layers::layer_pf`]). The up and down range
//! readings at a start scan give the candidate layers; one Monte Carlo localiser per candidate
//! (Dellaert et al., ICRA 1999), globally initialised over that layer's map, then takes the
//! following scans with the layered estimate's pose increments as its motion and the height
//! tracker's layer changes as its climbs and descents. The hypothesis whose particles spread
//! least is the choice.

use slamkit_core::observation::RangePair;
use slamkit_core::{LaserScan, Pose2};
use slamkit_lidar::layers::height::HeightConfig;
use slamkit_lidar::layers::layer_pf::{
    candidate_layers, LayerHypothesis, LayerLocaliser, LayerPfConfig, LayerPfError,
};
use slamkit_lidar::layers::{LayerScanStatus, LayeredEstimate};
use slamkit_lidar::particles::moved_enough;
use slamkit_map::OccupancyGrid;
use std::collections::BTreeMap;

/// The layer choice running from a start scan.
///
/// ```
/// use slamkit_lidar::layers::height::HeightConfig;
/// use slamkit_lidar::layers::layer_pf::{LayerPfConfig, LayerPfError};
/// use slamkit_slam::drone::layer_choice::LayerChoice;
/// use std::collections::BTreeMap;
///
/// // no layer has a map: nothing to choose from
/// let none = LayerChoice::new(&BTreeMap::new(), None, 2.5, &HeightConfig::default(),
///     LayerPfConfig::default());
/// assert!(matches!(none, Err(LayerPfError::NoMappedCandidate { .. })));
/// ```
pub struct LayerChoice {
    localiser: LayerLocaliser,
    config: LayerPfConfig,
    candidates: Vec<i64>,
    /// Planar pose and layer of the last update (or the start).
    previous: Option<(Pose2, i64)>,
    updates: usize,
}

impl LayerChoice {
    /// Candidates from the start scan's `range` pair among the layers of `maps` (grids of the
    /// layered maps, `height` the settings they were made with, `ceiling_m` the room's height),
    /// one localiser over each candidate's map.
    pub fn new(
        maps: &BTreeMap<i64, OccupancyGrid>,
        range: Option<RangePair>,
        ceiling_m: f64,
        height: &HeightConfig,
        config: LayerPfConfig,
    ) -> Result<Self, LayerPfError> {
        let candidates = candidate_layers(
            maps.keys().copied(),
            range.and_then(|r| r.up_m),
            range.and_then(|r| r.down_m),
            ceiling_m,
            height,
        );
        let localiser = LayerLocaliser::new(maps, &candidates, &config)?;
        Ok(Self {
            localiser,
            config,
            candidates,
            previous: None,
            updates: 0,
        })
    }

    /// The candidate layers.
    pub fn candidates(&self) -> &[i64] {
        &self.candidates
    }

    /// Particles of each candidate's global initialisation.
    pub fn global_particles(&self) -> Vec<usize> {
        self.localiser.global_particles()
    }

    /// Takes the next scan (the start scan first) with its layered estimate; returns true when
    /// the localisers updated. An update is due at the start scan and then once the drone
    /// moved or turned enough (updating on every scan of a hover counts the same view again
    /// and again); scans without a layer or not matched (tilted: they cut the room at a slant)
    /// are skipped, as layered SLAM skips them.
    pub fn push(&mut self, scan: &LaserScan, estimate: &LayeredEstimate) -> bool {
        let pose = estimate.smooth_world_from_base;
        let start = self.previous.is_none();
        let previous = *self
            .previous
            .get_or_insert((pose, estimate.layer.unwrap_or_default()));
        let increment = previous.0.inverse() * pose;
        let mcl = &self.config.mcl;
        let due = start || moved_enough(&increment, mcl.update_linear_m, mcl.update_angular_rad);
        let matched = matches!(estimate.status, LayerScanStatus::Slam(_));
        let (Some(layer), true, true) = (estimate.layer, matched, due) else {
            return false;
        };
        self.localiser.update(&increment, layer - previous.1, scan);
        self.previous = Some((pose, layer));
        self.updates += 1;
        true
    }

    /// Localiser updates run.
    pub fn updates(&self) -> usize {
        self.updates
    }

    /// The hypothesis whose particles spread least, after the last update.
    pub fn best(&self) -> Option<LayerHypothesis> {
        self.localiser.best()
    }

    /// Every hypothesis after the last update.
    pub fn hypotheses(&self) -> Vec<LayerHypothesis> {
        self.localiser.hypotheses()
    }
}
