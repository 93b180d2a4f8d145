//! Log-odds occupancy grid built from 2D laser scans.
//!
//! Each cell holds the log-odds `l = ln(p / (1 - p))` that it is occupied (H. Moravec and
//! A. Elfes, "High resolution maps from wide angle sonar", ICRA 1985; S. Thrun, W. Burgard,
//! D. Fox, *Probabilistic Robotics*, 2005, ch. 9). A scan adds `l_hit` to each cell holding a beam
//! end point and `l_miss` to each cell a beam passed through, and the sum is clamped to
//! `[l_min, l_max]` so a cell can change its mind after the world changes (K. M. Wurm et al.,
//! "OctoMap", Autonomous Robots 34(3), 2013, section 3.3; the defaults here are OctoMap's).
//!
//! Beams are traced with Bresenham's algorithm ([`crate::raycast`]). Within one scan a cell is
//! updated at most once, and a hit wins over a pass-through, as in Cartographer's
//! `CastRays`: the cells are first marked in a byte array over the scan's bounding box, then
//! applied in raster order, one tile row at a time. Beams that return nothing clear free space up to a limit but mark no
//! obstacle.
//!
//! Cells live in copy-on-write 64 × 64 tiles (see `tiles.rs`); the grid grows as the robot
//! explores.
//! Cell `(i, j)` covers world `[origin + i·res, origin + (i+1)·res) × [...]`; indices may be
//! negative. Unknown cells hold log-odds 0.

use crate::error::MapError;
use crate::raycast::bresenham;
use crate::tiles::{local_index, Tile, TileStore, MAX_INDEX_TILES, TILE_BITS, TILE_SIZE};
use nalgebra::{Point2, Vector2};
use serde::{Deserialize, Serialize};
use slamkit_core::{LaserScan, Pose2};
use std::collections::HashSet;
use std::sync::Arc;

/// Largest |cell index| a grid addresses; keeps cell arithmetic far from `i32` overflow.
const MAX_CELL_INDEX: f64 = (1u32 << 28) as f64;

/// Parameters of the occupancy grid and its inverse sensor model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OccupancyGridConfig {
    /// Side length of a cell \[m\].
    pub resolution_m: f64,
    /// Probability that the cell holding a beam's end point is occupied \[0..1\].
    pub p_hit: f64,
    /// Probability that a cell a beam passed through is occupied \[0..1\].
    pub p_miss: f64,
    /// Lower clamp on a cell's probability \[0..1\].
    pub p_min: f64,
    /// Upper clamp on a cell's probability \[0..1\].
    pub p_max: f64,
    /// "No return" beams clear free space up to this distance, and never beyond the scan's
    /// maximum range \[m\].
    pub no_return_clear_m: f64,
    /// Hits farther than this are not trusted as obstacles; their beam clears free space up to
    /// this distance instead (GMapping's `maxUrange`) \[m\].
    pub max_usable_range_m: f64,
}

impl Default for OccupancyGridConfig {
    fn default() -> Self {
        Self {
            resolution_m: 0.05,
            p_hit: 0.7,
            p_miss: 0.4,
            p_min: 0.12,
            p_max: 0.97,
            no_return_clear_m: 5.0,
            max_usable_range_m: 50.0,
        }
    }
}

impl OccupancyGridConfig {
    /// Checks every value; the grid refuses a configuration that fails.
    pub fn validate(&self) -> Result<(), MapError> {
        let bad = |message: &str| {
            Err(MapError::InvalidConfig {
                message: message.to_string(),
            })
        };
        if !(self.resolution_m.is_finite() && self.resolution_m >= 1e-4) {
            return bad("resolution_m must be finite and at least 1e-4");
        }
        let ordered = 0.0 < self.p_min
            && self.p_min < self.p_miss
            && self.p_miss < 0.5
            && 0.5 < self.p_hit
            && self.p_hit < self.p_max
            && self.p_max < 1.0;
        if !ordered {
            return bad("need 0 < p_min < p_miss < 0.5 < p_hit < p_max < 1");
        }
        let ranges = [self.no_return_clear_m, self.max_usable_range_m];
        if !ranges
            .iter()
            .all(|r| r.is_finite() && *r >= 0.0 && *r <= 1e4)
        {
            return bad("no_return_clear_m and max_usable_range_m must lie in [0, 1e4]");
        }
        Ok(())
    }
}

/// Tri-state reading of a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Occupancy {
    /// More likely free than occupied (log-odds < 0).
    Free,
    /// More likely occupied than free (log-odds > 0).
    Occupied,
    /// Never observed, or evidence exactly balanced (log-odds = 0).
    Unknown,
}

impl Occupancy {
    /// The cell's value in a ROS `nav_msgs/OccupancyGrid` (and Foxglove's grids, numpy
    /// arrays of slamkit's Python package): 100 occupied, 0 free, -1 unknown.
    ///
    /// ```
    /// use slamkit_map::Occupancy;
    /// assert_eq!(Occupancy::Occupied.ros_value(), 100);
    /// assert_eq!(Occupancy::Unknown.ros_value(), -1);
    /// ```
    pub fn ros_value(self) -> i8 {
        match self {
            Self::Occupied => 100,
            Self::Free => 0,
            Self::Unknown => -1,
        }
    }

    /// Classifies a log-odds value.
    pub fn from_log_odds(log_odds: f32) -> Self {
        if log_odds > 0.0 {
            Self::Occupied
        } else if log_odds < 0.0 {
            Self::Free
        } else {
            Self::Unknown
        }
    }
}

/// Integer index of a grid cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CellIndex {
    /// Column (grows with world x).
    pub x: i32,
    /// Row (grows with world y).
    pub y: i32,
}

/// Inclusive rectangle of cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CellBounds {
    /// Lower-left cell.
    pub min: CellIndex,
    /// Upper-right cell.
    pub max: CellIndex,
}

impl CellBounds {
    /// Number of columns.
    pub fn width(&self) -> usize {
        (i64::from(self.max.x) - i64::from(self.min.x) + 1) as usize
    }
    /// Number of rows.
    pub fn height(&self) -> usize {
        (i64::from(self.max.y) - i64::from(self.min.y) + 1) as usize
    }
}

/// What happened to the beams of one inserted scan.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct InsertStats {
    /// Beams that marked an obstacle.
    pub hits: usize,
    /// Beams that only cleared free space (no return, or beyond the usable range).
    pub cleared: usize,
    /// Beams ignored: NaN, infinite, negative or zero ranges, or end points outside the map.
    pub ignored: usize,
}

/// Memory held by one grid or a set of grids sharing tiles.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TileStats {
    /// Tiles referenced, counting a shared tile once per grid.
    pub tile_references: usize,
    /// Distinct tiles in memory.
    pub unique_tiles: usize,
    /// Bytes of distinct tiles plus every grid's tile index.
    pub bytes: usize,
}

/// Mark of a cell no beam of the current scan touched.
const UNTOUCHED: u8 = 0;
/// Mark of a cell a beam of the current scan passed through.
const PASSED: u8 = 1;
/// Mark of a cell holding the end point of a hit of the current scan.
const HIT: u8 = 2;

/// Per-scan scratch space, kept to avoid reallocating on every insertion.
#[derive(Debug, Default)]
struct ScanScratch {
    /// End cell of each usable beam and whether it marks a hit.
    rays: Vec<(i32, i32, bool)>,
    /// One mark per cell of the scan's window, row-major.
    marks: Vec<u8>,
}

/// Converts a probability to log-odds.
pub fn log_odds_from_probability(p: f64) -> f32 {
    (p / (1.0 - p)).ln() as f32
}

/// Converts log-odds to a probability.
pub fn probability_from_log_odds(log_odds: f32) -> f64 {
    1.0 - 1.0 / (1.0 + f64::from(log_odds).exp())
}

/// The error for a bounding box of `[w, h]` tiles of cells of `resolution_m`.
fn too_large([w, h]: [u64; 2], resolution_m: f64) -> MapError {
    let tile_m = TILE_SIZE as f64 * resolution_m;
    MapError::TooLarge {
        width_m: w as f64 * tile_m,
        height_m: h as f64 * tile_m,
        limit_tiles: MAX_INDEX_TILES,
        tile_m,
    }
}

/// A growable 2D log-odds occupancy grid; see the module documentation.
#[derive(Debug)]
pub struct OccupancyGrid {
    config: OccupancyGridConfig,
    origin_m: Vector2<f64>,
    inv_resolution: f64,
    l_hit: f32,
    l_miss: f32,
    l_min: f32,
    l_max: f32,
    store: TileStore,
    scratch: ScanScratch,
}

impl Clone for OccupancyGrid {
    /// Shares every tile with `self`; scratch space is not copied.
    fn clone(&self) -> Self {
        Self {
            config: self.config.clone(),
            store: self.store.clone(),
            scratch: ScanScratch::default(),
            ..*self
        }
    }
}

impl OccupancyGrid {
    /// An empty grid whose cell (0, 0) has its lower-left corner at the world origin.
    pub fn new(config: OccupancyGridConfig) -> Result<Self, MapError> {
        Self::with_origin(config, Point2::origin())
    }

    /// An empty grid whose cell (0, 0) has its lower-left corner at `origin_m` (world frame).
    pub fn with_origin(
        config: OccupancyGridConfig,
        origin_m: Point2<f64>,
    ) -> Result<Self, MapError> {
        config.validate()?;
        if !(origin_m.x.is_finite() && origin_m.y.is_finite()) {
            return Err(MapError::OutsideMap {
                x_m: origin_m.x,
                y_m: origin_m.y,
            });
        }
        Ok(Self {
            inv_resolution: 1.0 / config.resolution_m,
            l_hit: log_odds_from_probability(config.p_hit),
            l_miss: log_odds_from_probability(config.p_miss),
            l_min: log_odds_from_probability(config.p_min),
            l_max: log_odds_from_probability(config.p_max),
            config,
            origin_m: origin_m.coords,
            store: TileStore::default(),
            scratch: ScanScratch::default(),
        })
    }

    /// The configuration the grid was built with.
    pub fn config(&self) -> &OccupancyGridConfig {
        &self.config
    }

    /// Side length of a cell \[m\].
    pub fn resolution_m(&self) -> f64 {
        self.config.resolution_m
    }

    /// World position of the lower-left corner of cell (0, 0) \[m\].
    pub fn origin_m(&self) -> Point2<f64> {
        Point2::from(self.origin_m)
    }

    /// Clamp range of the log-odds, `(l_min, l_max)`.
    pub fn log_odds_limits(&self) -> (f32, f32) {
        (self.l_min, self.l_max)
    }

    /// Cell containing world point `point_m`; `None` for NaN or points beyond the addressable area.
    #[inline]
    pub fn cell_at(&self, point_m: &Point2<f64>) -> Option<CellIndex> {
        let x = ((point_m.x - self.origin_m.x) * self.inv_resolution).floor();
        let y = ((point_m.y - self.origin_m.y) * self.inv_resolution).floor();
        // NaN fails both comparisons.
        (x.abs() < MAX_CELL_INDEX && y.abs() < MAX_CELL_INDEX).then_some(CellIndex {
            x: x as i32,
            y: y as i32,
        })
    }

    /// World position of the centre of `cell` \[m\].
    pub fn cell_center_m(&self, cell: CellIndex) -> Point2<f64> {
        let res = self.config.resolution_m;
        Point2::new(
            self.origin_m.x + (f64::from(cell.x) + 0.5) * res,
            self.origin_m.y + (f64::from(cell.y) + 0.5) * res,
        )
    }

    /// Log-odds of `cell`; `None` outside the area the grid has grown to.
    #[inline]
    pub fn log_odds(&self, cell: CellIndex) -> Option<f32> {
        self.store.get(cell.x, cell.y)
    }

    /// Log-odds of the `len` cells from `first` along +x, when they lie in one tile of the grown
    /// area; `None` otherwise (read them with [`Self::log_odds`]).
    #[inline]
    pub fn log_odds_row(&self, first: CellIndex, len: usize) -> Option<&[f32]> {
        self.store.row(first.x, first.y, len)
    }

    /// Occupancy probability of `cell`; `None` outside the grid.
    pub fn probability(&self, cell: CellIndex) -> Option<f64> {
        self.log_odds(cell).map(probability_from_log_odds)
    }

    /// Tri-state of `cell`; `None` outside the grid.
    pub fn occupancy(&self, cell: CellIndex) -> Option<Occupancy> {
        self.log_odds(cell).map(Occupancy::from_log_odds)
    }

    /// Log-odds at world point `point_m`; `None` outside the grid.
    pub fn log_odds_at(&self, point_m: &Point2<f64>) -> Option<f32> {
        self.log_odds(self.cell_at(point_m)?)
    }

    /// Occupancy probability at world point `point_m`; `None` outside the grid.
    pub fn probability_at(&self, point_m: &Point2<f64>) -> Option<f64> {
        self.probability(self.cell_at(point_m)?)
    }

    /// Tri-state at world point `point_m`; `None` outside the grid.
    pub fn occupancy_at(&self, point_m: &Point2<f64>) -> Option<Occupancy> {
        self.occupancy(self.cell_at(point_m)?)
    }

    /// Sets the log-odds of `cell`, clamped to the grid's limits (NaN becomes unknown), growing
    /// the grid when needed.
    ///
    /// # Errors
    /// [`MapError::TooLarge`] when the grid would span more than [`MAX_INDEX_TILES`] tiles.
    pub fn set_log_odds(&mut self, cell: CellIndex, log_odds: f32) -> Result<(), MapError> {
        let value = if log_odds.is_nan() {
            0.0
        } else {
            log_odds.clamp(self.l_min, self.l_max)
        };
        let resolution_m = self.config.resolution_m;
        *self
            .store
            .cell_mut(cell.x, cell.y)
            .map_err(|tiles| too_large(tiles, resolution_m))? = value;
        Ok(())
    }

    /// Smallest rectangle holding every known (non-zero) cell; `None` for an empty grid.
    pub fn known_bounds(&self) -> Option<CellBounds> {
        let mut bounds: Option<CellBounds> = None;
        for ([x0, y0], tile) in self.store.tiles() {
            for (i, _) in tile.cells.iter().enumerate().filter(|(_, l)| **l != 0.0) {
                let cell = CellIndex {
                    x: x0 + (i % TILE_SIZE) as i32,
                    y: y0 + (i / TILE_SIZE) as i32,
                };
                let b = bounds.get_or_insert(CellBounds {
                    min: cell,
                    max: cell,
                });
                b.min.x = b.min.x.min(cell.x);
                b.min.y = b.min.y.min(cell.y);
                b.max.x = b.max.x.max(cell.x);
                b.max.y = b.max.y.max(cell.y);
            }
        }
        bounds
    }

    /// Memory held by this grid alone, counting shared tiles as if owned.
    pub fn tile_stats(&self) -> TileStats {
        shared_tile_stats([self])
    }

    /// Inserts a scan taken with the laser at `world_from_laser`: cells holding beam end points
    /// gain `l_hit`, cells the beams passed through gain `l_miss` (each cell once per scan, a hit
    /// winning), and "no return" beams clear free space up to
    /// `min(no_return_clear_m, scan.max_range_m)` without marking a hit. NaN, infinite, zero and
    /// negative ranges are ignored.
    pub fn insert_scan(
        &mut self,
        scan: &LaserScan,
        world_from_laser: &Pose2,
    ) -> Result<InsertStats, MapError> {
        let t = world_from_laser.translation.vector;
        let angle_rad = world_from_laser.rotation.angle();
        if !(t.x.is_finite() && t.y.is_finite() && angle_rad.is_finite()) {
            return Err(MapError::NonFinitePose {
                x_m: t.x,
                y_m: t.y,
                angle_rad,
            });
        }
        let origin = self
            .cell_at(&Point2::from(t))
            .ok_or(MapError::OutsideMap { x_m: t.x, y_m: t.y })?;
        let mut scratch = std::mem::take(&mut self.scratch);
        let stats = self.beam_end_cells(scan, world_from_laser, &mut scratch.rays);
        let window = MarkWindow::around(origin, &scratch.rays);
        window.mark_rays(origin, &mut scratch);
        if let Err(tiles) = self.store.cover_tiles(window.min_tile(), window.max_tile()) {
            self.scratch = scratch;
            return Err(too_large(tiles, self.config.resolution_m));
        }
        self.apply_marks(&window, &scratch.marks);
        self.scratch = scratch;
        Ok(stats)
    }

    /// Fills `rays` with the end cell of every usable beam and whether it is a hit.
    fn beam_end_cells(
        &self,
        scan: &LaserScan,
        world_from_laser: &Pose2,
        rays: &mut Vec<(i32, i32, bool)>,
    ) -> InsertStats {
        rays.clear();
        let mut stats = InsertStats::default();
        let t = world_from_laser.translation.vector;
        let clear_m = self.config.no_return_clear_m.min(scan.max_range_m);
        // Beam directions by repeated rotation: one sin_cos per scan instead of one per beam.
        let first = world_from_laser.rotation * nalgebra::UnitComplex::new(scan.angle_min_rad);
        let increment = nalgebra::UnitComplex::new(scan.angle_increment_rad);
        let mut direction = *first.complex();
        for (i, &range_m) in scan.ranges_m.iter().enumerate() {
            let (cos, sin) = (direction.re, direction.im);
            direction *= *increment.complex();
            let (reach_m, hit) = if scan.is_hit(i) {
                if range_m <= self.config.max_usable_range_m {
                    (range_m, true)
                } else {
                    (self.config.max_usable_range_m, false)
                }
            } else if range_m.is_finite() && range_m >= scan.max_range_m {
                (clear_m, false)
            } else {
                stats.ignored += 1;
                continue;
            };
            let Some(end) = self.cell_at(&Point2::new(t.x + reach_m * cos, t.y + reach_m * sin))
            else {
                stats.ignored += 1;
                continue;
            };
            rays.push((end.x, end.y, hit));
            if hit {
                stats.hits += 1;
            } else {
                stats.cleared += 1;
            }
        }
        stats
    }

    /// Applies the marks to the cells tile by tile, so each touched tile is made writable
    /// ([`Arc::make_mut`], an atomic operation) once per scan rather than once per row.
    fn apply_marks(&mut self, window: &MarkWindow, marks: &[u8]) {
        let stride = window.tiles_per_row * TILE_SIZE;
        let mut band_start = 0;
        while band_start < window.rows {
            let cy0 = window.y0 + band_start as i32;
            let band_end = window
                .rows
                .min(band_start + TILE_SIZE - (cy0 & (TILE_SIZE as i32 - 1)) as usize);
            for column in 0..window.tiles_per_row {
                let segment = |row: usize| {
                    let start = row * stride + column * TILE_SIZE;
                    &marks[start..start + TILE_SIZE]
                };
                let touched = |row: &usize| segment(*row).iter().fold(UNTOUCHED, |a, m| a | m) != 0;
                let Some(first) = (band_start..band_end).find(touched) else {
                    continue;
                };
                let tx = (window.x0 >> TILE_BITS) + column as i32;
                let Some(index) = self.store.tile_index(tx, cy0 >> TILE_BITS) else {
                    continue;
                };
                let tile: &mut Tile = self.store.tile_mut(index);
                for row in (first..band_end).filter(touched) {
                    let start = local_index(0, window.y0 + row as i32);
                    let cells = &mut tile.cells[start..start + TILE_SIZE];
                    apply_row(
                        cells,
                        segment(row),
                        self.l_hit,
                        self.l_miss,
                        self.l_min,
                        self.l_max,
                    );
                }
            }
            band_start = band_end;
        }
    }
}

/// Adds `l_hit` to the cells marked hit and `l_miss` to those marked passed, clamped to
/// `[l_min, l_max]`. Branch-free so it vectorises: untouched cells add 0 and are already in range.
#[inline]
fn apply_row(cells: &mut [f32], marks: &[u8], l_hit: f32, l_miss: f32, l_min: f32, l_max: f32) {
    for (cell, &mark) in cells.iter_mut().zip(marks) {
        let step = match mark {
            HIT => l_hit,
            PASSED => l_miss,
            _ => 0.0,
        };
        let value = *cell + step;
        // Comparisons rather than f32::max/min: no NaN handling, plain minps/maxps.
        let value = if value < l_min { l_min } else { value };
        *cell = if value > l_max { l_max } else { value };
    }
}

/// Memory of a set of grids, counting each shared tile once (for particle filters).
pub fn shared_tile_stats<'a>(grids: impl IntoIterator<Item = &'a OccupancyGrid>) -> TileStats {
    let mut seen = HashSet::new();
    let mut stats = TileStats::default();
    for grid in grids {
        stats.bytes += grid.store.index_bytes();
        for (_, tile) in grid.store.tiles() {
            stats.tile_references += 1;
            if seen.insert(Arc::as_ptr(tile)) {
                stats.unique_tiles += 1;
                stats.bytes += std::mem::size_of::<Tile>();
            }
        }
    }
    stats
}

/// The rectangle of cells a scan can touch, one mark byte per cell. Its left edge is
/// tile-aligned and its width a multiple of the tile size, so each run of 64 marks maps onto one
/// row of one tile.
#[derive(Debug)]
struct MarkWindow {
    x0: i32,
    y0: i32,
    tiles_per_row: usize,
    rows: usize,
}

impl MarkWindow {
    fn around(origin: CellIndex, rays: &[(i32, i32, bool)]) -> Self {
        let (mut lo, mut hi) = ([origin.x, origin.y], [origin.x, origin.y]);
        for &(x, y, _) in rays {
            lo = [lo[0].min(x), lo[1].min(y)];
            hi = [hi[0].max(x), hi[1].max(y)];
        }
        let x0 = lo[0] & !(TILE_SIZE as i32 - 1);
        Self {
            x0,
            y0: lo[1],
            tiles_per_row: ((hi[0] - x0) as usize >> TILE_BITS) + 1,
            rows: (hi[1] - lo[1]) as usize + 1,
        }
    }

    fn min_tile(&self) -> [i32; 2] {
        [self.x0 >> TILE_BITS, self.y0 >> TILE_BITS]
    }

    fn max_tile(&self) -> [i32; 2] {
        let x1 = self.x0 + (self.tiles_per_row * TILE_SIZE) as i32 - 1;
        let y1 = self.y0 + self.rows as i32 - 1;
        [x1 >> TILE_BITS, y1 >> TILE_BITS]
    }

    /// Marks every cell of every ray as passed, then every hit end cell as hit. Plain byte
    /// stores: no read-modify-write chain between neighbouring cells of a ray.
    fn mark_rays(&self, origin: CellIndex, scratch: &mut ScanScratch) {
        let stride = self.tiles_per_row * TILE_SIZE;
        scratch.marks.clear();
        scratch.marks.resize(stride * self.rows, UNTOUCHED);
        let (x0, y0) = (self.x0, self.y0);
        let index = |x: i32, y: i32| (y - y0) as usize * stride + (x - x0) as usize;
        let marks = &mut scratch.marks;
        for &(x, y, _) in &scratch.rays {
            bresenham(origin.x, origin.y, x, y, |cx, cy| {
                marks[index(cx, cy)] = PASSED
            });
        }
        for &(x, y, hit) in &scratch.rays {
            if hit {
                marks[index(x, y)] = HIT;
            }
        }
    }
}

#[cfg(test)]
#[path = "occupancy_grid_tests.rs"]
mod tests;
