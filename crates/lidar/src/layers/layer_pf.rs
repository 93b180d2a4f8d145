//! Which height layer is the drone in? The seed method's particle-filter variant: particles are
//! initialised in every layer the up and down range finders allow, each layer's particles are
//! weighted by the scans against that layer's map, and the layer whose particles spread least
//! is picked.
//!
//! The range finders bound the height without knowing what is under or over the drone: the
//! surface below is at or above the floor, so the base is at least `down + down_offset` high;
//! the surface above is at or below the ceiling, so the base is at most
//! `ceiling − up − up_offset`. Every mapped layer whose height span meets that interval is a
//! candidate. Each candidate starts a hypothesis: Monte Carlo localisation ([`crate::mcl`],
//! globally initialised over the candidate's map) on the same scans and motion increments. The
//! height tracker knows the layer changes, not the layer: when it climbs or descends `n`
//! layers, every hypothesis's particles move to the map `n` layers up or down (as the seed's
//! layered filter re-enters layers), so a hypothesis is "the drone started in layer `k`" and
//! the run may cross layers; while a hypothesis's layer has no map its particles are not
//! weighted and spread with the motion noise. The layer whose map explains the scans gathers
//! its particles, the others stay spread (their maps lack what the scan sees, or are
//! ambiguous).
//!
//! The spread compared is the particles' RMS distance to their mean after each update's
//! resampling ([`Mcl::spread_m`]), averaged over all of the hypothesis's updates: one update
//! can gather a cloud by chance, a map that explains the scans gathers it early and keeps it
//! gathered. The likelihood is tempered ([`LayerPfConfig`]) so that the clouds gather over
//! several updates rather than on the first.

use super::height::HeightConfig;
use crate::mcl::{Mcl, MclConfig, MclEstimate, MclMap};
use crate::LidarError;
use serde::{Deserialize, Serialize};
use slamkit_core::{LaserScan, Pose2};
use slamkit_map::OccupancyGrid;
use std::collections::BTreeMap;
use std::sync::Arc;

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

/// Settings of the multi-layer localiser.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LayerPfConfig {
    /// Monte Carlo localisation in each hypothesis's layer. Its defaults differ from
    /// [`MclConfig::default`] in two fields. `likelihood_gain` 30 instead of 3: a particle at
    /// the capture radius, whose beams end about 0.2 m from the walls (−0.5 nat each under
    /// `sigma_hit_m` 0.2 m), loses 1 nat per update over 60 beams instead of 10, so one update
    /// of a global initialisation no longer puts all the weight on a few particles (with 3
    /// every layer's cloud had gathered to 0.01–0.1 m after one update, in every layer alike).
    /// `tracking_particles` equal to `max_particles`: a hypothesis keeps its global count, a
    /// wrong layer's cloud is not cut to a few hundred particles on a chance gathering.
    pub mcl: MclConfig,
}

impl Default for LayerPfConfig {
    fn default() -> Self {
        let mcl = MclConfig::default();
        Self {
            mcl: MclConfig {
                likelihood_gain: 30.0,
                tracking_particles: mcl.max_particles,
                ..mcl
            },
        }
    }
}

/// Why the multi-layer localiser could not start.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LayerPfError {
    /// None of the candidate layers has a map to localise in.
    #[error("none of the candidate layers {candidates:?} has a map")]
    NoMappedCandidate {
        /// The candidates asked for.
        candidates: Vec<i64>,
    },
    /// A layer's map or the localisation settings were refused.
    #[error("layer {layer}: {source}")]
    Layer {
        /// The layer whose map was refused.
        layer: i64,
        /// Why.
        #[source]
        source: LidarError,
    },
}

/// One hypothesis on the drone's layer: particles in the map of the layer it started in,
/// carried to the map of the layer as far above or below as the height tracker climbs or
/// descends.
struct Hypothesis {
    start_layer: i64,
    layer: i64,
    /// True when `layer` has a map.
    mapped: bool,
    mcl: Mcl,
    /// Sum of the spreads after its updates \[m\].
    spread_sum_m: f64,
    /// Spread after its latest update \[m\].
    spread_now_m: f64,
    /// Updates run.
    updates: usize,
    estimate: Option<MclEstimate>,
}

/// A layer hypothesis as it stands.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LayerHypothesis {
    /// Candidate layer it started in.
    pub start_layer: i64,
    /// Layer it is in now.
    pub layer: i64,
    /// True when that layer has a map (else its particles were last weighted in another).
    pub mapped: bool,
    /// Mean spread of its particles over its updates, each taken after the update's
    /// resampling \[m\].
    pub spread_m: f64,
    /// Spread of its particles after its latest update \[m\].
    pub spread_now_m: f64,
    /// Its latest estimate.
    pub estimate: MclEstimate,
}

/// One Monte Carlo localiser per candidate layer, run side by side; each follows the height
/// tracker's layer changes through the layer maps.
pub struct LayerLocaliser {
    maps: BTreeMap<i64, Arc<MclMap>>,
    hypotheses: Vec<Hypothesis>,
}

impl LayerLocaliser {
    /// Particles spread over the map of every layer in `candidates` (layers without a map in
    /// `maps` are left out). Fails when no candidate has a map, or a map or the settings are
    /// refused.
    pub fn new(
        maps: &BTreeMap<i64, OccupancyGrid>,
        candidates: &[i64],
        config: &LayerPfConfig,
    ) -> Result<Self, LayerPfError> {
        let prepared = maps
            .iter()
            .map(|(&layer, map)| {
                MclMap::new(map, &config.mcl.likelihood)
                    .map(|m| (layer, Arc::new(m)))
                    .map_err(|source| LayerPfError::Layer { layer, source })
            })
            .collect::<Result<BTreeMap<_, _>, _>>()?;
        let hypotheses = candidates
            .iter()
            .filter_map(|&layer| prepared.get(&layer).map(|map| (layer, map)))
            .map(|(layer, map)| {
                let mcl = MclConfig {
                    seed: config.mcl.seed.wrapping_add(layer as u64),
                    ..config.mcl.clone()
                };
                Mcl::on_map(Arc::clone(map), mcl)
                    .map(|mcl| Hypothesis {
                        start_layer: layer,
                        layer,
                        mapped: true,
                        mcl,
                        spread_sum_m: 0.0,
                        spread_now_m: 0.0,
                        updates: 0,
                        estimate: None,
                    })
                    .map_err(|source| LayerPfError::Layer { layer, source })
            })
            .collect::<Result<Vec<_>, _>>()?;
        if hypotheses.is_empty() {
            return Err(LayerPfError::NoMappedCandidate {
                candidates: candidates.to_vec(),
            });
        }
        Ok(Self {
            maps: prepared,
            hypotheses,
        })
    }

    /// Moves every hypothesis's particles by the motion `increment` (previous base from
    /// current) and `layer_change` layers up (down when negative), as the height tracker
    /// changed layer since the last update, and weights them by `scan` in the map of its
    /// layer. A hypothesis whose layer has no map (the maps do not reach the height it puts
    /// the drone at) is not weighted: its particles spread with the motion noise until it
    /// reaches a mapped layer again.
    pub fn update(&mut self, increment: &Pose2, layer_change: i64, scan: &LaserScan) {
        for h in &mut self.hypotheses {
            h.layer += layer_change;
            let map = self.maps.get(&h.layer);
            // all maps were prepared for the filters' sensor model: the move cannot fail, and
            // if it did the hypothesis would coast as over an unmapped layer
            h.mapped = map
                .is_some_and(|map| layer_change == 0 || h.mcl.move_to_map(Arc::clone(map)).is_ok());
            h.mcl.predict(increment);
            if h.mapped {
                let Some(estimate) = h.mcl.correct(scan) else {
                    continue;
                };
                h.estimate = Some(estimate);
            } else if let Some(e) = &mut h.estimate {
                e.world_from_base *= increment;
            }
            h.spread_now_m = h.mcl.spread_m();
            h.spread_sum_m += h.spread_now_m;
            h.updates += 1;
        }
    }

    /// Particles of each candidate layer's global initialisation, in layer order.
    pub fn global_particles(&self) -> Vec<usize> {
        self.hypotheses
            .iter()
            .map(|h| h.mcl.stats().global_particles)
            .collect()
    }

    /// Every hypothesis that has an estimate, in the order of their start layers.
    pub fn hypotheses(&self) -> Vec<LayerHypothesis> {
        self.hypotheses
            .iter()
            .filter_map(|h| {
                let estimate = h.estimate?;
                let spread_m = h.spread_sum_m / h.updates.max(1) as f64;
                Some(LayerHypothesis {
                    start_layer: h.start_layer,
                    layer: h.layer,
                    mapped: h.mapped,
                    spread_m,
                    spread_now_m: h.spread_now_m,
                    estimate,
                })
            })
            .collect()
    }

    /// The hypothesis whose particles spread least.
    pub fn best(&self) -> Option<LayerHypothesis> {
        self.hypotheses()
            .into_iter()
            .min_by(|a, b| a.spread_m.total_cmp(&b.spread_m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim_scan::SegmentWorld;
    use nalgebra::Vector2;
    use slamkit_map::OccupancyGridConfig;
    use std::f64::consts::PI;

    /// An occupancy grid of `world` from scans at the poses `(x, y, yaw)`.
    fn grid_of(world: &SegmentWorld, poses: &[(f64, f64, f64)]) -> OccupancyGrid {
        let mut grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
        for &(x, y, yaw) in poses {
            let pose = Pose2::new(Vector2::new(x, y), yaw);
            let scan = world.scan(&pose, 360, 1.5 * PI, 8.0);
            grid.insert_scan(&scan, &pose).unwrap();
        }
        grid
    }

    /// Poses that see all of the test room.
    const ROOM_POSES: [(f64, f64, f64); 8] = [
        (-4.0, -2.0, 0.0),
        (0.0, -2.5, 1.0),
        (4.0, -2.0, 2.0),
        (4.0, 2.5, 3.0),
        (0.0, 2.5, -2.5),
        (-4.0, 2.0, -1.0),
        (-4.5, 0.0, 0.5),
        (2.5, 0.8, -0.5),
    ];

    /// The room with a crate in its lower slice.
    fn low_room() -> SegmentWorld {
        let mut low = SegmentWorld::room();
        let crate_box = [(3.0, -2.5), (3.8, -2.5), (3.8, -1.7), (3.0, -1.7)];
        low.segments
            .extend(SegmentWorld::polygon(&crate_box).segments);
        low
    }

    /// The map of a 40 m long, 2 m wide corridor: a scan of the room fits it nowhere well, and
    /// anywhere along it equally badly.
    fn corridor_map() -> OccupancyGrid {
        let corridor =
            SegmentWorld::polygon(&[(-20.0, -1.0), (20.0, -1.0), (20.0, 1.0), (-20.0, 1.0)]);
        let poses: Vec<(f64, f64, f64)> = (-3..=3)
            .flat_map(|k| {
                [
                    (5.0 * f64::from(k), 0.0, 0.0),
                    (5.0 * f64::from(k), 0.0, 3.1),
                ]
            })
            .collect();
        grid_of(&corridor, &poses)
    }

    /// A gentle path through the room, 0.08 m per step.
    fn path(steps: i32) -> Vec<Pose2> {
        (0..steps)
            .map(|k| {
                let s = f64::from(k) * 0.08;
                Pose2::new(Vector2::new(-4.0 + s, -1.5 + 0.3 * s.sin()), 0.1 * s)
            })
            .collect()
    }

    fn config(seed: u64) -> LayerPfConfig {
        let mut config = LayerPfConfig::default();
        config.mcl.seed = seed;
        config
    }

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

    #[test]
    fn range_readings_bound_the_candidate_layers() {
        let h = HeightConfig::default();
        // over a 0.2 m crate (down 0.1 m), 1 m under a 2 m ceiling: heights 0.13 to 0.97 m
        let layers = candidate_layers([2, 6, 12, 19, 20, 30], Some(1.0), Some(0.1), 2.0, &h);
        assert_eq!(layers, vec![2, 6, 12, 19]);
        // no up reading: no upper bound; a NaN down reading: no lower bound
        assert_eq!(
            candidate_layers([2, 30], None, Some(0.1), 2.0, &h),
            vec![2, 30]
        );
        assert_eq!(
            candidate_layers([2, 30], Some(1.0), Some(f64::NAN), 2.0, &h),
            vec![2]
        );
    }

    #[test]
    fn the_particle_filter_picks_the_layer_whose_particles_gather() {
        // layer 6 (0.30 m) holds the room with its boxes and a crate; layers 12 and 30 the
        // corridor (partitions higher up)
        let low = low_room();
        let maps: BTreeMap<i64, _> = [
            (6, grid_of(&low, &ROOM_POSES)),
            (12, corridor_map()),
            (30, corridor_map()),
        ]
        .into_iter()
        .collect();
        // down 0.1 m over a crate, up 1.0 m under a 2 m ceiling: layers 6 and 12, not 30
        let h = HeightConfig::default();
        let candidates = candidate_layers(maps.keys().copied(), Some(1.0), Some(0.1), 2.0, &h);
        assert_eq!(candidates, vec![6, 12]);
        let mut localiser = LayerLocaliser::new(&maps, &candidates, &config(3)).unwrap();
        let path = path(60);
        let mut previous = path[0];
        for pose in &path {
            let scan = low.scan(pose, 360, 1.5 * PI, 8.0);
            localiser.update(&(previous.inverse() * pose), 0, &scan);
            previous = *pose;
        }
        let best = localiser.best().unwrap();
        let spreads: Vec<f64> = localiser.hypotheses().iter().map(|h| h.spread_m).collect();
        assert_eq!(
            (best.start_layer, best.layer),
            (6, 6),
            "spreads {spreads:?}"
        );
        let error =
            (best.estimate.world_from_base.translation.vector - previous.translation.vector).norm();
        assert!(error < 0.2, "error {error} m, spreads {spreads:?}");
        assert!(spreads[1] > 2.0 * spreads[0], "spreads {spreads:?}");
    }

    #[test]
    fn hypotheses_follow_the_height_trackers_layer_changes() {
        // layer 6 is the room with the crate, layer 7 (above the crate) the room without it,
        // layer 12 the corridor, and nothing is mapped above it: the drone climbs from layer 6
        // to 7 half way, the hypothesis of layer 6 follows into layer 7's map, the one of
        // layer 12 leaves the maps (its particles are no longer weighted)
        let (low, high) = (low_room(), SegmentWorld::room());
        let maps: BTreeMap<i64, _> = [
            (6, grid_of(&low, &ROOM_POSES)),
            (7, grid_of(&high, &ROOM_POSES)),
            (12, corridor_map()),
        ]
        .into_iter()
        .collect();
        let mut localiser = LayerLocaliser::new(&maps, &[6, 12], &config(5)).unwrap();
        let path = path(80);
        let mut previous = path[0];
        for (k, pose) in path.iter().enumerate() {
            let (world, change) = match k {
                0..=39 => (&low, 0),
                40 => (&high, 1),
                _ => (&high, 0),
            };
            let scan = world.scan(pose, 360, 1.5 * PI, 8.0);
            localiser.update(&(previous.inverse() * pose), change, &scan);
            previous = *pose;
            let hypotheses = localiser.hypotheses();
            let layers: Vec<(i64, i64, bool)> = hypotheses
                .iter()
                .map(|h| (h.start_layer, h.layer, h.mapped))
                .collect();
            let expected = if k < 40 {
                vec![(6, 6, true), (12, 12, true)]
            } else {
                vec![(6, 7, true), (12, 13, false)]
            };
            assert_eq!(layers, expected, "step {k}");
        }
        let best = localiser.best().unwrap();
        let error =
            (best.estimate.world_from_base.translation.vector - previous.translation.vector).norm();
        assert_eq!((best.start_layer, best.layer), (6, 7));
        assert!(error < 0.2, "error {error} m");
    }

    #[test]
    fn the_tempered_likelihood_keeps_the_cloud_spread_after_one_update() {
        // one scan in the room against its own map: with MCL's own likelihood gain of 3 the
        // weight goes to the few particles nearest the pose, with the localiser's 30 the cloud
        // keeps the places that explain the scan about as well
        let maps: BTreeMap<i64, _> = [(6, grid_of(&low_room(), &ROOM_POSES))]
            .into_iter()
            .collect();
        let scan = low_room().scan(&path(1)[0], 360, 1.5 * PI, 8.0);
        let spread = |mcl: MclConfig| {
            let config = LayerPfConfig { mcl };
            let mut localiser = LayerLocaliser::new(&maps, &[6], &config).unwrap();
            localiser.update(&Pose2::identity(), 0, &scan);
            localiser.hypotheses()[0].spread_now_m
        };
        let sharp = spread(MclConfig::default());
        let tempered = spread(LayerPfConfig::default().mcl);
        eprintln!("spread after one update: gain 3 {sharp} m, gain 30 {tempered} m");
        assert!(sharp < 0.3 && tempered > 1.0, "{sharp} {tempered}");
    }

    #[test]
    fn no_mapped_candidate_and_bad_settings_are_errors_not_panics() {
        let maps: BTreeMap<i64, _> = [(6, grid_of(&low_room(), &ROOM_POSES))]
            .into_iter()
            .collect();
        assert!(matches!(
            LayerLocaliser::new(&maps, &[7, 8], &config(1)),
            Err(LayerPfError::NoMappedCandidate { candidates }) if candidates == vec![7, 8]
        ));
        let mut bad = config(1);
        bad.mcl.beams = 0;
        assert!(matches!(
            LayerLocaliser::new(&maps, &[6], &bad),
            Err(LayerPfError::Layer { layer: 6, .. })
        ));
        // an empty map (no free cell) is named by its layer
        let empty = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
        let maps: BTreeMap<i64, _> = [(9, empty)].into_iter().collect();
        assert!(matches!(
            LayerLocaliser::new(&maps, &[6], &config(1)),
            Err(LayerPfError::Layer { layer: 9, .. })
        ));
    }
}
