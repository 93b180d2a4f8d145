//! The mean of the beam end points that fell in each cell of a particle's map, as GMapping's
//! `PointAccumulator` keeps it (G. Grisetti, C. Stachniss, W. Burgard, "Improved techniques for
//! grid mapping with Rao-Blackwellized particle filters", IEEE T-RO 23(1), 2007; the openslam
//! GMapping `ScanMatcher::score` reads `cell.mean()`).
//!
//! Scoring a beam end against the centre of its nearest occupied cell quantises the match to the
//! cell size: a wall that runs through the middle of 5 cm cells sits up to 2.5 cm from where the
//! cell centres say, and the scan matcher's optimum snaps to the cell lattice. Scoring against
//! the mean of the end points that made a cell occupied puts the wall where the laser saw it,
//! so the match, and each particle's trajectory, is accurate below the cell size.
//!
//! The means live in 64 × 64-cell tiles held in [`Arc`]s, indexed by tile coordinates: a
//! particle copied by resampling shares every tile, and a tile is copied the first time one
//! of its sharers writes into it ([`Arc::make_mut`]), as the occupancy grid's own tiles.

use nalgebra::{Point2, Vector2};
use slamkit_core::{LaserScan, Pose2};
use std::collections::{HashMap, HashSet};
use std::sync::Arc;

/// log2 of a tile's side in cells.
const TILE_BITS: u32 = 6;
/// Cells per tile side.
const TILE_SIDE: i32 = 1 << TILE_BITS;

/// Running mean of the end points in one cell, as an offset from the cell centre in cells.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct MeanCell {
    x: f32,
    y: f32,
    count: f32,
}

/// Hit counts above this no longer slow the mean down, so a cell keeps following the
/// latest hits a little (and the count stays exact in `f32`).
const MAX_COUNT: f32 = 1000.0;

#[derive(Debug, Clone)]
struct MeanTile {
    cells: [MeanCell; (TILE_SIDE * TILE_SIDE) as usize],
}

impl MeanTile {
    fn empty() -> Arc<Self> {
        Arc::new(Self {
            cells: [MeanCell::default(); (TILE_SIDE * TILE_SIDE) as usize],
        })
    }
}

/// Cell holding `p` (grid origin `origin`, `inv_resolution` cells per metre) and `p`'s offset
/// from that cell's centre, in cells; `None` for NaN or points far outside any grid. Shared
/// with the scan matcher, so both place a point in the same cell. (Rounds down without a
/// `floor` call: the matcher calls this for every beam of every candidate pose.)
#[inline]
pub(super) fn locate(
    origin: &Vector2<f64>,
    inv_resolution: f64,
    p: &Point2<f64>,
) -> Option<(i32, i32, f64, f64)> {
    let x = (p.x - origin.x) * inv_resolution;
    let y = (p.y - origin.y) * inv_resolution;
    if !(x.abs() < 1e8 && y.abs() < 1e8) {
        return None;
    }
    let round_down = |v: f64| {
        let i = v as i32;
        if f64::from(i) > v {
            i - 1
        } else {
            i
        }
    };
    let (cx, cy) = (round_down(x), round_down(y));
    Some((cx, cy, x - f64::from(cx) - 0.5, y - f64::from(cy) - 0.5))
}

fn tile_key(cx: i32, cy: i32) -> [i32; 2] {
    [cx >> TILE_BITS, cy >> TILE_BITS]
}

fn local(cx: i32, cy: i32) -> usize {
    (((cy & (TILE_SIDE - 1)) << TILE_BITS) | (cx & (TILE_SIDE - 1))) as usize
}

/// Per-cell mean hit points over a grid with the given origin and resolution (those of the
/// occupancy grid it accompanies, so cell indices agree).
#[derive(Debug, Clone)]
pub struct HitMeans {
    origin_m: Vector2<f64>,
    inv_resolution: f64,
    max_range_m: f64,
    tiles: HashMap<[i32; 2], Arc<MeanTile>>,
}

impl HitMeans {
    /// No hits yet. Beam ends beyond `max_range_m` are not recorded (the occupancy grid's
    /// `max_usable_range_m`, beyond which it marks no hit either).
    pub fn new(origin_m: Point2<f64>, resolution_m: f64, max_range_m: f64) -> Self {
        Self {
            origin_m: origin_m.coords,
            inv_resolution: 1.0 / resolution_m,
            max_range_m,
            tiles: HashMap::new(),
        }
    }

    /// Adds the end point of every hit of `scan`, taken with the laser at `world_from_laser`.
    pub fn insert_scan(&mut self, scan: &LaserScan, world_from_laser: &Pose2) {
        let (origin, inv_resolution) = (self.origin_m, self.inv_resolution);
        let mut cached: Option<([i32; 2], &mut MeanTile)> = None;
        for (i, &r) in scan.ranges_m.iter().enumerate() {
            if !(scan.is_hit(i) && r <= self.max_range_m) {
                continue;
            }
            let (s, c) = scan.beam_angle_rad(i).sin_cos();
            let end = world_from_laser * Point2::new(r * c, r * s);
            let Some((cx, cy, ox, oy)) = locate(&origin, inv_resolution, &end) else {
                continue;
            };
            let key = tile_key(cx, cy);
            let tile = match cached.take() {
                Some((k, tile)) if k == key => tile,
                _ => Arc::make_mut(self.tiles.entry(key).or_insert_with(MeanTile::empty)),
            };
            let cell = &mut tile.cells[local(cx, cy)];
            let count = (cell.count + 1.0).min(MAX_COUNT);
            cell.x += (ox as f32 - cell.x) / count;
            cell.y += (oy as f32 - cell.y) / count;
            cell.count = count;
            cached = Some((key, tile));
        }
    }

    /// A reader that remembers the last tile it looked up (neighbouring beams end in the same
    /// tile nearly always).
    pub fn reader(&self) -> MeanReader<'_> {
        MeanReader {
            means: self,
            key: None,
            tile: None,
        }
    }

    /// Number of tiles holding means.
    pub fn tiles(&self) -> usize {
        self.tiles.len()
    }

    /// Bytes of the tiles of all of `means`, each tile counted once however many of them share
    /// it.
    pub fn shared_bytes<'a>(means: impl IntoIterator<Item = &'a HitMeans>) -> usize {
        let mut seen = HashSet::new();
        for m in means {
            seen.extend(m.tiles.values().map(Arc::as_ptr));
        }
        seen.len() * std::mem::size_of::<MeanTile>()
    }
}

/// Reads mean hit points; see [`HitMeans::reader`].
pub struct MeanReader<'a> {
    means: &'a HitMeans,
    key: Option<[i32; 2]>,
    tile: Option<&'a MeanTile>,
}

impl MeanReader<'_> {
    /// Mean hit point of cell `(cx, cy)` as an offset from its centre, in cells; the centre
    /// itself for a cell no hit was recorded in.
    #[inline]
    pub fn offset(&mut self, cx: i32, cy: i32) -> (f64, f64) {
        let key = tile_key(cx, cy);
        if self.key != Some(key) {
            self.key = Some(key);
            self.tile = self.means.tiles.get(&key).map(|t| &**t);
        }
        match self.tile.map(|t| t.cells[local(cx, cy)]) {
            Some(c) if c.count > 0.0 => (f64::from(c.x), f64::from(c.y)),
            _ => (0.0, 0.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan_with(ranges: Vec<f64>) -> LaserScan {
        let n = ranges.len();
        LaserScan {
            timestamp: 0.0,
            ranges_m: ranges,
            angle_min_rad: 0.0,
            angle_increment_rad: if n > 1 { 0.01 } else { 0.0 },
            max_range_m: 30.0,
            odometry: None,
            base_from_laser: Pose2::identity(),
        }
    }

    #[test]
    fn mean_of_the_hits_in_a_cell() {
        let mut means = HitMeans::new(Point2::origin(), 0.1, 20.0);
        // Beam 0 along +x: ends at 1.02 m and 1.08 m fall in cell (10, 0), whose centre is 1.05.
        for r in [1.02, 1.08, 1.02, 1.08] {
            means.insert_scan(
                &scan_with(vec![r]),
                &Pose2::new(Vector2::new(0.0, 0.05), 0.0),
            );
        }
        let mut reader = means.reader();
        let (x, y) = reader.offset(10, 0);
        assert!(x.abs() < 1e-5 && y.abs() < 1e-5, "({x}, {y})");
        means.insert_scan(
            &scan_with(vec![1.01]),
            &Pose2::new(Vector2::new(0.0, 0.02), 0.0),
        );
        let mut reader = means.reader();
        let (x, y) = reader.offset(10, 0);
        // Mean of 1.02, 1.08, 1.02, 1.08, 1.01 → 1.042 m, -0.08 cells; y: 0.044 m → -0.06 cells.
        assert!((x + 0.08).abs() < 1e-4, "{x}");
        assert!((y + 0.06).abs() < 1e-4, "{y}");
        assert_eq!(reader.offset(3, 3), (0.0, 0.0), "no hit: the centre");
        assert_eq!(reader.offset(-500, 7), (0.0, 0.0), "no tile: the centre");
    }

    #[test]
    fn beyond_range_and_no_return_are_not_recorded() {
        let mut means = HitMeans::new(Point2::origin(), 0.1, 5.0);
        means.insert_scan(&scan_with(vec![7.0, f64::NAN, 30.0]), &Pose2::identity());
        assert_eq!(means.tiles(), 0);
    }

    #[test]
    fn copies_share_tiles_until_written() {
        let mut a = HitMeans::new(Point2::new(-3.2, -3.2), 0.05, 20.0);
        // 300 beams over 3 rad at 5 m: several 3.2 m tiles.
        a.insert_scan(&scan_with(vec![5.0; 300]), &Pose2::identity());
        assert!(a.tiles() > 2);
        let mut b = a.clone();
        let shared = |a: &HitMeans, b: &HitMeans| {
            a.tiles
                .iter()
                .filter(|(k, t)| b.tiles.get(*k).is_some_and(|u| Arc::ptr_eq(t, u)))
                .count()
        };
        assert_eq!(shared(&a, &b), a.tiles());
        b.insert_scan(&scan_with(vec![5.0]), &Pose2::identity());
        assert!(shared(&a, &b) < a.tiles());
        let one = a.tiles() * std::mem::size_of::<MeanTile>();
        assert_eq!(HitMeans::shared_bytes([&a]), one);
        assert!(HitMeans::shared_bytes([&a, &b]) > one);
        assert!(HitMeans::shared_bytes([&a, &b]) < 2 * one);
    }
}
