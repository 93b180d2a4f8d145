//! Shortest paths on 8-connected grids: breadth-first search, Dijkstra and A*.
//!
//! The graph: a cell joins its 8 neighbours when both are passable; a diagonal move also needs
//! both cells it squeezes between to be passable, so paths never cut an obstacle's corner. The
//! three searches share this graph and differ in cost model and order:
//!
//! * BFS (E. F. Moore, "The shortest path through a maze", 1959) counts moves: every move costs
//!   1, diagonal or not ([`CostModel::Unit`]).
//! * Dijkstra (E. W. Dijkstra, "A note on two problems in connexion with graphs", Numerische
//!   Mathematik 1, 1959) and A* (P. E. Hart, N. J. Nilsson, B. Raphael, "A formal basis for the
//!   heuristic determination of minimum cost paths", IEEE Trans. SSC 4(2), 1968) take either
//!   model. Under [`CostModel::Octile`] a straight move costs 1 and a diagonal √2 (path length in
//!   cells) and A*'s heuristic is the octile distance `max + (√2 − 1)·min` of the cell offsets;
//!   under [`CostModel::Unit`] it is the Chebyshev distance `max`. Both heuristics are
//!   consistent, so A* returns an optimal path: A* under `Unit` has exactly BFS's cost, and A*
//!   under `Octile` exactly Dijkstra's.
//!
//! Ties in A*'s queue go to the larger cost-so-far, which on open ground expands little more
//! than the cells of the path itself.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};

/// How moves are charged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CostModel {
    /// Every move costs 1: the number of moves (BFS's model).
    Unit,
    /// Straight moves cost 1, diagonal moves √2: the path length in cells.
    Octile,
}

impl CostModel {
    fn step(self, diagonal: bool) -> f64 {
        match (self, diagonal) {
            (CostModel::Octile, true) => std::f64::consts::SQRT_2,
            _ => 1.0,
        }
    }

    /// Consistent lower bound of the cost between cells `dx`, `dy` apart.
    pub(crate) fn heuristic(self, dx: usize, dy: usize) -> f64 {
        let (hi, lo) = (dx.max(dy) as f64, dx.min(dy) as f64);
        match self {
            CostModel::Unit => hi,
            CostModel::Octile => hi + (std::f64::consts::SQRT_2 - 1.0) * lo,
        }
    }
}

/// A grid path: cells from start to goal, both included.
#[derive(Debug, Clone, PartialEq)]
pub struct SearchResult {
    /// Cells `(x, y)`, start first.
    pub cells: Vec<(usize, usize)>,
    /// Path cost under the search's cost model.
    pub cost: f64,
    /// Cells taken off the queue.
    pub expanded: usize,
}

/// The 8 moves: (dx, dy, diagonal).
pub(crate) const MOVES: [(isize, isize, bool); 8] = [
    (1, 0, false),
    (-1, 0, false),
    (0, 1, false),
    (0, -1, false),
    (1, 1, true),
    (1, -1, true),
    (-1, 1, true),
    (-1, -1, true),
];

/// A passability mask over a `width × height` grid, row-major.
#[derive(Debug, Clone, Copy)]
pub struct Passable<'a> {
    /// `mask[y * width + x]` is true when the robot may occupy cell `(x, y)`.
    pub mask: &'a [bool],
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
}

impl Passable<'_> {
    #[inline]
    pub(crate) fn ok(&self, x: isize, y: isize) -> bool {
        x >= 0
            && y >= 0
            && (x as usize) < self.width
            && (y as usize) < self.height
            && self.mask[y as usize * self.width + x as usize]
    }

    /// Neighbour of `index` by `m`, honouring the no-corner-cutting rule.
    #[inline]
    fn neighbour(&self, index: usize, m: (isize, isize, bool)) -> Option<usize> {
        let (x, y) = (index % self.width, index / self.width);
        self.neighbour_xy(x, y, m).map(|(n, _, _)| n)
    }

    /// Neighbour of cell `(x, y)` by `m` as `(index, x, y)`, honouring the no-corner-cutting
    /// rule.
    #[inline]
    fn neighbour_xy(
        &self,
        x: usize,
        y: usize,
        m: (isize, isize, bool),
    ) -> Option<(usize, usize, usize)> {
        let (x, y) = (x as isize, y as isize);
        let (nx, ny) = (x + m.0, y + m.1);
        let ok = self.ok(nx, ny) && (!m.2 || (self.ok(nx, y) && self.ok(x, ny)));
        ok.then(|| {
            let (nx, ny) = (nx as usize, ny as usize);
            (ny * self.width + nx, nx, ny)
        })
    }

    /// Cell indices of a search's `start` and `goal`; every search begins here, and answers
    /// `Err(0)` (nothing expanded) when the mask does not match the size or a cell is off the
    /// grid.
    pub(crate) fn endpoints(
        &self,
        start: (usize, usize),
        goal: (usize, usize),
    ) -> Result<(usize, usize), usize> {
        let on_grid = |c: (usize, usize)| c.0 < self.width && c.1 < self.height;
        if !(self.mask.len() == self.width * self.height && on_grid(start) && on_grid(goal)) {
            return Err(0);
        }
        Ok((start.1 * self.width + start.0, goal.1 * self.width + goal.0))
    }
}

/// Sentinel parent of cells not reached.
const NONE: u32 = u32::MAX;

fn trace(parent: &[u32], goal: usize, width: usize) -> Vec<(usize, usize)> {
    let mut cells = vec![(goal % width, goal / width)];
    let mut at = goal;
    while parent[at] != at as u32 {
        at = parent[at] as usize;
        cells.push((at % width, at / width));
    }
    cells.reverse();
    cells
}

/// Breadth-first search from `start` to `goal` (fewest moves). The start cell need not be
/// passable; every other cell of the path is.
///
/// # Errors
/// The number of cells expanded when the goal is unreachable (0 when a cell is off the grid).
pub fn bfs(
    grid: Passable<'_>,
    start: (usize, usize),
    goal: (usize, usize),
) -> Result<SearchResult, usize> {
    let (s, g) = grid.endpoints(start, goal)?;
    let mut parent = vec![NONE; grid.mask.len()];
    parent[s] = s as u32;
    let mut queue = VecDeque::from([s]);
    let mut expanded = 0;
    while let Some(at) = queue.pop_front() {
        expanded += 1;
        if at == g {
            let cells = trace(&parent, g, grid.width);
            let cost = (cells.len() - 1) as f64;
            return Ok(SearchResult {
                cells,
                cost,
                expanded,
            });
        }
        for m in MOVES {
            if let Some(n) = grid.neighbour(at, m) {
                if parent[n] == NONE {
                    parent[n] = at as u32;
                    queue.push_back(n);
                }
            }
        }
    }
    Err(expanded)
}

/// Dijkstra (`use_heuristic = false`) or A* from `start` to `goal` under `model`. The start
/// cell need not be passable.
///
/// # Errors
/// The number of cells expanded when the goal is unreachable (0 when a cell is off the grid).
pub fn best_first(
    grid: Passable<'_>,
    start: (usize, usize),
    goal: (usize, usize),
    model: CostModel,
    use_heuristic: bool,
) -> Result<SearchResult, usize> {
    let (s, g) = grid.endpoints(start, goal)?;
    let w = grid.width;
    let h = |x: usize, y: usize| {
        if use_heuristic {
            model.heuristic(x.abs_diff(goal.0), y.abs_diff(goal.1))
        } else {
            0.0
        }
    };
    let mut cost = vec![f64::INFINITY; grid.mask.len()];
    let mut parent = vec![NONE; grid.mask.len()];
    let mut closed = vec![false; grid.mask.len()];
    cost[s] = 0.0;
    parent[s] = s as u32;
    let mut queue = BinaryHeap::from([Reverse(queue_key(h(start.0, start.1), 0.0, s))]);
    let mut expanded = 0;
    while let Some(Reverse(key)) = queue.pop() {
        let at = (key & u128::from(u32::MAX)) as usize;
        if closed[at] {
            continue;
        }
        closed[at] = true;
        expanded += 1;
        if at == g {
            let cells = trace(&parent, g, w);
            return Ok(SearchResult {
                cells,
                cost: cost[g],
                expanded,
            });
        }
        let (x, y) = (at % w, at / w);
        for m in MOVES {
            let Some((n, nx, ny)) = grid.neighbour_xy(x, y, m) else {
                continue;
            };
            let c = cost[at] + model.step(m.2);
            if c < cost[n] && !closed[n] {
                cost[n] = c;
                parent[n] = at as u32;
                queue.push(Reverse(queue_key(c + h(nx, ny), c, n)));
            }
        }
    }
    Err(expanded)
}

/// One integer ordering `f` first, then the larger `g`, then the cell: the bits of
/// non-negative floats order as the floats do, so a single `u128` comparison does it all.
#[inline]
pub(crate) fn queue_key(f: f64, g: f64, index: usize) -> u128 {
    let g_rank = u32::MAX - (g as f32).to_bits();
    (u128::from(f.to_bits()) << 64) | (u128::from(g_rank) << 32) | index as u128
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_map(seed: u64, w: usize, h: usize, density: f64) -> Vec<bool> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..w * h).map(|_| !rng.gen_bool(density)).collect()
    }

    #[test]
    fn bfs_and_astar_agree_on_cost_on_random_maps() {
        let (w, h) = (60, 45);
        let mut compared = 0;
        for seed in 0..40 {
            let mask = random_map(seed, w, h, 0.3);
            let grid = Passable {
                mask: &mask,
                width: w,
                height: h,
            };
            let (start, goal) = ((0, 0), (w - 1, h - 1));
            let b = bfs(grid, start, goal);
            let a_unit = best_first(grid, start, goal, CostModel::Unit, true);
            let d_oct = best_first(grid, start, goal, CostModel::Octile, false);
            let a_oct = best_first(grid, start, goal, CostModel::Octile, true);
            assert_eq!(b.is_ok(), a_oct.is_ok(), "seed {seed}");
            let (Ok(b), Ok(a_unit), Ok(d_oct), Ok(a_oct)) = (b, a_unit, d_oct, a_oct) else {
                continue;
            };
            compared += 1;
            assert_eq!(b.cost, a_unit.cost, "seed {seed}: BFS vs A* (unit)");
            assert!(
                (d_oct.cost - a_oct.cost).abs() < 1e-9,
                "seed {seed}: Dijkstra vs A* (octile)"
            );
            assert!(a_oct.expanded <= d_oct.expanded);
            for path in [&b, &a_unit, &a_oct] {
                assert_eq!(path.cells.first(), Some(&start));
                assert_eq!(path.cells.last(), Some(&goal));
                for pair in path.cells.windows(2) {
                    let (p, q) = (pair[0], pair[1]);
                    assert!(p.0.abs_diff(q.0) <= 1 && p.1.abs_diff(q.1) <= 1);
                    assert!(mask[q.1 * w + q.0]);
                }
            }
        }
        assert!(compared >= 10, "only {compared} solvable maps");
    }

    #[test]
    fn known_costs_on_an_open_grid() {
        let mask = vec![true; 100];
        let grid = Passable {
            mask: &mask,
            width: 10,
            height: 10,
        };
        let b = bfs(grid, (0, 0), (9, 4)).unwrap();
        assert_eq!(b.cost, 9.0);
        let a = best_first(grid, (0, 0), (9, 4), CostModel::Octile, true).unwrap();
        assert!((a.cost - (5.0 + 4.0 * std::f64::consts::SQRT_2)).abs() < 1e-12);
        // On open ground A* expands only along the path.
        assert_eq!(a.expanded, a.cells.len());
    }

    #[test]
    fn walls_and_corners_block() {
        // A wall with a diagonal gap only: corner cutting is not allowed.
        let (w, h) = (5, 5);
        let mut mask = vec![true; w * h];
        for y in 0..h {
            mask[y * w + 2] = false;
        }
        let grid = Passable {
            mask: &mask,
            width: w,
            height: h,
        };
        assert!(bfs(grid, (0, 0), (4, 4)).is_err());
        assert!(best_first(grid, (0, 0), (4, 4), CostModel::Octile, true).is_err());
        // A diagonal-only gap: (1, 1) and (2, 2) touch at a corner, both walls around it closed.
        mask[2 * w + 2] = true;
        mask[2 * w + 1] = false;
        mask[w + 2] = false;
        let blocked = Passable {
            mask: &mask,
            width: w,
            height: h,
        };
        assert!(bfs(blocked, (1, 1), (2, 2)).is_err());
        mask[2 * w + 1] = true;
        let grid = Passable {
            mask: &mask,
            width: w,
            height: h,
        };
        assert!(bfs(grid, (0, 0), (4, 4)).is_ok());
        assert!(bfs(grid, (0, 0), (9, 9)).is_err(), "off-grid goal");
    }

    #[test]
    fn every_search_rejects_off_grid_cells_and_a_wrong_mask_expanding_nothing() {
        let mask = vec![true; 20];
        let grid = |height| Passable {
            mask: &mask,
            width: 5,
            height,
        };
        let cases = [
            (grid(4), (5, 0), (0, 0)),
            (grid(4), (0, 0), (0, 4)),
            (grid(3), (0, 0), (1, 1)),
        ];
        for (g, start, goal) in cases {
            assert_eq!(bfs(g, start, goal).err(), Some(0));
            let a = best_first(g, start, goal, CostModel::Octile, true);
            assert_eq!(a.err(), Some(0));
            let j = crate::jps::jump_point_search(g, start, goal);
            assert_eq!(j.err(), Some(0));
        }
        assert!(crate::jps::jump_point_search(grid(4), (0, 0), (4, 3)).is_ok());
    }
}
