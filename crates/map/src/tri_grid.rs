//! Dense tri-state grids (free / occupied / unknown) for planners, and obstacle inflation.
//!
//! Planners read a cell millions of times per query, so they take a flat row-major array rather
//! than the tiled log-odds [`OccupancyGrid`]. Inflation grows every obstacle by the robot's
//! footprint, a square of `(2r + 1) × (2r + 1)` cells (5 × 5 by default, r = 2), so a planner can
//! treat the robot as a point (configuration space, T. Lozano-Pérez, "Spatial planning: a
//! configuration space approach", IEEE Trans. Computers C-32(2), 1983).

use crate::occupancy_grid::{CellIndex, Occupancy, OccupancyGrid};
use nalgebra::Point2;

/// A dense tri-state grid; cell `(x, y)` covers world
/// `[origin + x·res, origin + (x+1)·res) × [origin + y·res, ...)`.
#[derive(Debug, Clone, PartialEq)]
pub struct TriGrid {
    width: usize,
    height: usize,
    resolution_m: f64,
    origin_m: Point2<f64>,
    cells: Vec<Occupancy>,
}

impl TriGrid {
    /// A grid of `width × height` cells all set to `fill`. `None` when a size is zero, the
    /// resolution is not positive and finite, or the origin is not finite.
    pub fn new(
        width: usize,
        height: usize,
        resolution_m: f64,
        origin_m: Point2<f64>,
        fill: Occupancy,
    ) -> Option<Self> {
        let valid = width > 0
            && height > 0
            && resolution_m.is_finite()
            && resolution_m > 0.0
            && origin_m.x.is_finite()
            && origin_m.y.is_finite();
        let len = width.checked_mul(height)?;
        valid.then(|| Self {
            width,
            height,
            resolution_m,
            origin_m,
            cells: vec![fill; len],
        })
    }

    /// The known part of a log-odds grid (a single unknown cell when nothing is known).
    pub fn from_occupancy_grid(grid: &OccupancyGrid) -> Self {
        let zero = CellIndex { x: 0, y: 0 };
        let bounds = grid.known_bounds().unwrap_or(crate::CellBounds {
            min: zero,
            max: zero,
        });
        let (width, height) = (bounds.width(), bounds.height());
        let res = grid.resolution_m();
        let origin = grid.origin_m();
        let origin_m = Point2::new(
            origin.x + f64::from(bounds.min.x) * res,
            origin.y + f64::from(bounds.min.y) * res,
        );
        let mut cells = Vec::with_capacity(width * height);
        for y in bounds.min.y..=bounds.max.y {
            for x in bounds.min.x..=bounds.max.x {
                cells.push(
                    grid.occupancy(CellIndex { x, y })
                        .unwrap_or(Occupancy::Unknown),
                );
            }
        }
        Self {
            width,
            height,
            resolution_m: res,
            origin_m,
            cells,
        }
    }

    /// Columns.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Side of a cell \[m\].
    pub fn resolution_m(&self) -> f64 {
        self.resolution_m
    }

    /// World position of cell (0, 0)'s lower-left corner \[m\].
    pub fn origin_m(&self) -> Point2<f64> {
        self.origin_m
    }

    /// Row-major cells, row 0 at the bottom (smallest y).
    pub fn cells(&self) -> &[Occupancy] {
        &self.cells
    }

    /// The cell `(x, y)`; `None` outside the grid.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Option<Occupancy> {
        (x < self.width && y < self.height).then(|| self.cells[y * self.width + x])
    }

    /// Sets cell `(x, y)`; ignored outside the grid.
    pub fn set(&mut self, x: usize, y: usize, value: Occupancy) {
        if x < self.width && y < self.height {
            self.cells[y * self.width + x] = value;
        }
    }

    /// The cell holding world point `point_m`; `None` outside the grid or for NaN.
    pub fn cell_at(&self, point_m: &Point2<f64>) -> Option<(usize, usize)> {
        let x = ((point_m.x - self.origin_m.x) / self.resolution_m).floor();
        let y = ((point_m.y - self.origin_m.y) / self.resolution_m).floor();
        // NaN fails both comparisons.
        let inside = x >= 0.0 && y >= 0.0 && x < self.width as f64 && y < self.height as f64;
        inside.then_some((x as usize, y as usize))
    }

    /// World centre of cell `(x, y)` \[m\].
    pub fn cell_center_m(&self, x: usize, y: usize) -> Point2<f64> {
        Point2::new(
            self.origin_m.x + (x as f64 + 0.5) * self.resolution_m,
            self.origin_m.y + (y as f64 + 0.5) * self.resolution_m,
        )
    }

    /// A copy in which every cell within `radius_cells` (Chebyshev distance) of an occupied
    /// cell is occupied: a `(2r + 1)²` square footprint. Two passes of a running count (rows,
    /// then columns) make it O(cells) whatever the radius.
    pub fn inflated(&self, radius_cells: usize) -> TriGrid {
        let (w, h) = (self.width, self.height);
        let occupied: Vec<bool> = self
            .cells
            .iter()
            .map(|c| *c == Occupancy::Occupied)
            .collect();
        let rows = dilate_lines(&occupied, w, h, radius_cells, true);
        let both = dilate_lines(&rows, w, h, radius_cells, false);
        let mut out = self.clone();
        for (cell, &hit) in out.cells.iter_mut().zip(&both) {
            if hit {
                *cell = Occupancy::Occupied;
            }
        }
        out
    }
}

/// 1D dilation of every row (`along_rows`) or column by `r` cells, with a sliding count.
fn dilate_lines(src: &[bool], w: usize, h: usize, r: usize, along_rows: bool) -> Vec<bool> {
    let (lines, len) = if along_rows { (h, w) } else { (w, h) };
    let at = |line: usize, i: usize| {
        if along_rows {
            line * w + i
        } else {
            i * w + line
        }
    };
    let mut out = vec![false; src.len()];
    for line in 0..lines {
        let mut count = 0usize;
        // Window [i - r, i + r]; prime it with [0, r).
        for i in 0..r.min(len) {
            count += usize::from(src[at(line, i)]);
        }
        for i in 0..len {
            if i + r < len {
                count += usize::from(src[at(line, i + r)]);
            }
            if i > r {
                count -= usize::from(src[at(line, i - r - 1)]);
            }
            out[at(line, i)] = count > 0;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inflation_grows_a_square_footprint() {
        let mut g = TriGrid::new(9, 7, 0.1, Point2::origin(), Occupancy::Free).unwrap();
        g.set(4, 3, Occupancy::Occupied);
        g.set(0, 0, Occupancy::Occupied);
        let inflated = g.inflated(2);
        let occupied = |x, y| inflated.get(x, y) == Some(Occupancy::Occupied);
        for y in 0..7usize {
            for x in 0..9usize {
                let near_centre = x.abs_diff(4) <= 2 && y.abs_diff(3) <= 2;
                let near_corner = x <= 2 && y <= 2;
                assert_eq!(occupied(x, y), near_centre || near_corner, "cell ({x},{y})");
            }
        }
        assert_eq!(g.inflated(0), g);
    }

    #[test]
    fn cells_and_points() {
        let g = TriGrid::new(10, 5, 0.5, Point2::new(-1.0, 2.0), Occupancy::Unknown).unwrap();
        assert_eq!(g.cell_at(&Point2::new(-1.0, 2.0)), Some((0, 0)));
        assert_eq!(g.cell_at(&Point2::new(3.9, 4.4)), Some((9, 4)));
        assert_eq!(g.cell_at(&Point2::new(4.0, 2.0)), None);
        assert_eq!(g.cell_at(&Point2::new(f64::NAN, 2.0)), None);
        assert_eq!(g.cell_center_m(1, 1), Point2::new(-0.25, 2.75));
        assert!(TriGrid::new(0, 5, 0.5, Point2::origin(), Occupancy::Free).is_none());
    }
}
