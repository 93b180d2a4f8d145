//! Exact nearest-neighbour search on a uniform grid, for queries with a bounded radius.
//!
//! ICP only asks for neighbours within its correspondence threshold (at most a few decimetres),
//! and its map is thinned to one point per voxel, so a regular grid answers a query by reading
//! the few cells around it: no tree descent, no backtracking, and the build is one counting sort
//! (the "uniform grid" of Akenine-Möller et al., *Real-Time Rendering*, ch. 25, used for ICP
//! correspondences by, e.g., KISS-ICP's voxel hash map, Vizzo et al. 2023). Cells are stored
//! row-major in compressed form (points sorted by cell, one start offset per cell), so a run of
//! cells along a row is one contiguous slice of points.
//!
//! The search visits square rings of cells around the query's cell, nearest ring first, and
//! stops once the nearest point found (the k-th, for [`GridIndex::nearest_k_within`]) is closer
//! than anything the next ring could hold, or the ring lies beyond the radius: the answer is
//! exact.

use super::{normals_or_none, NearestNeighbours, Neighbour};
use crate::cloud::floor_i64;
use nalgebra::{Point2, Vector2};

/// Points and queries farther than this from the origin along an axis are ignored (no scanner
/// sees them; it keeps cell arithmetic far from overflow) \[m\].
const MAX_COORDINATE_M: f64 = 1e7;

/// Cells are never smaller than this \[m\]: with points and queries within
/// `MAX_COORDINATE_M`, cell coordinates then stay below 10¹² in magnitude, far from overflow.
const MIN_CELL_M: f64 = 1e-4;

/// The grid never has more cells than this; a wider point set gets larger cells.
const MAX_CELLS: usize = 1 << 22;

/// Points (with optional unit normals) sorted into the cells of a uniform grid.
pub struct GridIndex {
    points: Vec<Point2<f64>>,
    normals: Vec<Option<Vector2<f64>>>,
    cell_m: f64,
    origin: Point2<f64>,
    width: usize,
    height: usize,
    /// Points of cell `k` are `sorted[starts[k]..starts[k + 1]]` (row-major `k = j·width + i`).
    starts: Vec<u32>,
    /// Indexed points in cell order.
    sorted: Vec<Point2<f64>>,
    /// Index into `points` of each entry of `sorted`.
    sorted_ids: Vec<u32>,
}

impl GridIndex {
    /// Indexes `points` in cells of side `cell_m` (a few times the map's point spacing and below
    /// the usual query radius is fastest; any positive size gives the same answers). `normals`,
    /// when given, must have one entry per point; a length mismatch drops them. Non-finite
    /// points are kept (so indices match the input) but never returned by a query.
    pub fn new(
        points: Vec<Point2<f64>>,
        normals: Option<Vec<Option<Vector2<f64>>>>,
        cell_m: f64,
    ) -> Self {
        let normals = normals_or_none(normals, points.len());
        let usable =
            |p: &Point2<f64>| p.x.abs() <= MAX_COORDINATE_M && p.y.abs() <= MAX_COORDINATE_M;
        let (min, max) = points.iter().filter(|p| usable(p)).fold(
            (
                Point2::new(f64::MAX, f64::MAX),
                Point2::new(f64::MIN, f64::MIN),
            ),
            |(lo, hi), p| (lo.inf(p), hi.sup(p)),
        );
        let mut cell_m = if cell_m.is_finite() && cell_m > 0.0 {
            cell_m.max(MIN_CELL_M)
        } else {
            0.1
        };
        let extent = (max - min).map(|e| e.max(0.0));
        // Grow the cells until the grid fits the cell budget.
        while (extent.x / cell_m + 1.0) * (extent.y / cell_m + 1.0) > MAX_CELLS as f64 {
            cell_m *= 2.0;
        }
        let (width, height) = if min.x <= max.x {
            (
                (extent.x / cell_m).floor() as usize + 1,
                (extent.y / cell_m).floor() as usize + 1,
            )
        } else {
            (0, 0)
        };
        let mut grid = Self {
            points,
            normals,
            cell_m,
            origin: if width > 0 { min } else { Point2::origin() },
            width,
            height,
            starts: Vec::new(),
            sorted: Vec::new(),
            sorted_ids: Vec::new(),
        };
        grid.sort_into_cells(usable);
        grid
    }

    /// Counting sort of the usable points by cell.
    fn sort_into_cells(&mut self, usable: impl Fn(&Point2<f64>) -> bool) {
        let cells: Vec<Option<usize>> = self
            .points
            .iter()
            .map(|p| usable(p).then(|| self.cell_of(p)).flatten())
            .collect();
        let mut starts = vec![0u32; self.width * self.height + 1];
        for k in cells.iter().flatten() {
            if let Some(s) = starts.get_mut(k + 1) {
                *s += 1;
            }
        }
        for k in 1..starts.len() {
            starts[k] += starts[k - 1];
        }
        let mut next = starts.clone();
        let total = starts.last().copied().unwrap_or(0) as usize;
        self.sorted = vec![Point2::origin(); total];
        self.sorted_ids = vec![0; total];
        for (id, k) in cells.iter().enumerate() {
            let Some(slot) = k.and_then(|k| next.get_mut(k)) else {
                continue;
            };
            let at = *slot as usize;
            *slot += 1;
            if let (Some(p), Some(s), Some(i)) = (
                self.points.get(id),
                self.sorted.get_mut(at),
                self.sorted_ids.get_mut(at),
            ) {
                *s = *p;
                *i = id as u32;
            }
        }
        self.starts = starts;
    }

    /// Row-major cell of an indexed point.
    fn cell_of(&self, p: &Point2<f64>) -> Option<usize> {
        let ((i, j), _) = self.cell_coords(p);
        let (i, j) = (usize::try_from(i).ok()?, usize::try_from(j).ok()?);
        (i < self.width && j < self.height).then_some(j * self.width + i)
    }

    /// Cell coordinates of `p` (possibly outside the grid; `p` within `MAX_COORDINATE_M`), and
    /// `p`'s position in cells from the grid origin.
    fn cell_coords(&self, p: &Point2<f64>) -> ((i64, i64), Vector2<f64>) {
        let f = (p - self.origin) / self.cell_m;
        ((floor_i64(f.x), floor_i64(f.y)), f)
    }

    /// Side of the cells \[m\] (larger than asked when the points spread very wide).
    pub fn cell_m(&self) -> f64 {
        self.cell_m
    }

    /// Offers the points of cells `i0..=i1` of row `j` (clipped to the grid) to `state`.
    fn scan_row<S: RingSearch>(&self, q: &Point2<f64>, j: i64, i0: i64, i1: i64, state: &mut S) {
        let (w, h) = (self.width as i64, self.height as i64);
        let (i0, i1) = (i0.max(0), i1.min(w - 1));
        if j < 0 || j >= h || i0 > i1 {
            return;
        }
        let row = j * w;
        let (Ok(a), Ok(b)) = (usize::try_from(row + i0), usize::try_from(row + i1 + 1)) else {
            return;
        };
        let (Some(&start), Some(&end)) = (self.starts.get(a), self.starts.get(b)) else {
            return;
        };
        let start = start as usize;
        let Some(pts) = self.sorted.get(start..end as usize) else {
            return;
        };
        for (at, p) in (start..).zip(pts) {
            state.offer(at, (p - q).norm_squared());
        }
    }

    /// Visits the rings of cells around `query`, nearest first, until the next ring lies
    /// farther than `state`'s bound or the rings cover the grid. Returns a distance every point
    /// not offered is at least from the query, or `None` (nothing visited) for an empty index,
    /// a query beyond `MAX_COORDINATE_M` or a NaN one.
    fn search_rings<S: RingSearch>(&self, query: &Point2<f64>, state: &mut S) -> Option<f64> {
        let far = |v: f64| v.is_nan() || v.abs() > MAX_COORDINATE_M;
        if self.sorted.is_empty() || far(query.x) || far(query.y) {
            return None;
        }
        let ((ci, cj), f) = self.cell_coords(query);
        let (fx, fy) = (f.x - ci as f64, f.y - cj as f64);
        // Distance (in cells) from the query to the border of its own cell.
        // (plain comparisons: nothing here is NaN, and NaN-aware min/max cost more)
        let smaller = |a: f64, b: f64| if b < a { b } else { a };
        let inner = smaller(smaller(fx, 1.0 - fx), smaller(fy, 1.0 - fy));
        let inner = if inner > 0.0 { inner } else { 0.0 };
        let (w, h) = (self.width as i64, self.height as i64);
        // Rings nearer than this hold no cell of the grid.
        let mut k = [0, -ci, ci - (w - 1), -cj, cj - (h - 1)]
            .into_iter()
            .max()
            .unwrap_or(0);
        loop {
            // Every cell of ring k or beyond is at least this far from the query.
            let ring_min = if k == 0 {
                0.0
            } else {
                ((k - 1) as f64 + inner) * self.cell_m
            };
            if ring_min * ring_min > state.bound_d2() {
                return Some(ring_min);
            }
            if k == 0 {
                self.scan_row(query, cj, ci, ci, state);
            } else {
                self.scan_row(query, cj - k, ci - k, ci + k, state);
                self.scan_row(query, cj + k, ci - k, ci + k, state);
                for j in (cj - k + 1).max(0)..=(cj + k - 1).min(h - 1) {
                    self.scan_row(query, j, ci - k, ci - k, state);
                    self.scan_row(query, j, ci + k, ci + k, state);
                }
            }
            let covers_grid = ci - k <= 0 && cj - k <= 0 && ci + k >= w - 1 && cj + k >= h - 1;
            if covers_grid {
                return Some(f64::INFINITY);
            }
            k += 1;
        }
    }

    /// Up to `k` indexed points nearest to `query` and at most `max_dist_m` from it, closest
    /// first (equal distances by index): the neighbourhoods of [`crate::cloud::estimate_normals`],
    /// a few times faster than a k-d tree on one scan's points. Empty for a NaN or negative
    /// radius, a NaN query or `k = 0`.
    ///
    /// ```
    /// use nalgebra::Point2;
    /// use slamkit_lidar::nn::GridIndex;
    ///
    /// let wall: Vec<Point2<f64>> = (0..10).map(|i| Point2::new(i as f64 * 0.1, 0.0)).collect();
    /// let grid = GridIndex::new(wall, None, 0.25);
    /// let near = grid.nearest_k_within(&Point2::new(0.42, 0.0), 3, 0.5);
    /// let ids: Vec<usize> = near.iter().map(|n| n.index).collect();
    /// assert_eq!(ids, [4, 5, 3]);
    /// assert!(grid.nearest_k_within(&Point2::new(5.0, 0.0), 3, 0.5).is_empty());
    /// ```
    pub fn nearest_k_within(
        &self,
        query: &Point2<f64>,
        k: usize,
        max_dist_m: f64,
    ) -> Vec<Neighbour> {
        if k == 0 || max_dist_m.is_nan() || max_dist_m < 0.0 {
            return Vec::new();
        }
        let limit = max_dist_m.min(f64::MAX);
        let mut state = KNearest {
            k,
            limit_d2: limit * limit,
            found: Vec::with_capacity(k + 1),
            ids: &self.sorted_ids,
        };
        self.search_rings(query, &mut state);
        state
            .found
            .into_iter()
            .map(|(d2, id)| Neighbour {
                index: id as usize,
                distance_m: d2.sqrt(),
            })
            .filter(|n| n.distance_m <= max_dist_m)
            .collect()
    }
}

/// What a ring search keeps of the points it is offered.
trait RingSearch {
    /// Points farther than this (squared) are of no more use.
    fn bound_d2(&self) -> f64;
    /// Offers the point at `at` in `sorted`, at squared distance `d2` from the query.
    fn offer(&mut self, at: usize, d2: f64);
}

/// No point found yet.
const NONE: usize = usize::MAX;

/// The state of a query: the nearest point so far and how close the others come.
struct Found {
    /// Squared distance of the nearest point so far (the squared radius before any).
    best_d2: f64,
    /// Its position in `sorted` (`NONE` before any point is found).
    best: usize,
    /// Smallest squared distance of the other points read so far.
    other_d2: f64,
}

impl RingSearch for Found {
    fn bound_d2(&self) -> f64 {
        self.best_d2
    }

    fn offer(&mut self, at: usize, d2: f64) {
        if d2 < self.best_d2 || (d2 == self.best_d2 && self.best == NONE) {
            if self.best != NONE && self.best_d2 < self.other_d2 {
                self.other_d2 = self.best_d2;
            }
            self.best_d2 = d2;
            self.best = at;
        } else if d2 < self.other_d2 {
            self.other_d2 = d2;
        }
    }
}

/// The state of a k-nearest query: up to `k` points so far, by (squared distance, index).
struct KNearest<'a> {
    k: usize,
    /// The squared radius.
    limit_d2: f64,
    found: Vec<(f64, u32)>,
    /// Index into the points of each entry of `sorted`.
    ids: &'a [u32],
}

impl RingSearch for KNearest<'_> {
    fn bound_d2(&self) -> f64 {
        match self.found.get(self.k - 1) {
            Some(&(d2, _)) => d2,
            None => self.limit_d2,
        }
    }

    fn offer(&mut self, at: usize, d2: f64) {
        let Some(&id) = self.ids.get(at) else {
            return;
        };
        if d2 > self.bound_d2() {
            return;
        }
        let entry = (d2, id);
        let pos = self
            .found
            .partition_point(|&(d, i)| d < d2 || (d == d2 && i < id));
        if pos < self.k {
            self.found.insert(pos, entry);
            self.found.truncate(self.k);
        }
    }
}

impl NearestNeighbours for GridIndex {
    fn nearest_within(&self, query: &Point2<f64>, max_dist_m: f64) -> Option<Neighbour> {
        self.nearest_within_clear(query, max_dist_m).0
    }

    fn nearest_within_clear(
        &self,
        query: &Point2<f64>,
        max_dist_m: f64,
    ) -> (Option<Neighbour>, f64) {
        let usable = !(query.x.is_nan() || query.y.is_nan())
            && query.x.abs() <= MAX_COORDINATE_M
            && query.y.abs() <= MAX_COORDINATE_M;
        if self.sorted.is_empty() {
            return (None, f64::INFINITY);
        }
        if !usable || max_dist_m.is_nan() || max_dist_m < 0.0 {
            // A query no clearance is given for.
            return (None, 0.0);
        }
        let limit = max_dist_m.min(f64::MAX);
        let mut found = Found {
            best_d2: limit * limit,
            best: NONE,
            other_d2: f64::INFINITY,
        };
        // Every point not read yet is at least this far from the query.
        let unread = self.search_rings(query, &mut found).unwrap_or(0.0);
        let clear = found.other_d2.sqrt().min(unread);
        let nearest = self.sorted_ids.get(found.best).map(|&id| Neighbour {
            index: id as usize,
            distance_m: found.best_d2.sqrt(),
        });
        (nearest, clear)
    }

    fn points(&self) -> &[Point2<f64>] {
        &self.points
    }

    fn normals(&self) -> &[Option<Vector2<f64>>] {
        &self.normals
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Nearest point of `pts` within `r` of `q` by brute force: (distance, index).
    fn brute(pts: &[Point2<f64>], q: &Point2<f64>, r: f64) -> Option<(f64, usize)> {
        pts.iter()
            .enumerate()
            .filter(|(_, p)| p.x.is_finite() && p.y.is_finite())
            .map(|(i, p)| ((p - q).norm(), i))
            .filter(|(d, _)| *d <= r)
            .min_by(|a, b| a.0.total_cmp(&b.0))
    }

    fn check(grid: &GridIndex, pts: &[Point2<f64>], q: &Point2<f64>, r: f64) {
        let got = grid.nearest_within(q, r);
        match (brute(pts, q, r), got) {
            (None, None) => {}
            (Some((d, _)), Some(n)) => {
                assert!(
                    (n.distance_m - d).abs() < 1e-12,
                    "{q:?} r {r}: {} vs {d}",
                    n.distance_m
                );
                let p = grid.point(n.index).unwrap();
                assert!(((p - q).norm() - d).abs() < 1e-12);
            }
            (b, g) => panic!("{q:?} r {r}: brute {b:?}, grid {g:?}"),
        }
    }

    #[test]
    fn random_points_match_brute_force_at_every_cell_size_and_radius() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let pts: Vec<Point2<f64>> = (0..400)
            .map(|_| Point2::new(rng.gen_range(-5.0..5.0), rng.gen_range(-3.0..3.0)))
            .collect();
        for cell in [0.03, 0.1, 0.3, 2.0, 50.0] {
            let grid = GridIndex::new(pts.clone(), None, cell);
            for _ in 0..300 {
                let q = Point2::new(rng.gen_range(-7.0..7.0), rng.gen_range(-5.0..5.0));
                for r in [0.0, 0.05, 0.3, 1.0, f64::INFINITY] {
                    check(&grid, &pts, &q, r);
                }
            }
        }
    }

    #[test]
    fn walls_and_far_queries_match_brute_force() {
        // Two axis-aligned walls at the map's 5 cm spacing, queried on and far off the grid.
        let mut pts = Vec::new();
        for i in 0..200 {
            pts.push(Point2::new(6.0, -4.0 + i as f64 * 0.05));
            pts.push(Point2::new(-6.0 + i as f64 * 0.05, 4.0));
        }
        let grid = GridIndex::new(pts.clone(), None, 0.1);
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        for _ in 0..500 {
            let q = Point2::new(rng.gen_range(-40.0..40.0), rng.gen_range(-40.0..40.0));
            for r in [0.3, 5.0, f64::INFINITY] {
                check(&grid, &pts, &q, r);
            }
        }
        // Exactly on a point, and at exactly the radius.
        let on = grid.nearest_within(&Point2::new(6.0, 1.0), 0.0).unwrap();
        assert_eq!(on.distance_m, 0.0);
        assert!(grid.nearest_within(&Point2::new(6.5, 1.0), 0.5).is_some());
        assert!(grid
            .nearest_within(&Point2::new(6.5, 1.0), 0.4999)
            .is_none());
    }

    #[test]
    fn bad_points_queries_and_sizes_give_no_panic() {
        let pts = vec![
            Point2::new(f64::NAN, 1.0),
            Point2::new(1.0, 1.0),
            Point2::new(1.0, 1.0),
            Point2::new(1e300, 0.0),
            Point2::new(f64::INFINITY, 0.0),
        ];
        for cell in [0.1, 0.0, -1.0, f64::NAN, 1e-300] {
            let grid = GridIndex::new(pts.clone(), Some(vec![None; 2]), cell);
            assert_eq!(grid.len(), 5);
            let n = grid.nearest_within(&Point2::new(0.0, 1.0), 10.0).unwrap();
            assert!(n.index == 1 || n.index == 2);
            assert_eq!(n.distance_m, 1.0);
            assert!(grid.normal(1).is_none());
            assert!(grid
                .nearest_within(&Point2::new(f64::NAN, 0.0), 1.0)
                .is_none());
            assert!(grid
                .nearest_within(&Point2::new(0.0, 0.0), f64::NAN)
                .is_none());
            assert!(grid.nearest_within(&Point2::new(1e300, 0.0), 1.0).is_none());
            let far = grid
                .nearest_within(&Point2::new(9e6, -9e6), f64::INFINITY)
                .unwrap();
            assert!(far.index == 1 || far.index == 2);
        }
        let empty = GridIndex::new(Vec::new(), None, 0.1);
        assert!(empty.is_empty());
        assert!(empty
            .nearest_within(&Point2::origin(), f64::INFINITY)
            .is_none());
    }

    #[test]
    fn clearance_bounds_every_other_point() {
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        let pts: Vec<Point2<f64>> = (0..300)
            .map(|_| Point2::new(rng.gen_range(-4.0..4.0), rng.gen_range(-2.0..2.0)))
            .collect();
        for cell in [0.05, 0.1, 0.4] {
            let grid = GridIndex::new(pts.clone(), None, cell);
            let mut clear_sum = 0.0;
            for _ in 0..400 {
                let q = Point2::new(rng.gen_range(-5.0..5.0), rng.gen_range(-3.0..3.0));
                let r = rng.gen_range(0.0..0.5);
                let (nearest, clear) = grid.nearest_within_clear(&q, r);
                assert_eq!(nearest, grid.nearest_within(&q, r));
                let skip = nearest.map(|n| n.index);
                for (i, p) in pts.iter().enumerate() {
                    if Some(i) != skip {
                        assert!((p - q).norm() >= clear - 1e-12, "{q:?} r {r} point {i}");
                    }
                }
                if let Some(n) = nearest {
                    assert!(clear >= n.distance_m);
                } else {
                    assert!(clear >= r);
                }
                clear_sum += clear;
            }
            // The clearance is a useful bound, not zero.
            assert!(
                clear_sum / 400.0 > 0.05,
                "cell {cell}: {}",
                clear_sum / 400.0
            );
        }
        let empty = GridIndex::new(Vec::new(), None, 0.1);
        assert_eq!(
            empty.nearest_within_clear(&Point2::origin(), 1.0).1,
            f64::INFINITY
        );
    }

    #[test]
    fn k_nearest_match_brute_force_with_ties_by_index() {
        let mut rng = ChaCha8Rng::seed_from_u64(14);
        let mut pts: Vec<Point2<f64>> = (0..300)
            .map(|_| Point2::new(rng.gen_range(-4.0..4.0), rng.gen_range(-2.0..2.0)))
            .collect();
        // a lattice: many equal distances
        for i in 0..10 {
            for j in 0..10 {
                pts.push(Point2::new(5.0 + i as f64 * 0.1, j as f64 * 0.1));
            }
        }
        pts.push(Point2::new(f64::NAN, 0.0));
        for cell in [0.05, 0.125, 1.0] {
            let grid = GridIndex::new(pts.clone(), None, cell);
            for q in 0..400 {
                let query = if q % 2 == 0 {
                    Point2::new(rng.gen_range(-5.0..7.0), rng.gen_range(-3.0..3.0))
                } else {
                    pts[q % 400]
                };
                for (k, r) in [(1, 0.3), (6, 0.5), (6, 0.05), (20, f64::INFINITY)] {
                    let mut want: Vec<(f64, usize)> = pts
                        .iter()
                        .enumerate()
                        .map(|(i, p)| ((p - query).norm_squared(), i))
                        .filter(|(d2, _)| d2.sqrt() <= r)
                        .collect();
                    want.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                    want.truncate(k);
                    let got: Vec<usize> = grid
                        .nearest_k_within(&query, k, r)
                        .iter()
                        .map(|n| n.index)
                        .collect();
                    let want: Vec<usize> = want.iter().map(|w| w.1).collect();
                    assert_eq!(got, want, "cell {cell} {query:?} k {k} r {r}");
                }
            }
        }
        let grid = GridIndex::new(pts.clone(), None, 0.1);
        assert!(grid.nearest_k_within(&Point2::origin(), 0, 1.0).is_empty());
        assert!(grid.nearest_k_within(&Point2::origin(), 3, -1.0).is_empty());
        assert!(grid
            .nearest_k_within(&Point2::origin(), 3, f64::NAN)
            .is_empty());
        assert!(grid
            .nearest_k_within(&Point2::new(f64::NAN, 0.0), 3, 1.0)
            .is_empty());
        let empty = GridIndex::new(Vec::new(), None, 0.1);
        assert!(empty.nearest_k_within(&Point2::origin(), 3, 1.0).is_empty());
    }

    #[test]
    fn wide_spread_grows_cells_within_budget() {
        let pts = vec![Point2::new(-5e6, -5e6), Point2::new(5e6, 5e6)];
        let grid = GridIndex::new(pts.clone(), None, 0.05);
        assert!(grid.cell_m() > 0.05);
        assert!(grid.width * grid.height <= MAX_CELLS);
        let n = grid
            .nearest_within(&Point2::new(4e6, 4e6), f64::INFINITY)
            .unwrap();
        assert_eq!(n.index, 1);
    }
}
