//! [`GroundRobotNav`]: a small ground robot that localises with its RGB-D camera, maps the
//! floor, plans to a goal and follows the plan.
//!
//! Every camera frame goes through [`floor_mapping`]: visual odometry ([`crate::VisualSlam`])
//! gives the base pose through the camera mount, and the frame's depth goes into a floor grid.
//! Every `replan_period_s` (while the motion gate is open) the path is re-planned from the
//! estimated position to the goal on the grid inflated by the robot's radius and a margin
//! (known-free cells first, unknown cells only when needed, [`plan_on_grid`]); the
//! carrot-following tracker ([`PathTracker`]) turns the estimate into speed and yaw-rate
//! commands ([`GroundRobotNav::command`]), zero while VO has lost the frame.
//!
//! Basic settings for a new robot: the camera's intrinsics and mounting ([`MountedCamera`]),
//! [`GroundRobotNavConfig::robot_radius_m`] and the grid's resolution; the rest is advanced.
//! [`closed_loop`] drives a simulated robot ([`slamkit_sim::GroundRobot`]) with it.

pub mod closed_loop;
pub mod floor_mapping;
pub mod map;
mod run_files;

pub use floor_mapping::{map_from_world, CameraStats, FrameOutcome, MountedCamera};

use nalgebra::{Point2, Vector2};
use serde::{Deserialize, Serialize};
use slamkit_core::observation::Observation;
use slamkit_core::{Pose3, StageTimings};
use slamkit_map::floor_grid::FloorGridConfig;
use slamkit_map::{Occupancy, TriGrid};
use slamkit_nav::{
    plan_on_grid, GridPlanner, MotionGateConfig, NavError, PathTracker, PlannedPath,
    TrackerCommand, TrackerConfig,
};
use slamkit_vo::VoConfig;
use std::time::Instant;

use crate::map_file::{self, MapFile, MapFileError};
use crate::session::{Session, Update};
use crate::SlamError;
use floor_mapping::FloorMapping;
use std::path::Path;

/// The floor grid covers the rectangle around the start and the goal widened by this \[m\].
pub const MAP_MARGIN_M: f64 = 10.0;

/// Look-ahead of the tracker \[m\]: the tracker's 0.5 m default cuts the hairpin around the
/// end of the `large` world's wall at (5, 4) so tightly that the body touches it (seeds 1 to 9
/// stuck there); 0.3 m follows it (seeds 1 to 10 reach the goal).
pub const TRACKER_LOOKAHEAD_M: f64 = 0.3;

/// Everything [`GroundRobotNav`] can be told besides its camera, start and goal.
///
/// Basic (what a new robot needs): `robot_radius_m`, `safety_margin_m`, `grid` (its
/// `resolution_m`, the obstacle band `min_height_m` / `max_height_m` above the floor, the
/// depth `max_range_m` it maps), `vo` (the camera's
/// settings, see [`VoConfig`]). The rest is advanced.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GroundRobotNavConfig {
    /// Re-plan from the estimated pose this often \[s\].
    pub replan_period_s: f64,
    /// Radius of the robot's body: obstacles are inflated by it \[m\].
    pub robot_radius_m: f64,
    /// Obstacles are inflated by this much beyond the robot's radius, room for the tracker to
    /// cut corners \[m\].
    pub safety_margin_m: f64,
    /// The floor grid built from the depth images.
    pub grid: FloorGridConfig,
    /// Depth pixels inserted: every `depth_step_px`-th pixel of every `depth_step_px`-th row.
    pub depth_step_px: usize,
    /// The path tracker (its goal tolerance is where the robot stops).
    pub tracker: TrackerConfig,
    /// Visual odometry.
    pub vo: VoConfig,
    /// Mapping and planning pause while the camera turns faster than this.
    pub gate: MotionGateConfig,
}

impl Default for GroundRobotNavConfig {
    fn default() -> Self {
        Self {
            replan_period_s: 1.5,
            robot_radius_m: 0.15,
            safety_margin_m: 0.05,
            grid: FloorGridConfig::default(),
            depth_step_px: 4,
            tracker: TrackerConfig {
                lookahead_m: TRACKER_LOOKAHEAD_M,
                ..TrackerConfig::default()
            },
            vo: VoConfig::default(),
            gate: MotionGateConfig::default(),
        }
    }
}

impl GroundRobotNavConfig {
    /// Checks the values the session uses itself (its parts check theirs when built).
    ///
    /// # Errors
    /// [`SlamError::Config`] naming the bad field.
    pub fn validate(&self) -> Result<(), SlamError> {
        if !(self.replan_period_s > 0.0 && self.replan_period_s.is_finite()) {
            return Err(SlamError::Config(
                "replan_period_s must be positive and finite".into(),
            ));
        }
        if ![self.robot_radius_m, self.safety_margin_m]
            .iter()
            .all(|r| r.is_finite() && *r >= 0.0)
        {
            return Err(SlamError::Config(
                "robot_radius_m and safety_margin_m must be finite and not negative".into(),
            ));
        }
        Ok(())
    }

    /// Obstacle inflation in cells of `resolution_m`: the robot's radius and the safety
    /// margin, rounded up.
    pub fn inflate_cells(&self, resolution_m: f64) -> usize {
        let radius_m = self.robot_radius_m + self.safety_margin_m;
        (radius_m / resolution_m - 1e-9).ceil().max(0.0) as usize
    }
}

/// Localisation, floor mapping, planning and path tracking of a ground robot.
///
/// ```
/// use nalgebra::Point2;
/// use slamkit_core::Observation;
/// use slamkit_slam::ground_robot::closed_loop::NavLoopConfig;
/// use slamkit_slam::ground_robot::{GroundRobotNavConfig, MountedCamera};
/// use slamkit_slam::GroundRobotNav;
/// use slamkit_sim::{GroundRobot, World};
///
/// // the simulated robot of `slamkit nav`: its camera 0.45 m up, tilted 10° down
/// let sim = NavLoopConfig::default().sim;
/// let robot = GroundRobot::new(World::builtin("office")?, &sim, 1)?;
/// let camera = MountedCamera {
///     intrinsics: sim.rgbd.intrinsics,
///     base_from_camera: sim.rgbd.mount.base_from_camera(),
/// };
/// let start = robot.at_base_height(&robot.truth());
/// let goal = Point2::new(11.5, 5.0);
/// let mut nav = GroundRobotNav::new(&GroundRobotNavConfig::default(), camera, &start, goal)?;
/// let frame = robot.rgbd_frame(0, 0.0);
/// let outcome = nav.process(Observation::Rgbd(frame)).ok_or("an RGB-D frame is used")?;
/// // the first frame is at the known start; its depth is mapped and the first plan made
/// let pose = outcome.world_from_base.ok_or("no pose")?;
/// assert!((pose.translation.vector - robot.truth().translation.vector).norm() < 1e-9);
/// assert_eq!(nav.plans().len(), 1);
/// let command = nav.command(0.1);
/// assert!(command.speed_m_s >= 0.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct GroundRobotNav {
    mapping: FloorMapping,
    tracker: PathTracker,
    goal: Point2<f64>,
    inflate: usize,
    plans: Vec<PlannedPath>,
    plan_failures: usize,
    next_replan_s: f64,
    replan_period_s: f64,
    /// The last frame's outcome (its pose steers the tracker).
    last: Option<FrameOutcome>,
    timings: StageTimings,
}

impl GroundRobotNav {
    /// A robot at the known `world_from_base` `start` heading for `goal` (world x, y), with an
    /// empty map covering the start and the goal widened by [`MAP_MARGIN_M`].
    ///
    /// # Errors
    /// [`SlamError`] for an invalid configuration of the session or of one of its parts.
    pub fn new(
        config: &GroundRobotNavConfig,
        camera: MountedCamera,
        start: &Pose3,
        goal: Point2<f64>,
    ) -> Result<Self, SlamError> {
        config.validate()?;
        let s = start.translation;
        let margin = Vector2::new(MAP_MARGIN_M, MAP_MARGIN_M);
        let bounds = [
            Point2::new(s.x.min(goal.x), s.y.min(goal.y)) - margin,
            Point2::new(s.x.max(goal.x), s.y.max(goal.y)) + margin,
        ];
        let mapping = FloorMapping::new(
            camera,
            &config.vo,
            (&config.grid, &config.gate),
            config.depth_step_px,
            start,
            bounds,
        )?;
        Ok(Self {
            mapping,
            tracker: PathTracker::new(config.tracker.clone())?,
            goal,
            inflate: config.inflate_cells(config.grid.resolution_m),
            plans: Vec::new(),
            plan_failures: 0,
            next_replan_s: 0.0,
            replan_period_s: config.replan_period_s,
            last: None,
            timings: StageTimings::default(),
        })
    }

    /// Takes one observation: an RGB-D frame localises the robot, maps its depth and, when
    /// due, re-plans; anything else is ignored (`None`). [`Session::push`] gives the same
    /// frame's [`Update`] alone.
    pub fn process(&mut self, observation: Observation) -> Option<FrameOutcome> {
        let Observation::Rgbd(frame) = observation else {
            return None;
        };
        let t = frame.timestamp;
        let outcome = self.mapping.process(frame, &mut self.timings)?;
        if let (Some(pose), true) = (&outcome.world_from_base, outcome.gate_open) {
            self.replan(t, &Point2::from(pose.translation.vector));
        }
        self.last = Some(outcome.clone());
        Some(outcome)
    }

    /// The velocity command for the next `dt_s` \[s\]: the tracker on the last frame's pose
    /// (zero without one).
    pub fn command(&mut self, dt_s: f64) -> TrackerCommand {
        let started = Instant::now();
        let estimate = self.last.as_ref().and_then(|o| o.world_from_base);
        let command = self.tracker.step(estimate.as_ref(), dt_s);
        self.timings.record_since("track", started);
        command
    }

    /// Heads for `goal` (world x, y) from now on: the next frame with a pose re-plans. The
    /// map keeps the bounds it was made with (the start and the first goal widened by
    /// [`MAP_MARGIN_M`]), so a goal beyond them does not plan (a counted plan failure).
    pub fn set_goal(&mut self, goal: Point2<f64>) {
        self.goal = goal;
        self.next_replan_s = f64::NEG_INFINITY;
    }

    /// The goal (world x, y).
    pub fn goal(&self) -> Point2<f64> {
        self.goal
    }

    /// The path being followed (world x, y).
    pub fn path(&self) -> &[Point2<f64>] {
        self.tracker.path()
    }

    /// Every plan made, in order.
    pub fn plans(&self) -> &[PlannedPath] {
        &self.plans
    }

    /// Re-plans that failed (the previous path was kept).
    pub fn plan_failures(&self) -> usize {
        self.plan_failures
    }

    /// The map so far as a tri-state grid over the world's (x, y).
    pub fn grid(&self) -> TriGrid {
        self.mapping.grid()
    }

    /// Camera frame counters.
    pub fn camera_stats(&self) -> CameraStats {
        self.mapping.stats()
    }

    /// Wall time per stage \[ms\]: `vo`, `map`, `plan`, `track`.
    pub fn timings(&self) -> &StageTimings {
        &self.timings
    }

    /// The map as a map file: the camera's keyframes ([`crate::visual::keyframes`]) and the
    /// floor grid ([`map`]), rig RGB-D.
    ///
    /// # Errors
    /// [`MapFileError::Malformed`] for counts beyond what the format holds.
    pub fn map_file(&self) -> Result<MapFile, MapFileError> {
        let mut file = self
            .mapping
            .visual()
            .map()
            .to_map_file(map_file::Rig::Rgbd)?;
        file.sections.push(map::floor_section(&self.grid())?);
        file.header.notes = serde_json::json!({ "session": "ground robot navigation" });
        Ok(file)
    }

    /// Re-plans when due (or when there is no path yet).
    fn replan(&mut self, t: f64, position: &Point2<f64>) {
        if t + 1e-9 < self.next_replan_s && !self.tracker.path().is_empty() {
            return;
        }
        let started = Instant::now();
        let planned = plan_inflated(&self.mapping.grid(), position, &self.goal, self.inflate);
        self.timings.record_since("plan", started);
        match planned {
            Ok(path) => {
                self.tracker.set_path(&path.waypoints_m);
                self.plans.push(path);
            }
            Err(_) => self.plan_failures += 1,
        }
        self.next_replan_s = t + self.replan_period_s;
    }
}

impl Session for GroundRobotNav {
    fn push(&mut self, observation: Observation) -> Option<Update> {
        self.process(observation).map(|o| o.update)
    }

    /// Writes the camera's keyframes and the floor grid ([`GroundRobotNav::map_file`]).
    fn save(&self, path: &Path) -> Result<(), SlamError> {
        self.map_file()
            .and_then(|file| file.save(path))
            .map_err(|source| SlamError::MapFile {
                path: path.to_path_buf(),
                source,
            })
    }
}

/// Plans on `grid` inflated by `inflate` cells from `start` to `goal`, the cells near `start`
/// that are blocked only by inflation freed (the robot may start next to a wall).
///
/// # Errors
/// [`NavError`] when the start or goal is off the grid or in an obstacle, or no path exists.
pub fn plan_inflated(
    grid: &TriGrid,
    start: &Point2<f64>,
    goal: &Point2<f64>,
    inflate: usize,
) -> Result<PlannedPath, NavError> {
    let mut inflated = grid.inflated(inflate);
    clear_inflation_around(&mut inflated, grid, start, inflate);
    plan_on_grid(&inflated, start, goal, GridPlanner::Astar)
}

/// Frees the cells within `radius` (Chebyshev) of `point` that are occupied only through
/// inflation.
fn clear_inflation_around(
    inflated: &mut TriGrid,
    original: &TriGrid,
    point: &Point2<f64>,
    radius: usize,
) {
    let Some((cx, cy)) = original.cell_at(point) else {
        return;
    };
    for y in cy.saturating_sub(radius)..=cy + radius {
        for x in cx.saturating_sub(radius)..=cx + radius {
            if original.get(x, y).is_some_and(|o| o != Occupancy::Occupied) {
                inflated.set(x, y, original.get(x, y).unwrap_or(Occupancy::Unknown));
            }
        }
    }
}
