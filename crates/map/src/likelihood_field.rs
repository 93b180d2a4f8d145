//! Likelihood-field sensor model: how well a laser scan fits a map at a given pose.
//!
//! S. Thrun, W. Burgard, D. Fox, *Probabilistic Robotics*, 2005, section 6.4, table 6.3: each
//! beam end point is scored by its distance `d` to the nearest obstacle,
//! `p = z_hit · N(d; 0, σ_hit²) + z_rand / z_max`, and the beams are independent, so the scan's
//! log-likelihood is the sum of `ln p` over its hits; "no return" beams are skipped. This is the
//! importance weight of particle-filter SLAM and Monte Carlo localisation (ROS `amcl`'s
//! `likelihood_field` model).
//!
//! Distances come from an exact Euclidean distance transform
//! ([`crate::distance_transform`]) of the grid's obstacle cells, capped at `max_distance_m`, and
//! `ln p` is tabulated per cell, so scoring a beam is one rigid transform and one table read.
//! The field covers the grid's known cells plus a margin of `max_distance_m`; everything outside
//! scores as `max_distance_m` away.

use crate::distance_transform::squared_distance_transform;
use crate::error::MapError;
use crate::occupancy_grid::{log_odds_from_probability, CellIndex, OccupancyGrid};
use nalgebra::{Point2, UnitComplex, Vector2};
use serde::{Deserialize, Serialize};
use slamkit_core::{LaserScan, Pose2};

/// Parameters of the likelihood-field model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LikelihoodFieldConfig {
    /// Standard deviation of a hit around the nearest obstacle \[m\].
    pub sigma_hit_m: f64,
    /// Weight of the Gaussian hit component \[0..1\].
    pub z_hit: f64,
    /// Weight of the uniform random-reading component \[0..1\]; must be positive.
    pub z_rand: f64,
    /// Range over which random readings are uniform, the sensor's maximum range \[m\].
    pub z_max_m: f64,
    /// Distances are capped here; farther end points all score alike \[m\].
    pub max_distance_m: f64,
    /// Cells whose occupancy probability exceeds this are obstacles \[0..1\].
    pub obstacle_min_probability: f64,
}

impl Default for LikelihoodFieldConfig {
    /// `amcl`'s defaults, with a tighter `sigma_hit_m` suiting 5 cm grids.
    fn default() -> Self {
        Self {
            sigma_hit_m: 0.1,
            z_hit: 0.95,
            z_rand: 0.05,
            z_max_m: 30.0,
            max_distance_m: 2.0,
            obstacle_min_probability: 0.5,
        }
    }
}

impl LikelihoodFieldConfig {
    /// Checks every value; [`LikelihoodField::new`] refuses a configuration that fails.
    pub fn validate(&self) -> Result<(), MapError> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let valid = positive(self.sigma_hit_m)
            && self.z_hit.is_finite()
            && self.z_hit >= 0.0
            && positive(self.z_rand)
            && positive(self.z_max_m)
            && self.max_distance_m.is_finite()
            && (0.0..=1e3).contains(&self.max_distance_m)
            && (0.0..1.0).contains(&self.obstacle_min_probability);
        if valid {
            Ok(())
        } else {
            Err(MapError::InvalidConfig {
                message: format!("likelihood field: out-of-range value in {self:?}"),
            })
        }
    }

    /// `ln p` of an end point `distance_m` from the nearest obstacle (table 6.3, line 8).
    pub fn log_likelihood(&self, distance_m: f64) -> f64 {
        let d = distance_m.min(self.max_distance_m);
        let sigma = self.sigma_hit_m;
        let gauss = (-0.5 * (d / sigma).powi(2)).exp() / (sigma * std::f64::consts::TAU.sqrt());
        (self.z_hit * gauss + self.z_rand / self.z_max_m).ln()
    }
}

/// `ln p` of [`LikelihoodFieldConfig::log_likelihood`] tabulated over the squared distance
/// `0..=max_distance_m²`, for scorers that measure distances on the fly (particle-filter SLAM,
/// whose maps change at every step): one table read and one interpolation instead of an `exp`
/// and a `ln` per beam.
#[derive(Debug, Clone)]
pub struct SquaredDistanceTable {
    inv_step_m2: f64,
    values: Vec<f64>,
}

impl SquaredDistanceTable {
    /// Samples of the table; linear interpolation between them is within 1e-4 of the exact
    /// value for σ down to a tenth of `max_distance_m`.
    const SAMPLES: usize = 1024;

    /// The table of `config` (validate it first: a zero σ tabulates NaN).
    pub fn new(config: &LikelihoodFieldConfig) -> Self {
        let max_m2 = config.max_distance_m * config.max_distance_m;
        let step_m2 = max_m2 / (Self::SAMPLES - 1) as f64;
        let values = (0..Self::SAMPLES)
            .map(|i| config.log_likelihood((i as f64 * step_m2).sqrt()))
            .collect();
        Self {
            inv_step_m2: if step_m2 > 0.0 { 1.0 / step_m2 } else { 0.0 },
            values,
        }
    }

    /// `ln p` of an end point whose squared distance to the nearest obstacle is
    /// `squared_distance_m2`; distances beyond the table score as its end.
    #[inline]
    pub fn log_likelihood(&self, squared_distance_m2: f64) -> f64 {
        let x = (squared_distance_m2 * self.inv_step_m2).max(0.0);
        let last = self.values.len() - 1;
        // `as` saturates (NaN becomes 0), so `i` is a valid index.
        let i = (x as usize).min(last - 1);
        let f = (x - i as f64).min(1.0);
        let (a, b) = (self.values[i], self.values[i + 1]);
        a + (b - a) * f
    }
}

/// Distance to the nearest obstacle and the per-beam log-likelihood, tabulated over a map.
#[derive(Debug, Clone)]
pub struct LikelihoodField {
    config: LikelihoodFieldConfig,
    /// World position of the lower-left corner of field cell (0, 0) \[m\].
    origin_m: Vector2<f64>,
    inv_resolution: f64,
    width: usize,
    height: usize,
    distance_m: Vec<f32>,
    log_likelihood: Vec<f32>,
    far_log_likelihood: f32,
}

impl LikelihoodField {
    /// Builds the field of `grid`'s obstacles.
    pub fn new(grid: &OccupancyGrid, config: &LikelihoodFieldConfig) -> Result<Self, MapError> {
        config.validate()?;
        let resolution_m = grid.resolution_m();
        let margin = (config.max_distance_m / resolution_m).ceil() as i32 + 1;
        let (min, width, height) = match grid.known_bounds() {
            Some(b) => (
                CellIndex {
                    x: b.min.x - margin,
                    y: b.min.y - margin,
                },
                b.width() + 2 * margin as usize,
                b.height() + 2 * margin as usize,
            ),
            None => (CellIndex { x: 0, y: 0 }, 0, 0),
        };
        let l_obstacle = log_odds_from_probability(config.obstacle_min_probability);
        let is_obstacle: Vec<bool> = (0..width * height)
            .map(|i| {
                let cell = CellIndex {
                    x: min.x + (i % width) as i32,
                    y: min.y + (i / width) as i32,
                };
                grid.log_odds(cell).is_some_and(|l| l > l_obstacle)
            })
            .collect();
        let distance_m: Vec<f32> = squared_distance_transform(&is_obstacle, width, height)
            .into_iter()
            .map(|d2| (f64::from(d2).sqrt() * resolution_m).min(config.max_distance_m) as f32)
            .collect();
        let log_likelihood = distance_m
            .iter()
            .map(|&d| config.log_likelihood(f64::from(d)) as f32)
            .collect();
        let corner = grid.origin_m().coords
            + Vector2::new(f64::from(min.x), f64::from(min.y)) * resolution_m;
        Ok(Self {
            far_log_likelihood: config.log_likelihood(config.max_distance_m) as f32,
            config: config.clone(),
            origin_m: corner,
            inv_resolution: 1.0 / resolution_m,
            width,
            height,
            distance_m,
            log_likelihood,
        })
    }

    /// The configuration the field was built with.
    pub fn config(&self) -> &LikelihoodFieldConfig {
        &self.config
    }

    /// Flat index of the field cell holding world point `(x, y)`; `None` outside (or NaN).
    #[inline]
    fn index(&self, x_m: f64, y_m: f64) -> Option<usize> {
        let fx = (x_m - self.origin_m.x) * self.inv_resolution;
        let fy = (y_m - self.origin_m.y) * self.inv_resolution;
        let inside = fx >= 0.0 && fy >= 0.0 && fx < self.width as f64 && fy < self.height as f64;
        // Truncation is floor for non-negative values.
        inside.then(|| fy as usize * self.width + fx as usize)
    }

    /// Distance from world point `point_m` to the nearest obstacle, capped at
    /// `max_distance_m` \[m\].
    pub fn distance_m(&self, point_m: &Point2<f64>) -> f64 {
        self.index(point_m.x, point_m.y)
            .and_then(|i| self.distance_m.get(i))
            .map_or(self.config.max_distance_m, |&d| f64::from(d))
    }

    /// `ln p` of a beam ending at world point `(x_m, y_m)`.
    #[inline]
    pub fn log_likelihood_at(&self, x_m: f64, y_m: f64) -> f32 {
        self.index(x_m, y_m)
            .and_then(|i| self.log_likelihood.get(i))
            .map_or(self.far_log_likelihood, |&l| l)
    }

    /// Log-likelihood of end points given in the laser frame, with the laser at
    /// `world_from_laser`: the sum of `ln p` over the points. Precompute the points once per scan
    /// ([`LaserScan::hit_points`]) when scoring many poses.
    pub fn score_points(&self, points_laser: &[Point2<f64>], world_from_laser: &Pose2) -> f64 {
        let (sin, cos) = world_from_laser.rotation.angle().sin_cos();
        let t = world_from_laser.translation.vector;
        points_laser
            .iter()
            .map(|p| {
                let x = cos * p.x - sin * p.y + t.x;
                let y = sin * p.x + cos * p.y + t.y;
                f64::from(self.log_likelihood_at(x, y))
            })
            .sum()
    }

    /// Log-likelihood of `scan`'s hits with the laser at `world_from_laser`; "no return" and
    /// invalid beams do not count.
    pub fn score_scan(&self, scan: &LaserScan, world_from_laser: &Pose2) -> f64 {
        let t = world_from_laser.translation.vector;
        // Beam directions by repeated rotation: no allocation and one sin_cos per scan.
        let first = world_from_laser.rotation * UnitComplex::new(scan.angle_min_rad);
        let increment = *UnitComplex::new(scan.angle_increment_rad).complex();
        let mut direction = *first.complex();
        let mut sum = 0.0;
        for (i, &range_m) in scan.ranges_m.iter().enumerate() {
            if scan.is_hit(i) {
                let (x, y) = (t.x + range_m * direction.re, t.y + range_m * direction.im);
                sum += f64::from(self.log_likelihood_at(x, y));
            }
            direction *= increment;
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::occupancy_grid::OccupancyGridConfig;
    use crate::test_room::room_scan;

    const HALF_M: f64 = 4.025;

    fn room_grid() -> OccupancyGrid {
        let mut grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
        for (x, y) in [(0.0, 0.0), (2.0, 1.0), (-2.5, -2.0), (1.5, -2.5)] {
            for k in 0..4 {
                let pose = Pose2::new(Vector2::new(x, y), f64::from(k) * 1.6);
                grid.insert_scan(&room_scan(&pose, HALF_M, 180, 30.0), &pose)
                    .unwrap();
            }
        }
        grid
    }

    #[test]
    fn distances_to_a_single_obstacle() {
        let mut grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
        grid.set_log_odds(CellIndex { x: 10, y: 20 }, 2.0).unwrap();
        let field = LikelihoodField::new(&grid, &LikelihoodFieldConfig::default()).unwrap();
        let centre = grid.cell_center_m(CellIndex { x: 10, y: 20 });
        assert_eq!(field.distance_m(&centre), 0.0);
        let p = centre + Vector2::new(0.3, 0.4);
        assert!((field.distance_m(&p) - 0.5).abs() < 1e-6);
        // Capped at 2 m, also outside the field and for NaN.
        assert_eq!(field.distance_m(&(centre + Vector2::new(1.8, 1.8))), 2.0);
        assert_eq!(field.distance_m(&Point2::new(500.0, 0.0)), 2.0);
        assert_eq!(field.distance_m(&Point2::new(f64::NAN, 0.0)), 2.0);
        let config = LikelihoodFieldConfig::default();
        let expected = config.log_likelihood(0.5);
        assert!((f64::from(field.log_likelihood_at(p.x, p.y)) - expected).abs() < 1e-5);
    }

    #[test]
    fn log_likelihood_follows_table_6_3() {
        let c = LikelihoodFieldConfig::default();
        let gauss0 = 1.0 / (0.1 * std::f64::consts::TAU.sqrt());
        assert!((c.log_likelihood(0.0) - (0.95 * gauss0 + 0.05 / 30.0).ln()).abs() < 1e-12);
        let far = (0.95 * gauss0 * (-200.0f64).exp() + 0.05 / 30.0).ln();
        assert!((c.log_likelihood(2.0) - far).abs() < 1e-12);
        assert_eq!(c.log_likelihood(7.0), c.log_likelihood(2.0));
    }

    #[test]
    fn true_pose_scores_best() {
        let grid = room_grid();
        let field = LikelihoodField::new(&grid, &LikelihoodFieldConfig::default()).unwrap();
        let truth = Pose2::new(Vector2::new(0.7, -0.4), 0.9);
        let scan = room_scan(&truth, HALF_M, 180, 30.0);
        let best = field.score_scan(&scan, &truth);
        for (dx, dy, da) in [
            (0.1, 0.0, 0.0),
            (0.0, -0.1, 0.0),
            (0.0, 0.0, 0.03),
            (0.3, 0.3, 0.1),
        ] {
            let pose = Pose2::new(Vector2::new(0.7 + dx, -0.4 + dy), 0.9 + da);
            let score = field.score_scan(&scan, &pose);
            assert!(
                score < best - 10.0,
                "offset ({dx}, {dy}, {da}): {score} vs {best}"
            );
        }
        // Every beam hits a wall, each within a cell of an obstacle at the true pose.
        let points = scan.hit_points();
        assert_eq!(points.len(), 180);
        assert!((field.score_points(&points, &truth) - best).abs() < 1e-9);
        let near = LikelihoodFieldConfig::default().log_likelihood(0.0501);
        assert!(best > 180.0 * near, "{best}");
    }

    #[test]
    fn squared_distance_table_matches_the_model() {
        let config = LikelihoodFieldConfig {
            sigma_hit_m: 0.05,
            max_distance_m: 0.15,
            ..Default::default()
        };
        let table = SquaredDistanceTable::new(&config);
        for i in 0..=300 {
            let d = 0.0006 * f64::from(i);
            let exact = config.log_likelihood(d);
            let got = table.log_likelihood(d * d);
            assert!((got - exact).abs() < 1e-4, "d {d}: {got} vs {exact}");
        }
        assert_eq!(table.log_likelihood(f64::NAN), config.log_likelihood(0.0));
    }

    #[test]
    fn empty_map_scores_everything_far() {
        let grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
        let config = LikelihoodFieldConfig::default();
        let field = LikelihoodField::new(&grid, &config).unwrap();
        let scan = room_scan(&Pose2::identity(), HALF_M, 10, 30.0);
        let expected = 10.0 * f64::from(config.log_likelihood(2.0) as f32);
        assert!((field.score_scan(&scan, &Pose2::identity()) - expected).abs() < 1e-9);
    }

    #[test]
    fn invalid_config_is_rejected() {
        let grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
        for config in [
            LikelihoodFieldConfig {
                sigma_hit_m: 0.0,
                ..Default::default()
            },
            LikelihoodFieldConfig {
                z_rand: 0.0,
                ..Default::default()
            },
            LikelihoodFieldConfig {
                max_distance_m: f64::NAN,
                ..Default::default()
            },
        ] {
            assert!(matches!(
                LikelihoodField::new(&grid, &config),
                Err(MapError::InvalidConfig { .. })
            ));
        }
    }
}
