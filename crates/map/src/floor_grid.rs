//! 2D occupancy grids on the floor from 3D points, for ground robots.
//!
//! Points are given in a floor-aligned map frame ([`crate::floor`]: height above the floor is
//! `-y`, floor coordinates `(x, z)`). Points in a height band (default 0.1–1.0 m) are obstacles
//! the robot would hit; points below it are floor; points above it pass over the robot and are
//! ignored. Two ways to turn them into a grid, both kept side by side in one [`FloorGrid`]:
//!
//! * [`FloorGridMethod::PointCount`] (the seed robot's): band points are counted per cell and a
//!   cell is an obstacle once its count reaches `min_points`, which filters depth noise; cells
//!   crossed by a Bresenham ray from the camera to a band or floor point are free.
//! * [`FloorGridMethod::LogOdds`] (Bayesian, as OctoMap and [`crate::OccupancyGrid`]): per cloud,
//!   each cell hit by a band point adds `log_odds_hit`, each cell only crossed by rays adds
//!   `log_odds_miss`, clamped; positive is occupied, negative free (A. Hornung et al.,
//!   "OctoMap", Autonomous Robots 34(3), 2013).
//!
//! NaN points, points beyond `max_range_m` and points off the grid are skipped and counted.
//!
//! [`depth_points`] turns a depth image into such points (every `step`-th pixel, back-projected
//! with the pinhole intrinsics and moved by `map_from_camera`), and [`FloorGrid::insert_depth`]
//! inserts one depth frame seen from that camera pose.

use crate::error::MapError;
use crate::occupancy_grid::Occupancy;
use crate::raycast::bresenham;
use crate::tri_grid::TriGrid;
use nalgebra::{Point2, Point3};
use serde::{Deserialize, Serialize};
use slamkit_core::camera::Intrinsics;
use slamkit_core::image::Image;
use slamkit_core::Pose3;

/// Settings of the floor grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FloorGridConfig {
    /// Side of a cell \[m\].
    pub resolution_m: f64,
    /// Lowest height of an obstacle point above the floor \[m\].
    pub min_height_m: f64,
    /// Highest height of an obstacle point above the floor \[m\].
    pub max_height_m: f64,
    /// Points farther from the camera are skipped \[m\].
    pub max_range_m: f64,
    /// Band points a cell needs to be an obstacle (point-count method).
    pub min_points: u32,
    /// Log-odds added to a hit cell per cloud (log-odds method).
    pub log_odds_hit: f32,
    /// Log-odds added to a cell crossed by rays per cloud (log-odds method).
    pub log_odds_miss: f32,
    /// Clamping bounds of the log-odds `[min, max]`.
    pub log_odds_clamp: [f32; 2],
}

impl Default for FloorGridConfig {
    fn default() -> Self {
        Self {
            resolution_m: 0.1,
            min_height_m: 0.1,
            max_height_m: 1.0,
            max_range_m: 8.0,
            min_points: 5,
            // OctoMap's defaults: p_hit 0.7, p_miss 0.4, clamping 0.12 and 0.97.
            log_odds_hit: 0.847,
            log_odds_miss: -0.405,
            log_odds_clamp: [-1.992, 3.476],
        }
    }
}

/// Which rule decides a cell's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FloorGridMethod {
    /// Obstacle above a point count, free where rays passed.
    PointCount,
    /// Bayesian log-odds of hits and misses.
    LogOdds,
}

/// What one cloud contributed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FloorInsertStats {
    /// Points in the height band, counted as obstacles.
    pub obstacle_points: usize,
    /// Points below the band (floor).
    pub floor_points: usize,
    /// Points above the band, ignored.
    pub above_points: usize,
    /// NaN, too far, or off-grid points, skipped.
    pub skipped_points: usize,
}

/// A fixed-size floor grid holding both methods' evidence.
#[derive(Debug, Clone)]
pub struct FloorGrid {
    config: FloorGridConfig,
    width: usize,
    height: usize,
    origin_m: Point2<f64>,
    hits: Vec<u32>,
    rays: Vec<u32>,
    log_odds: Vec<f32>,
}

impl FloorGrid {
    /// An empty grid of `width × height` cells whose cell (0, 0) has its corner at floor point
    /// `origin_m` = (x, z).
    ///
    /// # Errors
    /// [`MapError::InvalidConfig`] for a zero size, a non-positive resolution, an empty band
    /// or range, a zero `min_points`, or log-odds of the wrong sign.
    pub fn new(
        width: usize,
        height: usize,
        origin_m: Point2<f64>,
        config: FloorGridConfig,
    ) -> Result<Self, MapError> {
        validate(width, height, &origin_m, &config)?;
        let n = width * height;
        Ok(Self {
            config,
            width,
            height,
            origin_m,
            hits: vec![0; n],
            rays: vec![0; n],
            log_odds: vec![0.0; n],
        })
    }

    /// Adds one cloud of points (map frame) seen from `camera_m` (map frame).
    pub fn insert_cloud(
        &mut self,
        points: &[Point3<f64>],
        camera_m: &Point3<f64>,
    ) -> FloorInsertStats {
        let mut stats = FloorInsertStats::default();
        let Some(origin) = self.cell_of(camera_m) else {
            stats.skipped_points = points.len();
            return stats;
        };
        let mut hit_now = vec![false; self.hits.len()];
        let mut crossed_now = vec![false; self.hits.len()];
        for p in points {
            let range = (p - camera_m).norm();
            let cell = if range <= self.config.max_range_m {
                self.cell_of(p)
            } else {
                None
            };
            let Some(cell) = cell else {
                stats.skipped_points += 1;
                continue;
            };
            let height = -p.y;
            if height > self.config.max_height_m {
                stats.above_points += 1;
                continue;
            }
            let obstacle = height >= self.config.min_height_m;
            self.trace(origin, cell, !obstacle, &mut crossed_now);
            let index = cell.1 * self.width + cell.0;
            if obstacle {
                stats.obstacle_points += 1;
                self.hits[index] += 1;
                hit_now[index] = true;
            } else {
                stats.floor_points += 1;
            }
        }
        let [lo, hi] = self.config.log_odds_clamp;
        for ((l, &hit), &crossed) in self.log_odds.iter_mut().zip(&hit_now).zip(&crossed_now) {
            if hit {
                *l = (*l + self.config.log_odds_hit).clamp(lo, hi);
            } else if crossed {
                *l = (*l + self.config.log_odds_miss).clamp(lo, hi);
            }
        }
        stats
    }

    /// Adds one depth frame (metres, 0 or NaN where unknown; pinhole `intrinsics`) taken by a
    /// camera at `map_from_camera`, every `step`-th pixel in both directions (0 counts as 1).
    pub fn insert_depth(
        &mut self,
        depth_m: &Image<f32>,
        intrinsics: &Intrinsics,
        map_from_camera: &Pose3,
        step: usize,
    ) -> FloorInsertStats {
        let points = depth_points(depth_m, intrinsics, map_from_camera, step);
        self.insert_cloud(&points, &Point3::from(map_from_camera.translation.vector))
    }

    /// Marks the cells from `from` to `to` crossed (including `to` when `include_end`).
    fn trace(
        &mut self,
        from: (usize, usize),
        to: (usize, usize),
        include_end: bool,
        crossed: &mut [bool],
    ) {
        let w = self.width;
        let rays = &mut self.rays;
        let cell = |c: usize| c as i32;
        bresenham(
            cell(from.0),
            cell(from.1),
            cell(to.0),
            cell(to.1),
            |x, y| {
                let (x, y) = (x as usize, y as usize);
                if (x, y) != to || include_end {
                    let i = y * w + x;
                    rays[i] += 1;
                    crossed[i] = true;
                }
            },
        );
    }

    /// The cell of a map point's floor coordinates `(x, z)`, or `None` off the grid or for NaN.
    pub fn cell_of(&self, p: &Point3<f64>) -> Option<(usize, usize)> {
        let gx = ((p.x - self.origin_m.x) / self.config.resolution_m).floor();
        let gy = ((p.z - self.origin_m.y) / self.config.resolution_m).floor();
        let inside = gx >= 0.0 && gy >= 0.0 && gx < self.width as f64 && gy < self.height as f64;
        inside.then_some((gx as usize, gy as usize))
    }

    /// The tri-state grid by `method`, cell (x, y) at floor coordinates (x, z).
    pub fn to_tri_grid(&self, method: FloorGridMethod) -> TriGrid {
        let mut grid = match TriGrid::new(
            self.width,
            self.height,
            self.config.resolution_m,
            self.origin_m,
            Occupancy::Unknown,
        ) {
            Some(g) => g,
            None => unreachable!("sizes validated in FloorGrid::new"),
        };
        for i in 0..self.hits.len() {
            let state = match method {
                FloorGridMethod::PointCount if self.hits[i] >= self.config.min_points => {
                    Occupancy::Occupied
                }
                FloorGridMethod::PointCount if self.rays[i] > 0 => Occupancy::Free,
                FloorGridMethod::LogOdds if self.log_odds[i] > 0.0 => Occupancy::Occupied,
                FloorGridMethod::LogOdds if self.log_odds[i] < 0.0 => Occupancy::Free,
                _ => continue,
            };
            grid.set(i % self.width, i / self.width, state);
        }
        grid
    }
}

/// The map-frame points of every `step`-th pixel (rows and columns; 0 counts as 1) of a depth
/// image with a positive finite depth: back-projected through `intrinsics`, then moved by
/// `map_from_camera`.
pub fn depth_points(
    depth_m: &Image<f32>,
    intrinsics: &Intrinsics,
    map_from_camera: &Pose3,
    step: usize,
) -> Vec<Point3<f64>> {
    let step = step.max(1);
    let mut points = Vec::new();
    for v in (0..depth_m.height()).step_by(step) {
        let Some(row) = depth_m.row(v) else { continue };
        for (u, &z) in row.iter().enumerate().step_by(step) {
            let z = f64::from(z);
            if !(z.is_finite() && z > 0.0) {
                continue;
            }
            let x = (u as f64 - intrinsics.cx) / intrinsics.fx * z;
            let y = (v as f64 - intrinsics.cy) / intrinsics.fy * z;
            points.push(map_from_camera * Point3::new(x, y, z));
        }
    }
    points
}

fn validate(
    width: usize,
    height: usize,
    origin: &Point2<f64>,
    c: &FloorGridConfig,
) -> Result<(), MapError> {
    let problem = if width == 0
        || height == 0
        || width.checked_mul(height).is_none()
        || width.max(height) > 1 << 24
    {
        Some("grid size must be positive and at most 2^24 cells a side")
    } else if !(c.resolution_m.is_finite() && c.resolution_m > 0.0) {
        Some("resolution_m must be positive and finite")
    } else if !(origin.x.is_finite() && origin.y.is_finite()) {
        Some("origin must be finite")
    } else if !(c.min_height_m < c.max_height_m
        && c.min_height_m.is_finite()
        && c.max_height_m.is_finite())
    {
        Some("min_height_m must be below max_height_m, both finite")
    } else if c.max_range_m.is_nan() || c.max_range_m <= 0.0 || c.min_points == 0 {
        Some("max_range_m must be positive and min_points at least 1")
    } else if !(c.log_odds_hit > 0.0
        && c.log_odds_miss < 0.0
        && c.log_odds_clamp[0] < 0.0
        && c.log_odds_clamp[1] > 0.0)
    {
        Some("log_odds_hit and the upper clamp must be positive, log_odds_miss and the lower clamp negative")
    } else {
        None
    };
    match problem {
        Some(message) => Err(MapError::InvalidConfig {
            message: message.to_owned(),
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A camera 0.5 m above the floor at (x, z) = (1, 0.5) looking along +z at a wall at
    /// z = 3 (x in 0..2, heights 0..1.5) over the floor, with noise points.
    fn scene(seed: u64) -> (Vec<Point3<f64>>, Point3<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut points = Vec::new();
        for _ in 0..3000 {
            points.push(Point3::new(
                rng.gen_range(0.0..2.0),
                -rng.gen_range(0.0..1.5),
                3.05,
            ));
        }
        for _ in 0..6000 {
            points.push(Point3::new(
                rng.gen_range(0.0..2.0),
                0.0,
                rng.gen_range(0.5..3.0),
            ));
        }
        // Depth noise: a few stray points floating in the room.
        for _ in 0..3 {
            points.push(Point3::new(
                rng.gen_range(0.0..2.0),
                -0.5,
                rng.gen_range(1.0..2.5),
            ));
        }
        points.push(Point3::new(f64::NAN, 0.0, 1.0));
        points.push(Point3::new(1e300, -0.5, 1.0));
        (points, Point3::new(1.0, -0.5, 0.5))
    }

    fn grid() -> FloorGrid {
        FloorGrid::new(20, 40, Point2::new(0.0, 0.0), FloorGridConfig::default()).unwrap()
    }

    #[test]
    fn wall_is_an_obstacle_and_the_floor_before_it_free() {
        let (all, camera) = scene(1);
        // Without the stray points: one cloud with a stray hit marks it occupied by log-odds.
        let points: Vec<Point3<f64>> = all[..9000].iter().chain(&all[9003..]).copied().collect();
        let mut g = grid();
        let stats = g.insert_cloud(&points, &camera);
        assert_eq!(stats.skipped_points, 2);
        let seen = stats.obstacle_points + stats.above_points + stats.floor_points;
        assert_eq!(seen + stats.skipped_points, points.len());
        assert!(
            stats.obstacle_points > 1500 && stats.above_points > 800,
            "{stats:?}"
        );
        for method in [FloorGridMethod::PointCount, FloorGridMethod::LogOdds] {
            let t = g.to_tri_grid(method);
            for x in 1..19 {
                assert_eq!(
                    t.get(x, 30),
                    Some(Occupancy::Occupied),
                    "{method:?} wall at {x}"
                );
                assert_eq!(
                    t.get(x, 15),
                    Some(Occupancy::Free),
                    "{method:?} floor at {x}"
                );
                assert_eq!(
                    t.get(x, 35),
                    Some(Occupancy::Unknown),
                    "{method:?} behind the wall"
                );
            }
        }
    }

    #[test]
    fn counting_filters_noise_and_log_odds_clears_it() {
        let (points, camera) = scene(2);
        let noise: Vec<Point3<f64>> = points[9000..9003].to_vec();
        let mut g = grid();
        g.insert_cloud(&points, &camera);
        let count = g.to_tri_grid(FloorGridMethod::PointCount);
        for p in &noise {
            let (x, y) = g.cell_of(p).unwrap();
            assert_ne!(
                count.get(x, y),
                Some(Occupancy::Occupied),
                "one stray point is not an obstacle"
            );
        }
        // Seen again without the noise, the log-odds grid frees the noisy cells.
        let (clean, _) = scene(3);
        for _ in 0..3 {
            g.insert_cloud(&clean[..9000], &camera);
        }
        let bayes = g.to_tri_grid(FloorGridMethod::LogOdds);
        for p in &noise {
            let (x, y) = g.cell_of(p).unwrap();
            assert_eq!(bayes.get(x, y), Some(Occupancy::Free));
        }
    }

    #[test]
    fn ceiling_view_empty_and_bad_input_do_not_panic() {
        let mut g = grid();
        let ceiling: Vec<Point3<f64>> = (0..100)
            .map(|i| Point3::new(f64::from(i) * 0.02, -2.5, 1.0))
            .collect();
        let stats = g.insert_cloud(&ceiling, &Point3::new(1.0, -0.5, 0.5));
        assert_eq!(stats.above_points, 100);
        assert!(g
            .to_tri_grid(FloorGridMethod::LogOdds)
            .cells()
            .iter()
            .all(|c| *c == Occupancy::Unknown));
        assert_eq!(
            g.insert_cloud(&[], &Point3::new(1.0, -0.5, 0.5)),
            FloorInsertStats::default()
        );
        let off = g.insert_cloud(&ceiling, &Point3::new(f64::NAN, 0.0, 0.0));
        assert_eq!(off.skipped_points, 100);
        let bad = FloorGridConfig {
            min_height_m: 2.0,
            ..FloorGridConfig::default()
        };
        assert!(FloorGrid::new(10, 10, Point2::origin(), bad).is_err());
        assert!(FloorGrid::new(0, 10, Point2::origin(), FloorGridConfig::default()).is_err());
    }

    /// A 64 × 48 depth frame from a camera 0.5 m above the floor at (x, z) = (0, 0) looking
    /// along +z at a wall at z = 2.05 m, the floor nearer than the wall in the bottom rows, one
    /// hole and one NaN pixel.
    fn wall_depth_frame() -> (Image<f32>, Intrinsics, Pose3) {
        let k = Intrinsics::from_array([40.0, 40.0, 31.5, 23.5], 64, 48);
        let mut depth = Image::filled(64, 48, 0.0f32);
        for v in 0..48 {
            for u in 0..64 {
                let below = v as f64 - k.cy;
                let floor_z = if below > 0.0 {
                    0.5 * k.fy / below
                } else {
                    f64::INFINITY
                };
                *depth.get_mut(u, v).unwrap() = floor_z.min(2.05) as f32;
            }
        }
        *depth.get_mut(3, 20).unwrap() = 0.0;
        *depth.get_mut(4, 20).unwrap() = f32::NAN;
        (depth, k, Pose3::translation(0.0, -0.5, 0.0))
    }

    #[test]
    fn a_depth_frame_of_a_wall_marks_the_wall_and_frees_the_floor_before_it() {
        let (depth, k, map_from_camera) = wall_depth_frame();
        let points = depth_points(&depth, &k, &map_from_camera, 1);
        assert_eq!(points.len(), 64 * 48 - 2);
        let mut g =
            FloorGrid::new(40, 40, Point2::new(-2.0, -1.0), FloorGridConfig::default()).unwrap();
        let stats = g.insert_depth(&depth, &k, &map_from_camera, 1);
        // band 0.1-1.0 m on the wall: image rows 14..=31 (row 20 has the two bad pixels)
        assert_eq!(stats.obstacle_points, 18 * 64 - 2);
        assert_eq!(stats.skipped_points, 0);
        let t = g.to_tri_grid(FloorGridMethod::LogOdds);
        // the wall spans x = ±2.05 · 31.5 / 40 = ±1.61 m: columns 4..=35 at row 30
        for x in 4..=35 {
            assert_eq!(
                t.get(x, 30),
                Some(Occupancy::Occupied),
                "wall at column {x}"
            );
        }
        assert_eq!(t.get(2, 30), Some(Occupancy::Unknown));
        // from the camera's cell (20, 10) to the wall: free; behind the wall: unknown
        for y in 10..30 {
            assert_eq!(t.get(20, y), Some(Occupancy::Free), "row {y}");
        }
        assert_eq!(t.get(20, 31), Some(Occupancy::Unknown));
        // every other pixel: a quarter of the points
        let sparse = depth_points(&depth, &k, &map_from_camera, 2);
        assert_eq!(sparse.len(), 32 * 24 - 1);
    }
}
