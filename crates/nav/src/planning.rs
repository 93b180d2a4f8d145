//! Planning on a 2D tri-state grid between two points in metres.
//!
//! The search first runs through known-free cells only; only when that fails does it run again
//! with unknown cells allowed, so the robot prefers ground it has seen but can still head into
//! unexplored space. Occupied cells (already inflated by the robot's radius) are never entered.

use crate::error::NavError;
use crate::grid_search::{best_first, bfs, CostModel, Passable, SearchResult};
use crate::jps::jump_point_search;
use nalgebra::Point2;
use slamkit_map::{Occupancy, TriGrid};

/// Which search to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GridPlanner {
    /// Breadth-first search: fewest 8-connected moves.
    Bfs,
    /// Dijkstra: shortest path in octile length.
    Dijkstra,
    /// A* with the octile heuristic and jump-point pruning ([`crate::jps`]): shortest path in
    /// octile length, Dijkstra's cost, far fewer expansions.
    Astar,
}

/// A planned path.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedPath {
    /// Grid cells `(x, y)`, start first.
    pub cells: Vec<(usize, usize)>,
    /// Cell centres in the map frame \[m\], start first.
    pub waypoints_m: Vec<Point2<f64>>,
    /// Cost under the planner's model: moves for BFS, octile length in cells otherwise.
    pub cost: f64,
    /// Euclidean length of the polyline through the waypoints \[m\].
    pub length_m: f64,
    /// True when no path existed through known-free cells and unknown cells were used.
    pub through_unknown: bool,
    /// Cells expanded by the search that found the path.
    pub expanded: usize,
}

impl PlannedPath {
    /// The waypoints as CSV, `x_m,y_m` under a header, start first (`path.csv` of `slamkit
    /// plan`).
    ///
    /// ```
    /// use nalgebra::Point2;
    /// use slamkit_nav::PlannedPath;
    ///
    /// let path = PlannedPath {
    ///     cells: vec![(0, 0), (1, 0)],
    ///     waypoints_m: vec![Point2::new(0.025, 0.025), Point2::new(0.075, 0.025)],
    ///     cost: 1.0,
    ///     length_m: 0.05,
    ///     through_unknown: false,
    ///     expanded: 2,
    /// };
    /// assert_eq!(path.waypoints_csv(), "x_m,y_m\n0.025,0.025\n0.075,0.025\n");
    /// ```
    pub fn waypoints_csv(&self) -> String {
        let mut text = String::from("x_m,y_m\n");
        for p in &self.waypoints_m {
            text += &format!("{},{}\n", p.x, p.y);
        }
        text
    }
}

/// Plans from `start_m` to `goal_m` on `grid` (already inflated).
///
/// # Errors
/// [`NavError::OutsideMap`] for a start or goal off the grid or NaN; [`NavError::Blocked`]
/// when either lies on an occupied cell; [`NavError::Unreachable`] when no path exists even
/// through unknown cells.
pub fn plan_on_grid(
    grid: &TriGrid,
    start_m: &Point2<f64>,
    goal_m: &Point2<f64>,
    planner: GridPlanner,
) -> Result<PlannedPath, NavError> {
    let start = endpoint(grid, start_m, "start")?;
    let goal = endpoint(grid, goal_m, "goal")?;
    let mut expanded = 0;
    let any_unknown = grid.cells().contains(&Occupancy::Unknown);
    for allow_unknown in [false, true] {
        if allow_unknown && !any_unknown {
            break; // the second search would repeat the first
        }
        let mask: Vec<bool> = grid
            .cells()
            .iter()
            .map(|c| *c == Occupancy::Free || (allow_unknown && *c == Occupancy::Unknown))
            .collect();
        let passable = Passable {
            mask: &mask,
            width: grid.width(),
            height: grid.height(),
        };
        match search(passable, start, goal, planner) {
            Ok(found) => return Ok(to_path(grid, found, allow_unknown)),
            Err(n) => expanded = n,
        }
    }
    Err(NavError::Unreachable { expanded })
}

/// Runs the chosen search; on failure returns the cells it expanded.
fn search(
    grid: Passable<'_>,
    start: (usize, usize),
    goal: (usize, usize),
    planner: GridPlanner,
) -> Result<SearchResult, usize> {
    match planner {
        GridPlanner::Bfs => bfs(grid, start, goal),
        GridPlanner::Dijkstra => best_first(grid, start, goal, CostModel::Octile, false),
        GridPlanner::Astar => jump_point_search(grid, start, goal),
    }
}

fn endpoint(
    grid: &TriGrid,
    point_m: &Point2<f64>,
    what: &'static str,
) -> Result<(usize, usize), NavError> {
    let (x_m, y_m, z_m) = (point_m.x, point_m.y, 0.0);
    let cell = grid.cell_at(point_m).ok_or(NavError::OutsideMap {
        what,
        x_m,
        y_m,
        z_m,
    })?;
    if grid.get(cell.0, cell.1) == Some(Occupancy::Occupied) {
        return Err(NavError::Blocked {
            what,
            x_m,
            y_m,
            z_m,
        });
    }
    Ok(cell)
}

fn to_path(grid: &TriGrid, found: SearchResult, through_unknown: bool) -> PlannedPath {
    let waypoints_m: Vec<Point2<f64>> = found
        .cells
        .iter()
        .map(|&(x, y)| grid.cell_center_m(x, y))
        .collect();
    // Folded from +0: an empty `sum()` of floats is -0, which prints as "-0.00 m".
    let length_m = waypoints_m
        .windows(2)
        .fold(0.0, |sum, w| sum + (w[1] - w[0]).norm());
    PlannedPath {
        cells: found.cells,
        waypoints_m,
        cost: found.cost,
        length_m,
        through_unknown,
        expanded: found.expanded,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 20 × 10 free grid at 0.1 m with a wall at x = 10 open at the top row only.
    fn walled() -> TriGrid {
        let mut g = TriGrid::new(20, 10, 0.1, Point2::origin(), Occupancy::Free).unwrap();
        for y in 0..9 {
            g.set(10, y, Occupancy::Occupied);
        }
        g
    }

    #[test]
    fn plans_around_a_wall_and_prefers_known_free_cells() {
        let mut g = walled();
        let (start, goal) = (Point2::new(0.05, 0.05), Point2::new(1.95, 0.05));
        let path = plan_on_grid(&g, &start, &goal, GridPlanner::Astar).unwrap();
        assert!(!path.through_unknown);
        assert!(path.cells.contains(&(10, 9)));
        let bfs = plan_on_grid(&g, &start, &goal, GridPlanner::Bfs).unwrap();
        assert_eq!(bfs.cost as usize, bfs.cells.len() - 1);
        // Close the gap with unknown cells: the plan goes through them only then.
        g.set(10, 9, Occupancy::Unknown);
        let path = plan_on_grid(&g, &start, &goal, GridPlanner::Dijkstra).unwrap();
        assert!(path.through_unknown);
        // A detour through free cells is taken rather than a shortcut through unknown ones.
        let mut g = TriGrid::new(20, 10, 0.1, Point2::origin(), Occupancy::Free).unwrap();
        for y in 0..9 {
            g.set(10, y, Occupancy::Unknown);
        }
        let path = plan_on_grid(&g, &start, &goal, GridPlanner::Astar).unwrap();
        assert!(!path.through_unknown && path.cells.contains(&(10, 9)));
    }

    #[test]
    fn unreachable_and_out_of_map_goals_are_clear_errors() {
        let mut g = walled();
        g.set(10, 9, Occupancy::Occupied);
        let start = Point2::new(0.05, 0.05);
        let err = plan_on_grid(&g, &start, &Point2::new(1.95, 0.05), GridPlanner::Astar);
        assert!(matches!(err, Err(NavError::Unreachable { .. })), "{err:?}");
        let err = plan_on_grid(&g, &start, &Point2::new(5.0, 0.05), GridPlanner::Bfs);
        assert!(matches!(
            err,
            Err(NavError::OutsideMap { what: "goal", .. })
        ));
        let err = plan_on_grid(&g, &Point2::new(f64::NAN, 0.0), &start, GridPlanner::Bfs);
        assert!(matches!(
            err,
            Err(NavError::OutsideMap { what: "start", .. })
        ));
        let err = plan_on_grid(&g, &start, &Point2::new(1.05, 0.05), GridPlanner::Astar);
        assert!(matches!(err, Err(NavError::Blocked { what: "goal", .. })));
        let message = plan_on_grid(&g, &start, &Point2::new(5.0, 0.05), GridPlanner::Bfs)
            .unwrap_err()
            .to_string();
        assert!(message.contains("outside the map"), "{message}");
    }

    #[test]
    fn a_path_to_itself_is_one_cell() {
        let g = walled();
        let p = Point2::new(0.55, 0.55);
        let path = plan_on_grid(&g, &p, &p, GridPlanner::Astar).unwrap();
        assert_eq!(path.cells.len(), 1);
        assert!(path.length_m == 0.0 && path.length_m.is_sign_positive());
    }
}
