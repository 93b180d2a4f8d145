//! Height above the floor, and the height layer, from an up- and a down-looking range finder.
//!
//! Each sensor gives a candidate height: the down-looking one `floor + down`, the up-looking one
//! `ceiling − up`, where `floor` and `ceiling` are the heights of the surfaces under and over the
//! drone. While the drone climbs, both ranges change by opposite amounts and their sum stays put;
//! when it flies over or under an obstacle, one range jumps and the sum changes. A change of the
//! sum by more than `obstacle_step_m` between two readings is therefore an obstacle edge, not a
//! climb: the height is kept from the sensor that did not jump, and the surface under (or over)
//! the other is moved by the jump. Otherwise the height is the mean of the two candidates. This
//! is the seed method's rule; a gradual slope (a ramp flown over) is not told apart from a climb.
//!
//! The layer is the height divided by the layer thickness, with hysteresis: the tracker moves to
//! a neighbouring layer only once the height is `hysteresis_m` past the boundary, so noise on a
//! boundary does not flip between two maps.

use crate::error::FieldCheck;
use serde::{Deserialize, Serialize};

/// Parameters of the height and layer tracker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeightConfig {
    /// Thickness of a height layer \[m\].
    pub layer_height_m: f64,
    /// How far past a layer boundary the height must go before the layer changes \[m\].
    pub hysteresis_m: f64,
    /// A change of the sum of the up and down ranges larger than this between two readings is
    /// an obstacle edge, not a climb \[m\].
    pub obstacle_step_m: f64,
    /// Height of the up-looking sensor above the base origin \[m\].
    pub up_offset_m: f64,
    /// Depth of the down-looking sensor below the base origin \[m\].
    pub down_offset_m: f64,
}

impl Default for HeightConfig {
    fn default() -> Self {
        Self {
            layer_height_m: 0.05,
            hysteresis_m: 0.01,
            obstacle_step_m: 0.05,
            up_offset_m: 0.03,
            down_offset_m: 0.03,
        }
    }
}

impl HeightConfig {
    /// Each field with whether it is in range, for [`check_fields`](crate::error::check_fields).
    pub(crate) fn field_checks(&self) -> [FieldCheck; 5] {
        [
            (
                "layer_height_m",
                self.layer_height_m,
                self.layer_height_m > 0.0,
            ),
            (
                "hysteresis_m",
                self.hysteresis_m,
                self.hysteresis_m >= 0.0 && self.hysteresis_m < self.layer_height_m / 2.0,
            ),
            (
                "obstacle_step_m",
                self.obstacle_step_m,
                self.obstacle_step_m > 0.0,
            ),
            ("up_offset_m", self.up_offset_m, true),
            ("down_offset_m", self.down_offset_m, true),
        ]
    }
}

/// The tracker's answer for one pair of readings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightEstimate {
    /// Height of the base origin above the floor the drone started over \[m\].
    pub height_m: f64,
    /// Height layer index (layer `k` spans `\[k, k + 1\) · layer_height_m`).
    pub layer: i64,
    /// True when this reading crossed an obstacle edge (the sum of the ranges jumped).
    pub obstacle_edge: bool,
}

/// Tracks height and layer through a stream of range readings.
#[derive(Debug, Clone)]
pub struct HeightTracker {
    config: HeightConfig,
    /// Heights of the surfaces below and above, when known \[m\].
    floor_m: Option<f64>,
    ceiling_m: Option<f64>,
    /// Last candidates `\[from down, from up\]`, to tell a jump from a climb.
    last: [Option<f64>; 2],
    estimate: Option<HeightEstimate>,
}

impl HeightTracker {
    /// A tracker that has seen nothing yet; the floor under the first reading is height 0.
    pub fn new(config: HeightConfig) -> Self {
        Self {
            config,
            floor_m: None,
            ceiling_m: None,
            last: [None, None],
            estimate: None,
        }
    }

    /// The latest estimate.
    pub fn estimate(&self) -> Option<HeightEstimate> {
        self.estimate
    }

    /// Takes the vertical ranges `up_m`, `down_m` (already corrected for tilt; `None` or
    /// non-finite: no reading) and returns the new estimate, or `None` before the first usable
    /// reading.
    pub fn update(&mut self, up_m: Option<f64>, down_m: Option<f64>) -> Option<HeightEstimate> {
        let ok = |r: Option<f64>| r.filter(|v| v.is_finite() && *v >= 0.0);
        let (up, down) = (ok(up_m), ok(down_m));
        let below = down.map(|d| d + self.config.down_offset_m);
        let above = up.map(|u| u + self.config.up_offset_m);
        let Some(previous) = self.estimate.map(|e| e.height_m) else {
            return self.start(above, below);
        };
        if self.floor_m.is_none() {
            self.floor_m = below.map(|b| previous - b);
        }
        if self.ceiling_m.is_none() {
            self.ceiling_m = above.map(|a| previous + a);
        }
        let from_down = below.zip(self.floor_m).map(|(b, f)| f + b);
        let from_up = above.zip(self.ceiling_m).map(|(a, c)| c - a);
        let step = |now: Option<f64>, before: Option<f64>| now.zip(before).map(|(n, b)| n - b);
        let (d_down, d_up) = (step(from_down, self.last[0]), step(from_up, self.last[1]));
        let step_m = self.config.obstacle_step_m;
        let (height, edge) = match (from_down, from_up) {
            (Some(hd), Some(hu)) => match (d_down, d_up) {
                // the sum of the ranges changed: one surface moved; trust the steadier sensor
                (Some(a), Some(b)) if (a - b).abs() > step_m => {
                    if a.abs() > b.abs() {
                        (previous + b, true)
                    } else {
                        (previous + a, true)
                    }
                }
                _ => ((hd + hu) / 2.0, false),
            },
            (Some(h), None) | (None, Some(h)) => {
                let jump = (h - previous).abs() > step_m;
                (if jump { previous } else { h }, jump)
            }
            (None, None) => (previous, false),
        };
        if edge || from_down.zip(from_up).is_none() {
            self.floor_m = below.map(|b| height - b).or(self.floor_m);
            self.ceiling_m = above.map(|a| height + a).or(self.ceiling_m);
        }
        self.last = [
            below.zip(self.floor_m).map(|(b, f)| f + b),
            above.zip(self.ceiling_m).map(|(a, c)| c - a),
        ];
        Some(self.commit(height, edge))
    }

    /// The first reading: the floor is at 0 (or, with no down reading, the height is 0).
    fn start(&mut self, above: Option<f64>, below: Option<f64>) -> Option<HeightEstimate> {
        if above.is_none() && below.is_none() {
            return None;
        }
        let height = below.unwrap_or(0.0);
        self.floor_m = below.map(|_| 0.0);
        self.ceiling_m = above.map(|a| height + a);
        self.last = [below, above.map(|_| height)];
        Some(self.commit(height, false))
    }

    fn commit(&mut self, height_m: f64, obstacle_edge: bool) -> HeightEstimate {
        let h = self.config.layer_height_m;
        let layer = match self.estimate {
            Some(prev) => {
                let bottom = prev.layer as f64 * h;
                let margin = self.config.hysteresis_m;
                if height_m < bottom - margin || height_m >= bottom + h + margin {
                    (height_m / h).floor() as i64
                } else {
                    prev.layer
                }
            }
            None => (height_m / h).floor() as i64,
        };
        let estimate = HeightEstimate {
            height_m,
            layer,
            obstacle_edge,
        };
        self.estimate = Some(estimate);
        estimate
    }
}
