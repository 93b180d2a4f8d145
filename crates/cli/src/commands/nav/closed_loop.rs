//! The closed navigation loop in the simulator, stepped at the lidar rate.
//!
//! The simulated differential-drive robot ([`slamkit_sim`]) starts at the first point of the
//! world's drive path. At every lidar period: the simulator casts a noisy scan from the true
//! pose and adds the drifting wheel odometry; incremental ICP-SLAM ([`IcpSlam`]) gives the pose
//! estimate; the scan is inserted at that estimate into a growing log-odds occupancy grid;
//! every `replan_period_s` the path is re-planned from the estimated position to the goal on the
//! inflated grid (known-free cells first, unknown cells only when needed, [`plan_on_grid`]); the
//! carrot-following tracker ([`PathTracker`]) turns the estimate into speed and yaw-rate
//! commands, which the simulator integrates (exact unicycle arcs) to move the true robot.
//! A move that would bring the robot's body into an obstacle is refused (the robot stays put)
//! and counted. The simulator has no RGB-D camera, so localisation is lidar ICP-SLAM.
//!
//! The SLAM frame is anchored at the first scan; the robot knows its start pose in the world
//! (the goal is given in world coordinates), so estimates are mapped into the world frame by it.
//!
//! Scoring uses what the robot never sees: the true poses, and the world rasterised into a grid
//! whose inflated A* path from start to goal is the reference length.

use anyhow::Context;
use nalgebra::{Point2, Point3, Vector2};
use serde::{Deserialize, Serialize};
use slamkit_core::pose::{pose2_to_pose3, pose3_to_pose2};
use slamkit_core::{LaserScan, Pose2, Pose3, StageTimings, Trajectory};
use slamkit_lidar::icp_slam::{IcpSlam, IcpSlamConfig, IcpSlamStats};
use slamkit_map::{CellIndex, Occupancy, OccupancyGrid, OccupancyGridConfig, TriGrid};
use slamkit_nav::{
    plan_on_grid, GridPlanner, PathTracker, PlannedPath, TrackerConfig, TrackerStatus,
};
use slamkit_sim::{
    Lidar2dConfig, OdometrySimulator, RobotKind, Scene, SimConfig, Simulation, Stream, World,
};
use std::time::Instant;

/// Range of the ground robot's lidar \[m\]: the simulator's default 3 m (a drone's lidar)
/// leaves the office's open areas with a single wall in view, along which ICP slides (seeds 1
/// to 10: 0.08 to 0.84 m of localisation error); 8 m is within the reach of common 2D lidars
/// of small ground robots (12 m for an RPLIDAR A1).
pub const GROUND_LIDAR_RANGE_M: f64 = 8.0;

/// Look-ahead of the tracker in the loop \[m\]: the tracker's 0.5 m default cuts the hairpin
/// around the end of the `large` world's wall at (5, 4) so tightly that the body touches it
/// (seeds 1 to 9 stuck there); 0.3 m follows it (seeds 1 to 10 reach the goal).
pub const TRACKER_LOOKAHEAD_M: f64 = 0.3;

/// Everything the loop needs besides the world, goal and seed.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NavLoopConfig {
    /// Re-plan from the estimated pose this often \[s\].
    pub replan_period_s: f64,
    /// The goal counts as reached within this distance of the true position \[m\].
    pub goal_tolerance_m: f64,
    /// The run stops after this much simulated time \[s\].
    pub time_limit_s: f64,
    /// Radius of the robot's body: obstacles are inflated by it and the simulator refuses moves
    /// that bring it into contact \[m\].
    pub robot_radius_m: f64,
    /// Obstacles are inflated by this much beyond the robot's radius, room for the tracker to
    /// cut corners \[m\].
    pub safety_margin_m: f64,
    /// The growing map.
    pub grid: OccupancyGridConfig,
    /// The path tracker (its goal tolerance is where the robot stops).
    pub tracker: TrackerConfig,
    /// Localisation and mapping.
    pub slam: IcpSlamConfig,
    /// The simulated robot and its sensors (`robot` is always the ground robot).
    pub sim: SimConfig,
}

impl Default for NavLoopConfig {
    fn default() -> Self {
        Self {
            replan_period_s: 1.5,
            goal_tolerance_m: 0.2,
            time_limit_s: 240.0,
            robot_radius_m: 0.15,
            safety_margin_m: 0.05,
            grid: OccupancyGridConfig::default(),
            tracker: TrackerConfig {
                lookahead_m: TRACKER_LOOKAHEAD_M,
                ..TrackerConfig::default()
            },
            slam: IcpSlamConfig::default(),
            sim: SimConfig {
                robot: RobotKind::DiffDrive,
                lidar: Lidar2dConfig {
                    max_range_m: GROUND_LIDAR_RANGE_M,
                    ..Lidar2dConfig::default()
                },
                ..SimConfig::default()
            },
        }
    }
}

impl NavLoopConfig {
    /// Checks the loop's own values (the parts check theirs when built).
    pub fn validate(&self) -> anyhow::Result<()> {
        anyhow::ensure!(
            self.replan_period_s > 0.0 && self.time_limit_s.is_finite() && self.time_limit_s > 0.0,
            "replan_period_s and time_limit_s must be positive and finite"
        );
        anyhow::ensure!(
            [self.robot_radius_m, self.safety_margin_m]
                .iter()
                .all(|r| r.is_finite() && *r >= 0.0),
            "robot_radius_m and safety_margin_m must be finite and not negative"
        );
        Ok(())
    }

    /// Obstacle inflation in grid cells: the robot's radius and the safety margin, rounded up.
    pub fn inflate_cells(&self) -> usize {
        let radius_m = self.robot_radius_m + self.safety_margin_m;
        (radius_m / self.grid.resolution_m - 1e-9).ceil().max(0.0) as usize
    }
}

/// What a run did, with its truth-based scores.
#[derive(Debug)]
pub struct NavOutcome {
    /// True `world_from_base` at every step.
    pub ground_truth: Trajectory,
    /// Estimated `world_from_base` (SLAM, mapped into the world frame) at every step.
    pub estimate: Trajectory,
    /// Every plan made, in order.
    pub plans: Vec<PlannedPath>,
    /// The map built by the robot (world frame).
    pub grid: OccupancyGrid,
    /// Shortest path from start to goal on the world rasterised ([`rasterise_world`]) and
    /// inflated by the robot's radius.
    pub optimal: PlannedPath,
    /// True when the true position ended within the goal tolerance.
    pub reached: bool,
    /// Simulated time at the end \[s\].
    pub time_s: f64,
    /// Length driven by the true robot \[m\].
    pub path_length_m: f64,
    /// Largest distance of the true position from the path being followed \[m\].
    pub max_cross_track_m: f64,
    /// Mean distance between estimated and true positions \[m\].
    pub localisation_error_mean_m: f64,
    /// Largest distance between estimated and true positions \[m\].
    pub localisation_error_max_m: f64,
    /// Distance from the final true position to the goal \[m\].
    pub final_distance_m: f64,
    /// Re-plans that failed (the previous path was kept).
    pub plan_failures: usize,
    /// Steps whose move was refused because the body would touch an obstacle.
    pub blocked_steps: usize,
    /// ICP-SLAM counters.
    pub slam_stats: IcpSlamStats,
    /// Per-stage times: `slam`, `map`, `plan`, `track` (ms).
    pub timings: StageTimings,
}

/// The robot's state while the loop runs.
struct Robot {
    sim: Simulation,
    odometry: OdometrySimulator,
    truth: Pose2,
    base_height_m: f64,
}

impl Robot {
    fn new(world: World, config: &NavLoopConfig, seed: u64) -> anyhow::Result<Self> {
        let sim_config = SimConfig {
            robot: RobotKind::DiffDrive,
            ..config.sim.clone()
        };
        let sim = Simulation::new(world, sim_config, seed).context("setting up the simulation")?;
        let start = sim.state_at(0.0).world_from_base;
        let odometry =
            OdometrySimulator::new(sim.odometry_config().clone(), sim.rng(Stream::Odometry, 0));
        Ok(Self {
            odometry,
            truth: pose3_to_pose2(&start),
            base_height_m: start.translation.z,
            sim,
        })
    }

    fn truth3(&self, pose: &Pose2) -> Pose3 {
        let mut p = pose2_to_pose3(pose);
        p.translation.z = self.base_height_m;
        p
    }

    /// Scan number `index` at time `t` from the true pose, with the odometry so far.
    fn scan(&mut self, index: usize, t: f64) -> LaserScan {
        let pose = self.truth3(&self.truth);
        let mut rng = self.sim.rng(Stream::Lidar, index as u64);
        let mut scan = self
            .sim
            .config
            .lidar
            .scan(&self.sim.scene, &pose, t, &mut rng);
        scan.odometry = Some(self.odometry.update(&self.truth));
        scan
    }

    /// Drives `dt_s` under the command; returns false when the move was refused.
    fn drive(&mut self, speed_m_s: f64, yaw_rate_rad_s: f64, dt_s: f64, radius_m: f64) -> bool {
        let next = unicycle_step(&self.truth, speed_m_s, yaw_rate_rad_s, dt_s);
        if body_collides(&self.sim.scene, &next, self.base_height_m, radius_m) {
            return false;
        }
        self.truth = next;
        true
    }
}

/// The pose after driving at `v` and turning at `w` for `dt` (exact arc).
pub fn unicycle_step(pose: &Pose2, v: f64, w: f64, dt: f64) -> Pose2 {
    let turn = w * dt;
    let local = if turn.abs() < 1e-9 {
        Vector2::new(v * dt, 0.0)
    } else {
        let r = v / w;
        Vector2::new(r * turn.sin(), r * (1.0 - turn.cos()))
    };
    pose * Pose2::new(local, turn)
}

/// True when the robot's body (a sphere of `radius_m` centred `radius_m` above the floor, at
/// least at base height) at `pose` touches an obstacle or leaves the room.
fn body_collides(scene: &Scene, pose: &Pose2, base_height_m: f64, radius_m: f64) -> bool {
    let t = pose.translation.vector;
    let z = base_height_m.max(radius_m) + 0.1;
    scene.collides(&Point3::new(t.x, t.y, z), radius_m)
}

/// The world as a grid at `resolution_m`: a cell is occupied where a robot-body-height probe
/// of half a cell's size touches an obstacle or the room's walls.
pub fn rasterise_world(
    sim: &Simulation,
    resolution_m: f64,
    base_height_m: f64,
) -> anyhow::Result<TriGrid> {
    let [sx, sy] = sim.world.size_m;
    let (w, h) = (
        (sx / resolution_m).ceil().max(1.0) as usize,
        (sy / resolution_m).ceil().max(1.0) as usize,
    );
    let mut grid = TriGrid::new(w, h, resolution_m, Point2::origin(), Occupancy::Free)
        .context("rasterising the world")?;
    for y in 0..grid.height() {
        for x in 0..grid.width() {
            let c = grid.cell_center_m(x, y);
            let pose = Pose2::new(c.coords, 0.0);
            if body_collides(&sim.scene, &pose, base_height_m, resolution_m / 2.0) {
                grid.set(x, y, Occupancy::Occupied);
            }
        }
    }
    Ok(grid)
}

/// The robot's map as a tri-state grid holding its known cells and every point of `must_hold`
/// (start, goal), with `margin` unknown cells around them so the planner can skirt them.
pub fn planning_grid(
    grid: &OccupancyGrid,
    must_hold: &[Point2<f64>],
    margin: i32,
) -> Option<TriGrid> {
    let mut cells: Vec<CellIndex> = must_hold
        .iter()
        .map(|p| grid.cell_at(p))
        .collect::<Option<_>>()?;
    if let Some(b) = grid.known_bounds() {
        cells.extend([b.min, b.max]);
    }
    let min_x = cells.iter().map(|c| c.x).min()? - margin;
    let min_y = cells.iter().map(|c| c.y).min()? - margin;
    let max_x = cells.iter().map(|c| c.x).max()? + margin;
    let max_y = cells.iter().map(|c| c.y).max()? + margin;
    let res = grid.resolution_m();
    let origin = grid.origin_m() + Vector2::new(f64::from(min_x) * res, f64::from(min_y) * res);
    let (w, h) = ((max_x - min_x + 1) as usize, (max_y - min_y + 1) as usize);
    let mut tri = TriGrid::new(w, h, res, origin, Occupancy::Unknown)?;
    for y in 0..h {
        for x in 0..w {
            let index = CellIndex {
                x: min_x + x as i32,
                y: min_y + y as i32,
            };
            if let Some(o) = grid.occupancy(index) {
                tri.set(x, y, o);
            }
        }
    }
    Some(tri)
}

/// Frees the cells within `radius` (Chebyshev) of `point` that are occupied only through
/// inflation: the robot may start from (or head to) a spot close to a wall.
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

/// Plans on `grid` inflated by `inflate` cells from `start` to `goal`.
fn plan_inflated(
    grid: &TriGrid,
    start: &Point2<f64>,
    goal: &Point2<f64>,
    inflate: usize,
) -> Result<PlannedPath, slamkit_nav::NavError> {
    let mut inflated = grid.inflated(inflate);
    clear_inflation_around(&mut inflated, grid, start, inflate);
    plan_on_grid(&inflated, start, goal, GridPlanner::Astar)
}

/// Distance from `p` to the polyline `path` (to its only point when it has one).
pub fn distance_to_polyline(p: &Point2<f64>, path: &[Point2<f64>]) -> Option<f64> {
    if let [only] = path {
        return Some((p - only).norm());
    }
    path.windows(2)
        .map(|w| {
            let (a, b) = (w[0], w[1]);
            let ab = b - a;
            let len2 = ab.norm_squared();
            let s = if len2 > 0.0 {
                ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (p - (a + ab * s)).norm()
        })
        .min_by(f64::total_cmp)
}

/// The state of the loop between steps.
struct LoopState {
    slam: IcpSlam,
    grid: OccupancyGrid,
    tracker: PathTracker,
    world_from_slam: Pose2,
    plans: Vec<PlannedPath>,
    plan_failures: usize,
    next_replan_s: f64,
    replan_period_s: f64,
    timings: StageTimings,
}

impl LoopState {
    /// Empty map, no path; the SLAM frame sits at the robot's start pose `world_from_slam`.
    fn new(config: &NavLoopConfig, world_from_slam: Pose2) -> anyhow::Result<Self> {
        Ok(Self {
            slam: IcpSlam::new(config.slam.clone()).context("ICP-SLAM configuration")?,
            grid: OccupancyGrid::new(config.grid.clone()).context("grid configuration")?,
            tracker: PathTracker::new(config.tracker.clone()).context("tracker configuration")?,
            world_from_slam,
            plans: Vec::new(),
            plan_failures: 0,
            next_replan_s: 0.0,
            replan_period_s: config.replan_period_s,
            timings: StageTimings::default(),
        })
    }

    /// Localises and maps with `scan`; returns the estimated `world_from_base`.
    fn localise(&mut self, scan: &LaserScan) -> anyhow::Result<Pose2> {
        let started = Instant::now();
        let estimate = self.world_from_slam * self.slam.process(scan).world_from_base;
        self.timings.record_since("slam", started);
        let started = Instant::now();
        self.grid
            .insert_scan(scan, &(estimate * scan.base_from_laser))
            .context("inserting a scan into the map")?;
        self.timings.record_since("map", started);
        Ok(estimate)
    }

    /// Re-plans when due (or when there is no path yet).
    fn replan(&mut self, t: f64, position: &Point2<f64>, goal: &Point2<f64>, inflate: usize) {
        if t + 1e-9 < self.next_replan_s && !self.tracker.path().is_empty() {
            return;
        }
        let started = Instant::now();
        let planned = planning_grid(&self.grid, &[*position, *goal], inflate as i32 + 2)
            .ok_or(())
            .and_then(|g| plan_inflated(&g, position, goal, inflate).map_err(|_| ()));
        self.timings.record_since("plan", started);
        match planned {
            Ok(path) => {
                self.tracker.set_path(&path.waypoints_m);
                self.plans.push(path);
            }
            Err(()) => self.plan_failures += 1,
        }
        self.next_replan_s = t + self.replan_period_s;
    }
}

/// Running scores of a run.
#[derive(Default)]
struct Scores {
    ground_truth: Trajectory,
    estimate: Trajectory,
    max_cross_track_m: f64,
    localisation_errors_m: Vec<f64>,
    blocked_steps: usize,
}

impl Scores {
    /// Records the true and estimated poses at time `t`.
    fn record_poses(&mut self, t: f64, truth: Pose3, estimate: Pose3) {
        let error = (truth.translation.vector - estimate.translation.vector).norm();
        self.localisation_errors_m.push(error);
        self.ground_truth.push(t, truth);
        self.estimate.push(t, estimate);
    }

    /// The outcome of a run that ended at `time_s`, `final_distance_m` from the goal.
    fn finish(
        self,
        state: LoopState,
        optimal: PlannedPath,
        time_s: f64,
        final_distance_m: f64,
        config: &NavLoopConfig,
    ) -> NavOutcome {
        let errors = &self.localisation_errors_m;
        NavOutcome {
            reached: final_distance_m <= config.goal_tolerance_m,
            time_s,
            path_length_m: self.ground_truth.path_length_m(),
            max_cross_track_m: self.max_cross_track_m,
            localisation_error_mean_m: errors.iter().sum::<f64>() / errors.len().max(1) as f64,
            localisation_error_max_m: errors.iter().copied().fold(0.0, f64::max),
            final_distance_m,
            plan_failures: state.plan_failures,
            blocked_steps: self.blocked_steps,
            slam_stats: *state.slam.stats(),
            timings: state.timings,
            plans: state.plans,
            grid: state.grid,
            ground_truth: self.ground_truth,
            estimate: self.estimate,
            optimal,
        }
    }
}

/// Drives the robot from the start of `world`'s drive path to `goal` (world frame); see the
/// module documentation.
///
/// # Errors
/// A bad configuration, a goal outside the world or inside an obstacle, or no path on the true
/// map from start to goal.
pub fn run_nav_loop(
    world: World,
    goal: Point2<f64>,
    seed: u64,
    config: &NavLoopConfig,
) -> anyhow::Result<NavOutcome> {
    config.validate()?;
    let mut robot = Robot::new(world, config, seed)?;
    let start = robot.truth;
    let inflate = config.inflate_cells();
    let truth_grid = rasterise_world(&robot.sim, config.grid.resolution_m, robot.base_height_m)?;
    let start_m = Point2::from(start.translation.vector);
    let optimal = plan_inflated(&truth_grid, &start_m, &goal, inflate)
        .with_context(|| format!("goal {},{} on the true map of the world", goal.x, goal.y))?;
    let mut state = LoopState::new(config, start)?;
    let rate_hz = config.sim.lidar.rate_hz;
    let dt = 1.0 / rate_hz;
    let mut scores = Scores::default();
    let mut t = 0.0;
    for index in 0.. {
        t = index as f64 / rate_hz;
        let scan = robot.scan(index, t);
        let pose = state.localise(&scan)?;
        scores.record_poses(t, robot.truth3(&robot.truth), robot.truth3(&pose));
        let position = Point2::from(pose.translation.vector);
        let truth_position = Point2::from(robot.truth.translation.vector);
        state.replan(t, &position, &goal, inflate);
        let started = Instant::now();
        let command = state.tracker.step(Some(&pose), dt);
        state.timings.record_since("track", started);
        if let Some(d) = distance_to_polyline(&truth_position, state.tracker.path()) {
            scores.max_cross_track_m = scores.max_cross_track_m.max(d);
        }
        if command.status == TrackerStatus::GoalReached || t >= config.time_limit_s {
            break;
        }
        let moved = robot.drive(
            command.speed_m_s,
            command.yaw_rate_rad_s,
            dt,
            config.robot_radius_m,
        );
        scores.blocked_steps += usize::from(!moved);
    }
    let final_distance_m = (Point2::from(robot.truth.translation.vector) - goal).norm();
    Ok(scores.finish(state, optimal, t, final_distance_m, config))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unicycle_arcs_and_polyline_distances() {
        let quarter = unicycle_step(&Pose2::identity(), 1.0, 1.0, std::f64::consts::FRAC_PI_2);
        assert!((quarter.translation.vector - Vector2::new(1.0, 1.0)).norm() < 1e-9);
        let straight = unicycle_step(&Pose2::identity(), 0.5, 0.0, 2.0);
        assert!((straight.translation.vector - Vector2::new(1.0, 0.0)).norm() < 1e-12);
        let path = [
            Point2::new(0.0, 0.0),
            Point2::new(2.0, 0.0),
            Point2::new(2.0, 2.0),
        ];
        let d = |x, y| distance_to_polyline(&Point2::new(x, y), &path).unwrap();
        assert!((d(1.0, 0.3) - 0.3).abs() < 1e-12);
        assert!((d(2.5, 1.0) - 0.5).abs() < 1e-12);
        assert!((d(-1.0, 0.0) - 1.0).abs() < 1e-12);
        assert_eq!(distance_to_polyline(&Point2::origin(), &[]), None);
    }

    #[test]
    fn planning_grid_holds_the_goal_beyond_the_known_cells() {
        let grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
        let goal = Point2::new(3.0, -2.0);
        let tri = planning_grid(&grid, &[Point2::origin(), goal], 2).unwrap();
        assert!(tri.cell_at(&goal).is_some());
        assert!(tri.cells().iter().all(|c| *c == Occupancy::Unknown));
        let path = plan_inflated(&tri, &Point2::origin(), &goal, 3).unwrap();
        assert!(path.through_unknown && path.length_m > 3.5);
    }

    /// The whole loop on the small world (seed 1): reaches the built-in goal without touching
    /// anything, close to the shortest path.
    #[test]
    fn reaches_the_goal_in_the_small_world() {
        let world = World::builtin("small").unwrap();
        let goal = Point2::new(world.nav_goal[0], world.nav_goal[1]);
        let outcome = run_nav_loop(world, goal, 1, &NavLoopConfig::default()).unwrap();
        assert!(
            outcome.reached,
            "{} m from the goal",
            outcome.final_distance_m
        );
        assert_eq!(outcome.blocked_steps, 0);
        assert!(outcome.path_length_m < 1.25 * outcome.optimal.length_m);
        assert!(
            outcome.max_cross_track_m < 0.25,
            "{}",
            outcome.max_cross_track_m
        );
    }
}
