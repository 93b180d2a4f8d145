//! A drone session in a saved map ([`super::DroneSlam::localise`], [`super::DroneSlam::resume`]):
//! until the drone is found, each usable scan (a height known, not tilted) is searched for in
//! the keyframes of the layers near its height ([`GlobalSearch`]: Olson's correlative search
//! over the whole map, refined by ICP, refused when two distinct poses fit as well); once found,
//! the layered mapper starts in the saved layers at that pose
//! ([`slamkit_lidar::layers::LayeredIcpSlam::start_in_saved_map`]).
//!
//! The layers are those of the height above the floor, so the drone must fly over the floor the
//! map was made from (the map frame's z = 0).

use super::map::DroneMap;
use crate::SlamError;
use serde::{Deserialize, Serialize};
use slamkit_core::Pose2;
use slamkit_lidar::global_search::{GlobalOutcome, GlobalSearch, GlobalSearchConfig};
use slamkit_lidar::layers::height::HeightTracker;
use slamkit_lidar::layers::saved::SavedLayerKeyframe;
use slamkit_lidar::layers::{LayerInput, LayeredSlamConfig};
use slamkit_lidar::point_map::Keyframe;
use std::collections::BTreeMap;

/// How a drone session finds itself in a saved map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct InMapConfig {
    /// The search over the map ([`GlobalSearch`]).
    pub global_search: GlobalSearchConfig,
    /// Keyframes of layers at most this far above or below the drone's are searched \[m\]
    /// (walls and pillars are mostly full height; furniture is not).
    pub max_height_gap_m: f64,
    /// Until found, a search runs on every this-many usable scans (a search takes tens of
    /// milliseconds on an office map).
    pub search_every_scans: usize,
}

impl Default for InMapConfig {
    fn default() -> Self {
        Self {
            global_search: GlobalSearchConfig::default(),
            max_height_gap_m: 0.5,
            search_every_scans: 5,
        }
    }
}

impl InMapConfig {
    /// Checks every field's range.
    ///
    /// # Errors
    /// [`SlamError::Config`] naming the field.
    pub fn validate(&self) -> Result<(), SlamError> {
        self.global_search.validate()?;
        if !(self.max_height_gap_m >= 0.0 && self.max_height_gap_m.is_finite()) {
            return Err(SlamError::Config(format!(
                "in_map.max_height_gap_m is {}: it must be finite and not negative",
                self.max_height_gap_m
            )));
        }
        if self.search_every_scans == 0 {
            return Err(SlamError::Config(
                "in_map.search_every_scans is 0: it must be at least 1".into(),
            ));
        }
        Ok(())
    }
}

/// How the search for the drone in a saved map went.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct InMapStats {
    /// Global searches run.
    pub searches: usize,
    /// Searches refused because two distinct poses fitted as well.
    pub ambiguous: usize,
    /// The scan (counting from 0) the drone was found with; `None` while not found.
    pub found_at_scan: Option<usize>,
}

/// Searching for the drone in a saved map.
pub(crate) struct Search {
    pub(crate) map: DroneMap,
    pub(crate) stats: InMapStats,
    config: InMapConfig,
    height: HeightTracker,
    max_tilt_rad: f64,
    /// One search structure per band of layers, by the layer it was built for.
    searches: BTreeMap<i64, GlobalSearch>,
    usable: usize,
}

impl Search {
    pub(crate) fn new(
        map: DroneMap,
        layers: &LayeredSlamConfig,
        config: InMapConfig,
    ) -> Result<Self, SlamError> {
        config.validate()?;
        if map.layers.values().all(Vec::is_empty) {
            return Err(SlamError::Map("the map holds no keyframe".into()));
        }
        let (mine, theirs) = (
            layers.height.layer_height_m,
            map.config.layers.height.layer_height_m,
        );
        if (mine - theirs).abs() > 1e-9 {
            return Err(SlamError::Map(format!(
                "the map's layers are {theirs} m high, this session's {mine} m: \
                 set layers.height.layer_height_m to the map's"
            )));
        }
        Ok(Self {
            map,
            stats: InMapStats::default(),
            config,
            height: HeightTracker::new(layers.height.clone()),
            max_tilt_rad: layers.max_tilt_rad,
            searches: BTreeMap::new(),
            usable: 0,
        })
    }

    /// Looks for the drone with `input`; its pose in the map frame once found.
    pub(crate) fn find(&mut self, input: &LayerInput) -> Option<Pose2> {
        let cos_tilt = (input.roll_rad.cos() * input.pitch_rad.cos()).clamp(0.0, 1.0);
        let vertical = |r: Option<f64>| r.map(|v| v * cos_tilt);
        let height = self
            .height
            .update(vertical(input.up_m), vertical(input.down_m));
        let (Some(height), false) = (height, cos_tilt.acos() > self.max_tilt_rad) else {
            return None;
        };
        self.usable += 1;
        if (self.usable - 1) % self.config.search_every_scans != 0 {
            return None;
        }
        let search = match self.searches.entry(height.layer) {
            std::collections::btree_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::btree_map::Entry::Vacant(e) => {
                let keyframes = near_keyframes(
                    &self.map,
                    height.layer,
                    self.config.max_height_gap_m,
                    &self.map.config.layers,
                );
                if keyframes.is_empty() {
                    return None;
                }
                // GlobalSearch::new checks only its settings, checked in Search::new
                e.insert(GlobalSearch::new(&keyframes, self.config.global_search.clone()).ok()?)
            }
        };
        let slam = &self.map.config.layers.slam;
        let points =
            slamkit_lidar::cloud::scan_points(input.scan, slam.min_range_m, slam.max_range_m);
        if points.len() < slam.min_scan_points {
            return None;
        }
        self.stats.searches += 1;
        match search.search(&points) {
            GlobalOutcome::Found(fix) => Some(fix.world_from_base),
            GlobalOutcome::Ambiguous { .. } => {
                self.stats.ambiguous += 1;
                None
            }
            GlobalOutcome::NotFound(_) => None,
        }
    }

    /// The saved keyframes, for the layered mapper.
    pub(crate) fn saved(&self) -> Vec<SavedLayerKeyframe> {
        self.map
            .layers
            .iter()
            .flat_map(|(layer, keyframes)| {
                keyframes.iter().map(|k| SavedLayerKeyframe {
                    layer: *layer,
                    time_s: k.time_s,
                    world_from_base: k.map_from_base,
                    points: k.points.clone(),
                })
            })
            .collect()
    }
}

/// The keyframes of `map`'s layers within `gap_m` of `layer`, as the matchers take them.
fn near_keyframes(
    map: &DroneMap,
    layer: i64,
    gap_m: f64,
    layers: &LayeredSlamConfig,
) -> Vec<Keyframe> {
    let h = layers.height.layer_height_m;
    let slam = &layers.slam;
    map.layers
        .iter()
        .filter(|(k, _)| (**k - layer).abs() as f64 * h <= gap_m + 1e-9)
        .flat_map(|(_, keyframes)| keyframes)
        .map(|k| Keyframe {
            world_from_base: k.map_from_base,
            normals: slamkit_lidar::cloud::estimate_normals(
                &k.points,
                slam.normal_neighbours,
                slam.normal_radius_m,
                slam.normal_max_flatness,
            ),
            points: k.points.clone(),
        })
        .collect()
}
