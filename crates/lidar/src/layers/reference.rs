//! Older maps of nearby layers as a reference for the heading and the position.
//!
//! A layer's map starts from the pose the mapper holds when the drone enters the layer, and
//! every later scan of the layer agrees with it. While the drone climbs or descends slowly (a
//! new 5 cm layer every 0.25–2.5 s on the `office` flight's sloping legs) the map a scan is
//! matched to is a few seconds old and carries the pose's own heading error: the matches agree with
//! the gyro's prediction whatever its bias, the heading filter cannot see the bias, and each
//! new map takes the error on. Traced on `office` at commit fcdac19, the heading error grew by
//! −0.03 °/s on such legs and reached −2° to −6° by the end of most flights (the particle
//! filter's single map of all heights stays within 0.3°); along the north desks that turned
//! into most of the ICP position error.
//!
//! Walls, pillars and shelves, which pin the heading, are mostly full height, so a layer a few
//! centimetres above or below, mapped earlier, sees the same ones. Each scan that its own
//! layer's map fixed is therefore also aligned by ICP, from the fixed pose and without a
//! correlative search, to the oldest maps of the layers within `max_height_gap_m` (maps at
//! least `min_age_s` old, oldest first, at most `max_tries` of them); the first alignment that
//! puts `min_goodness` of the scan on its map is a second measurement, through the same gates
//! and filter updates as the layer's own match, with the scan's information scaled by that
//! share (the rest of the scan sees furniture that differs between the heights).

use serde::{Deserialize, Serialize};

/// Which nearby layers' maps are references, and when an alignment to one counts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReferenceConfig {
    /// Align to other layers' maps at all.
    pub enabled: bool,
    /// Layers at most this far above or below the current one are references \[m\]
    /// (`office` seeds 1–20, ICP median of the mean errors: 0.126 m at 0.1 m, 0.141 m at
    /// 0.15 m, 0.119 m at 0.2 m, 0.155 m at 0.3 m, 0.176 m at 0.6 m; 0.175 m without
    /// references): further away the furniture differs.
    pub max_height_gap_m: f64,
    /// Only maps created at least this long before the scan are references: a map started a
    /// moment ago carries the current drift \[s\] (office median 0.183 m at 2 s; 0.166 m at
    /// 10 s with a 0.3 m gap).
    pub min_age_s: f64,
    /// At most this many references are tried, oldest map first (office median 0.159 m
    /// with 1; with all of them, at most 5 on these flights, 0.112 m but the worst seed
    /// 0.266 m against 0.233 m at 3).
    pub max_tries: usize,
    /// Lowest ICP goodness (fraction of scan points on the reference map) of an alignment that
    /// counts, in \[0, 1\] (office median 0.166 m at 0.7).
    pub min_goodness: f64,
}

impl Default for ReferenceConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            max_height_gap_m: 0.2,
            min_age_s: 5.0,
            max_tries: 3,
            min_goodness: 0.6,
        }
    }
}

impl ReferenceConfig {
    /// `(field, value, valid)` for every numeric field: the gap and age non-negative, the
    /// goodness a fraction.
    pub fn field_checks(&self) -> [(&'static str, f64, bool); 3] {
        [
            (
                "reference.max_height_gap_m",
                self.max_height_gap_m,
                self.max_height_gap_m >= 0.0,
            ),
            ("reference.min_age_s", self.min_age_s, self.min_age_s >= 0.0),
            (
                "reference.min_goodness",
                self.min_goodness,
                (0.0..=1.0).contains(&self.min_goodness),
            ),
        ]
    }
}

/// The reference layers for a scan of `layer` at `now_s`, oldest map first: among `layers`
/// (index, creation time of its map), the others within `max_height_gap_m` whose maps are at
/// least `min_age_s` old, at most `max_tries` of them.
pub fn reference_layers(
    layers: impl IntoIterator<Item = (i64, f64)>,
    layer: i64,
    now_s: f64,
    layer_height_m: f64,
    config: &ReferenceConfig,
) -> Vec<i64> {
    let mut found: Vec<(f64, i64)> = layers
        .into_iter()
        .filter(|&(k, created_s)| {
            let gap = (k - layer).abs() as f64 * layer_height_m;
            k != layer
                && gap <= config.max_height_gap_m + 1e-9
                && created_s <= now_s - config.min_age_s
        })
        .map(|(k, created_s)| (created_s, k))
        .collect();
    found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    found
        .into_iter()
        .take(config.max_tries)
        .map(|(_, k)| k)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn references_are_the_oldest_old_enough_maps_of_nearby_other_layers() {
        let config = ReferenceConfig::default();
        // layer 10 now at t = 100 s; 0.2 m is four 5 cm layers
        let layers = [
            (10, 0.0),  // the current layer: never
            (6, 1.0),   // 0.20 m below: near enough
            (5, 0.5),   // 0.25 m below: too far
            (12, 20.0), // near, newer
            (9, 96.0),  // near, but only 4 s old
            (14, 10.0), // 0.20 m above
            (11, 50.0), // near, the newest of the old ones: beyond max_tries
        ];
        assert_eq!(
            reference_layers(layers, 10, 100.0, 0.05, &config),
            [6, 14, 12]
        );
        let one = ReferenceConfig {
            max_tries: 1,
            ..config.clone()
        };
        assert_eq!(reference_layers(layers, 10, 100.0, 0.05, &one), [6]);
        assert!(reference_layers(layers, 10, 5.0, 0.05, &config).is_empty());
    }
}
