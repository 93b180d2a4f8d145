//! Jump point search: A* that skips the cells of straight runs.
//!
//! D. Harabor and A. Grastien, "Online graph pruning for pathfinding on grid maps", AAAI 2011.
//! On an 8-connected uniform-cost grid most of A*'s expansions are cells in the middle of open
//! runs, each reachable by many equally short paths. JPS expands only "jump points": cells where
//! a straight or diagonal run must turn because an obstacle ends (a forced neighbour), plus the
//! goal. Between jump points the path is a straight or diagonal line, so it is returned expanded
//! back into cells. The costs, graph and heuristic are exactly A*'s under
//! [`CostModel::Octile`](crate::grid_search::CostModel) with no corner cutting (a diagonal
//! move needs both side cells free), the variant of the PathFinding.js library
//! (`JPFMoveDiagonallyIfNoObstacles`): while running straight, a cell is a jump point when a side
//! cell is free and the cell behind it is blocked; a diagonal run stops where one of its two
//! straight runs finds a jump point, and cannot pass a blocked side cell.

use crate::grid_search::{queue_key, CostModel, Passable, SearchResult, MOVES};
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

/// Octile distance between two cells.
fn octile(a: (isize, isize), b: (isize, isize)) -> f64 {
    CostModel::Octile.heuristic((a.0 - b.0).unsigned_abs(), (a.1 - b.1).unsigned_abs())
}

struct Jumper<'a> {
    grid: Passable<'a>,
    goal: (isize, isize),
}

impl Jumper<'_> {
    fn free(&self, x: isize, y: isize) -> bool {
        self.grid.ok(x, y)
    }

    /// Runs straight from `(x, y)` (already entered) along `(dx, dy)`; the first jump point.
    ///
    /// The hot loop of the search: cells are read along the run by index, with the two side
    /// lines' existence decided once per run.
    fn straight(&self, x: isize, y: isize, dx: isize, dy: isize) -> Option<(isize, isize)> {
        let (w, h) = (self.grid.width as isize, self.grid.height as isize);
        let mask = self.grid.mask;
        // Position `t` along the run, `perp` across it.
        let (mut t, perp, d, len, perp_len, stride_t, stride_p) = if dx != 0 {
            (x, y, dx, w, h, 1, w)
        } else {
            (y, x, dy, h, w, w, 1)
        };
        if perp < 0 || perp >= perp_len {
            return None;
        }
        let point = |t: isize| if dx != 0 { (t, perp) } else { (perp, t) };
        let goal_t = {
            let (gt, gp) = if dx != 0 {
                self.goal
            } else {
                (self.goal.1, self.goal.0)
            };
            (gp == perp).then_some(gt)
        };
        let (low_side, high_side) = (perp > 0, perp + 1 < perp_len);
        let base = perp * stride_p;
        let at = |t: isize, side: isize| {
            t >= 0 && t < len && mask[(base + t * stride_t + side * stride_p) as usize]
        };
        loop {
            if !at(t, 0) {
                return None;
            }
            let forced = (low_side && at(t, -1) && !at(t - d, -1))
                || (high_side && at(t, 1) && !at(t - d, 1));
            if forced || goal_t == Some(t) {
                return Some(point(t));
            }
            t += d;
        }
    }

    /// Runs diagonally from `(x, y)` (already entered) along `(dx, dy)`.
    fn diagonal(&self, mut x: isize, mut y: isize, dx: isize, dy: isize) -> Option<(isize, isize)> {
        loop {
            if !self.free(x, y) {
                return None;
            }
            if (x, y) == self.goal
                || self.straight(x + dx, y, dx, 0).is_some()
                || self.straight(x, y + dy, 0, dy).is_some()
            {
                return Some((x, y));
            }
            if !(self.free(x + dx, y) && self.free(x, y + dy)) {
                return None;
            }
            x += dx;
            y += dy;
        }
    }

    /// The jump point reached by leaving `(x, y)` towards its neighbour `(nx, ny)`.
    fn jump(&self, (x, y): (isize, isize), (nx, ny): (isize, isize)) -> Option<(isize, isize)> {
        let (dx, dy) = (nx - x, ny - y);
        if dx != 0 && dy != 0 {
            self.diagonal(nx, ny, dx, dy)
        } else {
            self.straight(nx, ny, dx, dy)
        }
    }

    /// The neighbours worth trying from `at`, reached from `parent` (pruned), or all of them.
    fn neighbours(
        &self,
        at: (isize, isize),
        parent: Option<(isize, isize)>,
    ) -> Vec<(isize, isize)> {
        let (x, y) = at;
        let Some(p) = parent else {
            let mut all = Vec::with_capacity(8);
            for (dx, dy, diagonal) in MOVES {
                let ok = self.free(x + dx, y + dy)
                    && (!diagonal || (self.free(x + dx, y) && self.free(x, y + dy)));
                if ok {
                    all.push((x + dx, y + dy));
                }
            }
            return all;
        };
        let (dx, dy) = ((x - p.0).signum(), (y - p.1).signum());
        let mut out = Vec::with_capacity(5);
        let mut add = |c: (isize, isize), ok: bool| {
            if ok {
                out.push(c);
            }
        };
        if dx != 0 && dy != 0 {
            let (side_y, side_x) = (self.free(x, y + dy), self.free(x + dx, y));
            add((x, y + dy), side_y);
            add((x + dx, y), side_x);
            add(
                (x + dx, y + dy),
                side_y && side_x && self.free(x + dx, y + dy),
            );
        } else if dx != 0 {
            let (next, up, down) = (
                self.free(x + dx, y),
                self.free(x, y + 1),
                self.free(x, y - 1),
            );
            add((x + dx, y), next);
            add((x + dx, y + 1), next && up && self.free(x + dx, y + 1));
            add((x + dx, y - 1), next && down && self.free(x + dx, y - 1));
            add((x, y + 1), up);
            add((x, y - 1), down);
        } else {
            let (next, right, left) = (
                self.free(x, y + dy),
                self.free(x + 1, y),
                self.free(x - 1, y),
            );
            add((x, y + dy), next);
            add((x + 1, y + dy), next && right && self.free(x + 1, y + dy));
            add((x - 1, y + dy), next && left && self.free(x - 1, y + dy));
            add((x + 1, y), right);
            add((x - 1, y), left);
        }
        out
    }
}

/// Shortest path in octile length from `start` to `goal` by jump point search; the cells of the
/// path, its cost in cells and the jump points expanded. The start cell need not be passable.
///
/// # Errors
/// The number of jump points expanded when the goal is unreachable (0 when a cell is off the
/// grid).
pub fn jump_point_search(
    grid: Passable<'_>,
    start: (usize, usize),
    goal: (usize, usize),
) -> Result<SearchResult, usize> {
    let (s, g) = grid.endpoints(start, goal)?;
    let w = grid.width;
    let cell = |c: (usize, usize)| (c.0 as isize, c.1 as isize);
    let index = |c: (isize, isize)| c.1 as usize * w + c.0 as usize;
    let jumper = Jumper {
        grid,
        goal: cell(goal),
    };
    // Only jump points get a record, a few thousand even on large maps, so a hash map keeps
    // the search's memory (and its set-up time) independent of the grid's size.
    let mut nodes: HashMap<usize, Node> = HashMap::new();
    nodes.insert(s, Node::new(0.0, s));
    let mut queue = BinaryHeap::from([Reverse(queue_key(octile(cell(start), cell(goal)), 0.0, s))]);
    let mut expanded = 0;
    while let Some(Reverse(key)) = queue.pop() {
        let at_index = (key & u128::from(u32::MAX)) as usize;
        let Some(node) = nodes.get_mut(&at_index) else {
            continue;
        };
        if node.closed {
            continue;
        }
        node.closed = true;
        let (g_at, from) = (node.cost, node.parent);
        expanded += 1;
        if at_index == g {
            return Ok(SearchResult {
                cells: expand(&nodes, g, w),
                cost: g_at,
                expanded,
            });
        }
        let at = ((at_index % w) as isize, (at_index / w) as isize);
        let came_from = (from != at_index).then(|| ((from % w) as isize, (from / w) as isize));
        for next in jumper.neighbours(at, came_from) {
            let Some(jp) = jumper.jump(at, next) else {
                continue;
            };
            let n = index(jp);
            let c = g_at + octile(at, jp);
            let better = nodes
                .get(&n)
                .map_or(true, |old| !old.closed && c < old.cost);
            if better {
                nodes.insert(n, Node::new(c, at_index));
                queue.push(Reverse(queue_key(c + octile(jp, cell(goal)), c, n)));
            }
        }
    }
    Err(expanded)
}

/// A jump point's search record.
#[derive(Debug, Clone, Copy)]
struct Node {
    /// Cost from the start \[cells\].
    cost: f64,
    /// Index of the jump point it was reached from (itself for the start).
    parent: usize,
    /// Expanded already.
    closed: bool,
}

impl Node {
    fn new(cost: f64, parent: usize) -> Self {
        Self {
            cost,
            parent,
            closed: false,
        }
    }
}

/// The cells from the start to `goal`, filling the straight or diagonal lines between jump
/// points.
fn expand(nodes: &HashMap<usize, Node>, goal: usize, w: usize) -> Vec<(usize, usize)> {
    let mut points = vec![goal];
    let mut at = goal;
    while let Some(node) = nodes.get(&at).filter(|n| n.parent != at) {
        at = node.parent;
        points.push(at);
    }
    points.reverse();
    let xy = |i: usize| ((i % w) as isize, (i / w) as isize);
    let mut cells = vec![(points[0] % w, points[0] / w)];
    for pair in points.windows(2) {
        let (a, b) = (xy(pair[0]), xy(pair[1]));
        let (dx, dy) = ((b.0 - a.0).signum(), (b.1 - a.1).signum());
        let mut c = a;
        while c != b {
            c = (c.0 + dx, c.1 + dy);
            cells.push((c.0 as usize, c.1 as usize));
        }
    }
    cells
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid_search::best_first;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn same_cost_as_dijkstra_on_random_maps() {
        let mut compared = 0;
        for seed in 0..200 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let (w, h) = (rng.gen_range(5..50), rng.gen_range(5..50));
            let density = rng.gen_range(0.0..0.4);
            let mask: Vec<bool> = (0..w * h).map(|_| !rng.gen_bool(density)).collect();
            let grid = Passable {
                mask: &mask,
                width: w,
                height: h,
            };
            let start = (rng.gen_range(0..w), rng.gen_range(0..h));
            let goal = (rng.gen_range(0..w), rng.gen_range(0..h));
            let d = best_first(grid, start, goal, CostModel::Octile, false);
            let j = jump_point_search(grid, start, goal);
            assert_eq!(d.is_ok(), j.is_ok(), "seed {seed}: {d:?} vs {j:?}");
            let (Ok(d), Ok(j)) = (d, j) else { continue };
            compared += 1;
            assert!(
                (d.cost - j.cost).abs() < 1e-9,
                "seed {seed}: {} vs {}",
                d.cost,
                j.cost
            );
            assert_eq!(j.cells.first(), Some(&start));
            assert_eq!(j.cells.last(), Some(&goal));
            let mut length = 0.0;
            for pair in j.cells.windows(2) {
                let (p, q) = (pair[0], pair[1]);
                let (dx, dy) = (p.0.abs_diff(q.0), p.1.abs_diff(q.1));
                assert!(
                    dx <= 1 && dy <= 1 && dx + dy > 0,
                    "seed {seed}: step {p:?} {q:?}"
                );
                assert!(
                    mask[q.1 * w + q.0],
                    "seed {seed}: through an obstacle at {q:?}"
                );
                if dx + dy == 2 {
                    assert!(
                        mask[p.1 * w + q.0] && mask[q.1 * w + p.0],
                        "seed {seed}: corner cut"
                    );
                    length += std::f64::consts::SQRT_2;
                } else {
                    length += 1.0;
                }
            }
            assert!(
                (length - j.cost).abs() < 1e-9,
                "seed {seed}: cells match the cost"
            );
        }
        assert!(compared >= 100, "only {compared} solvable maps");
    }

    #[test]
    fn open_ground_expands_few_points() {
        let mask = vec![true; 200 * 100];
        let grid = Passable {
            mask: &mask,
            width: 200,
            height: 100,
        };
        let j = jump_point_search(grid, (3, 4), (190, 90)).unwrap();
        assert!(j.expanded <= 3, "{}", j.expanded);
        assert!((j.cost - octile((3, 4), (190, 90))).abs() < 1e-9);
        assert_eq!(
            jump_point_search(grid, (5, 5), (5, 5)).unwrap().cells,
            vec![(5, 5)]
        );
        assert!(jump_point_search(grid, (5, 5), (500, 5)).is_err());
    }
}
