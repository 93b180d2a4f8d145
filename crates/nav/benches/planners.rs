//! A* on a 2000 × 2000 grid with random rectangular obstacles, corner to corner (issue #6: an
//! answer within 50 ms): the planner's A* (jump-point pruning), plain A* and BFS on the same
//! map for comparison.

// criterion's macros generate undocumented functions.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Point2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slamkit_map::{Occupancy, TriGrid};
use slamkit_nav::grid_search::{best_first, Passable};
use slamkit_nav::{plan_on_grid, CostModel, GridPlanner};

/// Random boxes on the benchmark map: about a fifth of it covered.
const BOXES: usize = 500;

/// 2000 × 2000 cells of 5 cm (100 m × 100 m) with [`BOXES`] random boxes of 0.5–4 m, seeded.
fn obstacle_map() -> TriGrid {
    let n = 2000;
    let Some(mut grid) = TriGrid::new(n, n, 0.05, Point2::origin(), Occupancy::Free) else {
        unreachable!("2000 × 2000 at 5 cm is a valid grid")
    };
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    for _ in 0..BOXES {
        let (x0, y0) = (rng.gen_range(0..n), rng.gen_range(0..n));
        let (w, h) = (rng.gen_range(10..80), rng.gen_range(10..80));
        for y in y0..(y0 + h).min(n) {
            for x in x0..(x0 + w).min(n) {
                grid.set(x, y, Occupancy::Occupied);
            }
        }
    }
    // Keep 2 m × 2 m free at the start and goal corners.
    for y in 0..40 {
        for x in 0..40 {
            grid.set(x, y, Occupancy::Free);
            grid.set(n - 1 - x, n - 1 - y, Occupancy::Free);
        }
    }
    grid
}

fn planners(c: &mut Criterion) {
    let grid = obstacle_map();
    let (start, goal) = (Point2::new(0.02, 0.02), Point2::new(99.98, 99.98));
    for planner in [GridPlanner::Astar, GridPlanner::Bfs] {
        let found = plan_on_grid(&grid, &start, &goal, planner);
        assert!(
            found.is_ok(),
            "the benchmark map must connect its corners: {found:?}"
        );
    }
    let mut group = c.benchmark_group("nav");
    group.sample_size(10);
    for (name, planner) in [
        ("astar_2000x2000", GridPlanner::Astar),
        ("bfs_2000x2000", GridPlanner::Bfs),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| plan_on_grid(&grid, &start, &goal, planner).map(|p| p.length_m))
        });
    }
    let mask: Vec<bool> = grid.cells().iter().map(|c| *c == Occupancy::Free).collect();
    let passable = Passable {
        mask: &mask,
        width: grid.width(),
        height: grid.height(),
    };
    let corners = ((0, 0), (grid.width() - 1, grid.height() - 1));
    group.bench_function("plain_astar_search_2000x2000", |b| {
        b.iter(|| {
            best_first(passable, corners.0, corners.1, CostModel::Octile, true).map(|r| r.cost)
        })
    });
    group.finish();
}

criterion_group!(benches, planners);
criterion_main!(benches);
