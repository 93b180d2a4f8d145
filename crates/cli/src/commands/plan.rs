//! `slamkit plan`: a path on an occupancy grid map.
//!
//! The map is read from a ROS `map_server` YAML (cropped to its known cells) or a `.skmap`
//! (the grid rebuilt from its keyframe scans), obstacles are
//! inflated by the robot's footprint, and the chosen planner runs through known-free cells
//! first and through unknown cells only when that fails. Writes `path.csv` (the waypoints),
//! `map.png` (the path drawn on the map) and `report.json`.

use crate::output::finish;
use anyhow::Context;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use nalgebra::Point2;
use serde_json::json;
use slamkit_io::image_writer::save_rgb_png;
use slamkit_io::output_folder::OutputFolder;
use slamkit_nav::render::draw_path;
use slamkit_nav::{plan_on_grid, GridPlanner};
use slamkit_slam::map_file::export::load_planning_grid;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `slamkit plan`.
#[derive(Debug, clap::Args)]
pub struct PlanArgs {
    /// Map: ROS map_server format (YAML next to its PGM) or a slamkit `.skmap`.
    #[arg(long)]
    pub map: PathBuf,
    /// Start position in map coordinates, `X,Y` (m).
    #[arg(long, allow_hyphen_values = true)]
    pub start: String,
    /// Goal position in map coordinates, `X,Y` (m).
    #[arg(long, allow_hyphen_values = true)]
    pub goal: String,
    /// Planner: `astar` (A* with the octile heuristic) or `bfs` (breadth-first search,
    /// 8-neighbourhood).
    #[arg(long, default_value = "astar", value_parser = planner_parser())]
    pub planner: GridPlanner,
    /// Obstacles grow by this many cells (Chebyshev), the robot's radius: 2 gives a 5 × 5
    /// footprint.
    #[arg(long, default_value_t = 2)]
    pub inflate_cells: usize,
    /// Output folder.
    #[arg(long, default_value = "out/plan")]
    pub out: PathBuf,
}

fn planner_parser() -> impl TypedValueParser<Value = GridPlanner> {
    PossibleValuesParser::new(["bfs", "astar"]).map(|s| match s.as_str() {
        "bfs" => GridPlanner::Bfs,
        _ => GridPlanner::Astar,
    })
}

/// Parses `X,Y` in metres.
pub fn parse_xy(text: &str, what: &str) -> anyhow::Result<Point2<f64>> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let [x, y] = parts.as_slice() else {
        anyhow::bail!("{what} `{text}`: expected X,Y in metres");
    };
    let parse = |s: &str| -> anyhow::Result<f64> {
        let v: f64 = s
            .parse()
            .with_context(|| format!("{what} `{text}`: `{s}` is not a number"))?;
        anyhow::ensure!(v.is_finite(), "{what} `{text}`: `{s}` is not finite");
        Ok(v)
    };
    Ok(Point2::new(parse(x)?, parse(y)?))
}

/// Runs `slamkit plan`.
pub fn run(args: &PlanArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let start = parse_xy(&args.start, "start")?;
    let goal = parse_xy(&args.goal, "goal")?;
    let grid = load_planning_grid(&args.map)
        .with_context(|| format!("reading map {}", args.map.display()))?;
    let folder = OutputFolder::create(&args.out, &["path.csv", "map.png", "report.json"])?;
    let out = folder.path();
    let inflated = grid.inflated(args.inflate_cells);
    let planner = args.planner;
    let plan_started = Instant::now();
    let path = plan_on_grid(&inflated, &start, &goal, planner).with_context(|| {
        format!(
            "planning from {},{} to {},{} on {}",
            start.x,
            start.y,
            goal.x,
            goal.y,
            args.map.display()
        )
    })?;
    let plan_ms = plan_started.elapsed().as_secs_f64() * 1e3;
    let csv = out.join("path.csv");
    std::fs::write(&csv, path.waypoints_csv())
        .with_context(|| format!("writing {}", csv.display()))?;
    save_rgb_png(
        &out.join("map.png"),
        &draw_path(&grid, &inflated, &path.cells),
    )?;
    let report = json!({
        "input": args.map,
        "config": {
            "planner": planner,
            "start_m": [start.x, start.y],
            "goal_m": [goal.x, goal.y],
            "inflate_cells": args.inflate_cells,
        },
        "grid": {
            "width": grid.width(),
            "height": grid.height(),
            "resolution_m": grid.resolution_m(),
            "origin_m": [grid.origin_m().x, grid.origin_m().y],
        },
        "metrics": {
            "length_m": path.length_m,
            "cost": path.cost,
            "waypoints": path.waypoints_m.len(),
            "through_unknown": path.through_unknown,
            "expanded": path.expanded,
        },
        "timings": { "plan_ms": plan_ms },
        "wall_s": started.elapsed().as_secs_f64(),
    });
    finish(folder, &report)?;
    if path.cells.len() == 1 {
        println!(
            "start and goal lie in one cell of the map ({} m a side): the path is that cell",
            grid.resolution_m()
        );
    }
    println!(
        "path: {:.2} m, {} waypoints{}, {:.1} ms; written to {}",
        path.length_m,
        path.waypoints_m.len(),
        if path.through_unknown {
            " (through unknown cells)"
        } else {
            ""
        },
        plan_ms,
        args.out.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xy_parses_and_rejects_garbage() {
        assert_eq!(parse_xy("1.5,-2", "goal").unwrap(), Point2::new(1.5, -2.0));
        assert_eq!(parse_xy(" 1 , 2 ", "goal").unwrap(), Point2::new(1.0, 2.0));
        for bad in ["1", "1,2,3", "a,2", "nan,1", ""] {
            let err = parse_xy(bad, "goal").unwrap_err().to_string();
            assert!(err.contains("goal"), "{bad}: {err}");
        }
    }
}
