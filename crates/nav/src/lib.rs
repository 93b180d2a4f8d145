//! slamkit-nav: from a map to wheel commands.
//!
//! * [`grid_search`]: breadth-first search, Dijkstra and A* on 8-connected 2D grids.
//! * [`jps`]: jump point search, A* that expands only where straight runs must turn.
//! * [`planning`]: start and goal in metres, known-free cells first and unknown cells only when
//!   that fails, clear errors for blocked, unreachable and out-of-map goals.
//! * [`octree_astar`]: A* through the free voxels of an octree, for flying robots.
//! * [`tracker`]: carrot-following path tracker for a unicycle (differential-drive) robot.
//! * [`gating`]: pauses mapping and planning while the camera turns too fast (motion blur).
//! * [`render`]: draws a path on its grid, for `map.png`.
//! * `error`: [`NavError`], what planning and tracking refuse.
//!
//! Frames: planners work in the map frame of the grid or octree they are given (x, y in metres
//! on the floor for 2D grids); the tracker takes the robot's pose `map_from_base` in the same
//! frame. Each stage is a struct or free function called once per step, so a closed loop can
//! drive them at its own rate. Nothing here prints, reads files or exits.

pub mod error;
pub mod gating;
pub mod grid_search;
pub mod jps;
pub mod octree_astar;
pub mod planning;
pub mod render;
pub mod tracker;

pub use error::NavError;
pub use gating::{MotionGate, MotionGateConfig};
pub use grid_search::{CostModel, SearchResult};
pub use octree_astar::{plan_octree, OctreePath, OctreePlannerConfig};
pub use planning::{plan_on_grid, GridPlanner, PlannedPath};
pub use tracker::{PathTracker, TrackerCommand, TrackerConfig, TrackerStatus};
