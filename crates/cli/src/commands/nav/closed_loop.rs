//! The closed navigation loop in the simulator, stepped at the RGB-D camera's rate.
//!
//! The simulated differential-drive robot ([`slamkit_sim`]) starts at the first point of the
//! world's drive path, knowing its start pose (the goal is given in world coordinates). At
//! every camera period: the simulator renders a noisy RGB-D frame from the true camera pose;
//! [`CameraSlam`] localises with visual odometry and maps the depth into a floor grid; every
//! `replan_period_s` (while the motion gate is open) the path is re-planned from the estimated
//! position to the goal on the inflated grid (known-free cells first, unknown cells only when
//! needed, [`plan_on_grid`]); the carrot-following tracker ([`PathTracker`]) turns the
//! estimate into speed and yaw-rate commands (zero when VO lost the frame), which the
//! simulator integrates (exact unicycle arcs) to move the true robot. A move that would bring
//! the robot's body into an obstacle is refused (the robot stays put) and counted.
//!
//! Scoring uses what the robot never sees: the true poses, and the world rasterised into a grid
//! whose inflated A* path from start to goal is the reference length.

use super::camera_slam::{CameraSlam, CameraStats};
use anyhow::Context;
use nalgebra::{Point2, Point3, Vector2};
use serde::{Deserialize, Serialize};
use slamkit_core::image::{Image, RgbImage};
use slamkit_core::pose::{pose2_to_pose3, pose3_to_pose2};
use slamkit_core::{Pose2, Pose3, StageTimings, Trajectory};
use slamkit_map::floor_grid::FloorGridConfig;
use slamkit_map::{Occupancy, TriGrid};
use slamkit_nav::{
    plan_on_grid, GridPlanner, MotionGateConfig, PathTracker, PlannedPath, TrackerConfig,
    TrackerStatus,
};
use slamkit_sim::camera::render_rgbd;
use slamkit_sim::{
    CameraMount, RgbdCameraConfig, RobotKind, Scene, SimConfig, Simulation, Stream, World,
};
use slamkit_vo::{FrameStatus, VoConfig};
use std::time::Instant;

/// Frame rate of the camera in the loop \[Hz\] (the sensor gives 30). Measured on office
/// seed 1 (BENCHMARKS.md): a 640×480 frame takes a median 52 ms to render and 11 ms of VO, so
/// 30 Hz would run the simulation at half real time; at 10 Hz the robot moves at most 2.5 cm
/// and turns at most 3° between frames, well within KLT's reach.
pub const CAMERA_RATE_HZ: f64 = 10.0;

/// Cell size of the true map on which the optimal path is planned \[m\].
pub const TRUTH_RESOLUTION_M: f64 = 0.05;

/// The camera on the robot: 0.45 m above the floor, 5 cm ahead of the base's centre, tilted
/// 10° down (a Kinect on a TurtleBot 2 sits about as high). The simulator's default, 0.2 m and
/// level, sees the floor at grazing angles and, in the office's open middle, little else within
/// the 4.5 m depth range: VO keeps 50-80 inliers there and its yaw jumps by up to 3° (seeds 1 to
/// 4: 2 of 4 reached, localisation error up to 0.37 m; BENCHMARKS.md).
pub fn camera_mount() -> CameraMount {
    CameraMount {
        xyz_m: [0.05, 0.0, 0.45],
        tilt_down_rad: 10f64.to_radians(),
    }
}

/// The floor grid covers the rectangle around the start and the goal widened by this \[m\].
pub const MAP_MARGIN_M: f64 = 10.0;

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
    /// The simulated robot and its sensors (`robot` is always the ground robot; the camera is
    /// `sim.rgbd`).
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
            grid: FloorGridConfig::default(),
            depth_step_px: 4,
            tracker: TrackerConfig {
                lookahead_m: TRACKER_LOOKAHEAD_M,
                ..TrackerConfig::default()
            },
            vo: VoConfig::default(),
            gate: MotionGateConfig::default(),
            sim: SimConfig {
                robot: RobotKind::DiffDrive,
                rgbd: RgbdCameraConfig {
                    rate_hz: CAMERA_RATE_HZ,
                    mount: camera_mount(),
                    ..RgbdCameraConfig::default()
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

    /// Obstacle inflation in cells of `resolution_m`: the robot's radius and the safety
    /// margin, rounded up.
    pub fn inflate_cells(&self, resolution_m: f64) -> usize {
        let radius_m = self.robot_radius_m + self.safety_margin_m;
        (radius_m / resolution_m - 1e-9).ceil().max(0.0) as usize
    }
}

/// What a run did, with its truth-based scores.
#[derive(Debug)]
pub struct NavOutcome {
    /// True `world_from_base` at every step.
    pub ground_truth: Trajectory,
    /// Estimated `world_from_base` (VO through the camera mount) at every step.
    pub estimate: Trajectory,
    /// Every plan made, in order.
    pub plans: Vec<PlannedPath>,
    /// The map built by the robot (world frame).
    pub grid: TriGrid,
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
    /// Camera frame counters.
    pub camera_stats: CameraStats,
    /// Every frame: true and estimated pose, what VO made of it.
    pub frames: Vec<FrameRecord>,
    /// Per-stage times: `render`, `vo`, `map`, `plan`, `track` (ms).
    pub timings: StageTimings,
}

/// One camera frame of the run.
#[derive(Debug, Clone)]
pub struct FrameRecord {
    /// Simulated time \[s\].
    pub t_s: f64,
    /// True `world_from_base`.
    pub truth: Pose2,
    /// Estimated `world_from_base` (`None`: VO failed).
    pub estimate: Option<Pose2>,
    /// What VO made of the frame.
    pub status: FrameStatus,
}

/// The robot's state while the loop runs.
struct Robot {
    sim: Simulation,
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
        Ok(Self {
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

    /// Frame number `index` of the camera at the true pose: colour and depth \[m\].
    fn frame(&self, index: usize) -> (RgbImage, Image<f32>) {
        let camera = &self.sim.config.rgbd;
        let world_from_camera = self.truth3(&self.truth) * camera.mount.base_from_camera();
        render_rgbd(
            &self.sim.scene,
            camera,
            world_from_camera,
            &self.sim.rng(Stream::Image, index as u64),
            &self.sim.rng(Stream::Depth, index as u64),
        )
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
    camera: CameraSlam,
    tracker: PathTracker,
    plans: Vec<PlannedPath>,
    plan_failures: usize,
    next_replan_s: f64,
    replan_period_s: f64,
    timings: StageTimings,
}

impl LoopState {
    /// Empty map, no path, VO started at the robot's known start pose `start`; the map covers
    /// the start and the goal widened by [`MAP_MARGIN_M`].
    fn new(config: &NavLoopConfig, start: &Pose3, goal: &Point2<f64>) -> anyhow::Result<Self> {
        let s = start.translation;
        let margin = Vector2::new(MAP_MARGIN_M, MAP_MARGIN_M);
        let bounds = [
            Point2::new(s.x.min(goal.x), s.y.min(goal.y)) - margin,
            Point2::new(s.x.max(goal.x), s.y.max(goal.y)) + margin,
        ];
        let camera = CameraSlam::new(
            &config.sim.rgbd,
            &config.vo,
            &config.grid,
            &config.gate,
            config.depth_step_px,
            start,
            bounds,
        )?;
        Ok(Self {
            camera,
            tracker: PathTracker::new(config.tracker.clone()).context("tracker configuration")?,
            plans: Vec::new(),
            plan_failures: 0,
            next_replan_s: 0.0,
            replan_period_s: config.replan_period_s,
            timings: StageTimings::default(),
        })
    }

    /// Re-plans when due (or when there is no path yet).
    fn replan(&mut self, t: f64, position: &Point2<f64>, goal: &Point2<f64>, inflate: usize) {
        if t + 1e-9 < self.next_replan_s && !self.tracker.path().is_empty() {
            return;
        }
        let started = Instant::now();
        let planned = plan_inflated(&self.camera.grid(), position, goal, inflate);
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

/// Running scores of a run.
#[derive(Default)]
struct Scores {
    ground_truth: Trajectory,
    estimate: Trajectory,
    max_cross_track_m: f64,
    localisation_errors_m: Vec<f64>,
    blocked_steps: usize,
    frames: Vec<FrameRecord>,
}

impl Scores {
    /// Records the true pose at time `t` and the estimate when VO gave one.
    fn record_poses(&mut self, t: f64, truth: Pose3, estimate: Option<Pose3>) {
        if let Some(estimate) = estimate {
            let error = (truth.translation.vector - estimate.translation.vector).norm();
            self.localisation_errors_m.push(error);
            self.estimate.push(t, estimate);
        }
        self.ground_truth.push(t, truth);
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
            camera_stats: state.camera.stats,
            frames: self.frames,
            grid: state.camera.grid(),
            timings: state.timings,
            plans: state.plans,
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
    let inflate = config.inflate_cells(config.grid.resolution_m);
    let truth_grid = rasterise_world(&robot.sim, TRUTH_RESOLUTION_M, robot.base_height_m)?;
    let start_m = Point2::from(start.translation.vector);
    let optimal = plan_inflated(
        &truth_grid,
        &start_m,
        &goal,
        config.inflate_cells(TRUTH_RESOLUTION_M),
    )
    .with_context(|| format!("goal {},{} on the true map of the world", goal.x, goal.y))?;
    let mut state = LoopState::new(config, &robot.truth3(&start), &goal)?;
    let rate_hz = config.sim.rgbd.rate_hz;
    let dt = 1.0 / rate_hz;
    let mut scores = Scores::default();
    let mut t = 0.0;
    for index in 0.. {
        t = index as f64 / rate_hz;
        let started = Instant::now();
        let (color, depth) = robot.frame(index);
        state.timings.record_since("render", started);
        let frame = state
            .camera
            .process(index, t, color, &depth, &mut state.timings);
        let truth3 = robot.truth3(&robot.truth);
        let estimate = frame.world_from_base;
        scores.record_poses(t, truth3, estimate.as_ref().map(|p| robot.truth3(p)));
        scores.frames.push(FrameRecord {
            t_s: t,
            truth: robot.truth,
            estimate,
            status: frame.status,
        });
        if let Some(pose) = &estimate {
            if frame.gate_open {
                state.replan(t, &Point2::from(pose.translation.vector), &goal, inflate);
            }
        }
        let started = Instant::now();
        let command = state.tracker.step(estimate.as_ref(), dt);
        let truth_position = Point2::from(robot.truth.translation.vector);
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
}
