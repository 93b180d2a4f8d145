//! `slamkit plan`: a path on an occupancy grid map.

use crate::output::not_yet;
use std::path::PathBuf;

/// Grid planners.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Planner {
    /// Breadth-first search, 8-neighbourhood.
    Bfs,
    /// A* with the octile heuristic.
    Astar,
}

/// Arguments of `slamkit plan`.
#[derive(Debug, clap::Args)]
pub struct PlanArgs {
    /// Map in ROS map_server format (YAML next to its PGM).
    #[arg(long)]
    pub map: PathBuf,
    /// Start position in map coordinates, `X,Y` (m).
    #[arg(long, allow_hyphen_values = true)]
    pub start: String,
    /// Goal position in map coordinates, `X,Y` (m).
    #[arg(long, allow_hyphen_values = true)]
    pub goal: String,
    /// Planner.
    #[arg(long, value_enum, default_value = "astar")]
    pub planner: Planner,
    /// Output folder.
    #[arg(long, default_value = "out/plan")]
    pub out: PathBuf,
}

/// Runs `slamkit plan`.
pub fn run(_args: &PlanArgs) -> anyhow::Result<()> {
    not_yet("plan", "planning, issue #6")
}
