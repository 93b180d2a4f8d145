//! The closed navigation loop in the simulator (`slamkit nav`), stepped at the RGB-D camera's
//! rate: a [`GroundRobotNav`] drives a simulated [`GroundRobot`] to a goal.
//!
//! The robot starts at the first point of the world's drive path, knowing its start pose (the
//! goal is given in world coordinates). At every camera period the simulator renders a noisy
//! RGB-D frame from the true camera pose, the session localises, maps and re-plans on it and
//! answers with a velocity command, which the simulator integrates to move the true robot (a
//! move into an obstacle is refused and counted).
//!
//! Scoring uses what the session never sees: the true poses, and the world rasterised into a
//! grid whose inflated A* path from start to goal is the reference length.

use nalgebra::Point2;
use serde::{Deserialize, Serialize};
use slamkit_core::image::RgbImage;
use slamkit_core::observation::Observation;
use slamkit_core::{Pose2, Pose3, StageTimings, Trajectory};
use slamkit_map::floor_grid::FloorGridConfig;
use slamkit_map::TriGrid;
use slamkit_nav::render::{draw_path, mark_points, upscale};
use slamkit_nav::{MotionGateConfig, PlannedPath, TrackerConfig, TrackerStatus};
use slamkit_sim::{CameraMount, GroundRobot, RgbdCameraConfig, RobotKind, SimConfig, World};
use slamkit_vo::{FrameStatus, VoConfig};
use std::time::Instant;

use super::{plan_inflated, CameraStats, GroundRobotNav, GroundRobotNavConfig, MountedCamera};
use crate::map_file::MapFile;
use crate::record::NavRecording;
use crate::SlamError;

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

/// Everything the loop needs besides the world, goal and seed: the session's settings, the
/// run's and the simulated robot's. One flat table (as `slamkit nav --config` reads it).
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
        let nav = GroundRobotNavConfig::default();
        Self {
            replan_period_s: nav.replan_period_s,
            goal_tolerance_m: 0.2,
            time_limit_s: 240.0,
            robot_radius_m: nav.robot_radius_m,
            safety_margin_m: nav.safety_margin_m,
            grid: nav.grid,
            depth_step_px: nav.depth_step_px,
            tracker: nav.tracker,
            vo: nav.vo,
            gate: nav.gate,
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
    /// The session's part of the settings.
    pub fn nav(&self) -> GroundRobotNavConfig {
        GroundRobotNavConfig {
            replan_period_s: self.replan_period_s,
            robot_radius_m: self.robot_radius_m,
            safety_margin_m: self.safety_margin_m,
            grid: self.grid.clone(),
            depth_step_px: self.depth_step_px,
            tracker: self.tracker.clone(),
            vo: self.vo.clone(),
            gate: self.gate.clone(),
        }
    }

    /// Checks the loop's own values and the session's.
    ///
    /// # Errors
    /// [`SlamError::Config`] naming the bad field.
    pub fn validate(&self) -> Result<(), SlamError> {
        if !(self.time_limit_s.is_finite() && self.time_limit_s > 0.0) {
            return Err(SlamError::Config(
                "time_limit_s must be positive and finite".into(),
            ));
        }
        self.nav().validate()
    }
}

/// What a run did, with its truth-based scores.
#[derive(Debug)]
pub struct NavOutcome {
    /// True `world_from_base` at every step.
    pub ground_truth: Trajectory,
    /// Estimated `world_from_base` (VO through the camera mount) at every step it had one.
    pub estimate: Trajectory,
    /// Every plan made, in order.
    pub plans: Vec<PlannedPath>,
    /// The map built by the robot (world frame).
    pub grid: TriGrid,
    /// The session's map file (camera keyframes and the floor grid), to save with
    /// [`MapFile::save`].
    pub map: MapFile,
    /// Shortest path from start to goal on the world rasterised at [`TRUTH_RESOLUTION_M`] and
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
    /// Per-stage wall times: `render`, `vo`, `map`, `plan`, `track`, and `record` when
    /// recording (ms).
    pub timings: StageTimings,
}

impl NavOutcome {
    /// The robot's final map with its inflated obstacles shaded (by `config`'s robot radius),
    /// every plan (red), the true-map shortest path (green) and the true driven path (blue),
    /// three pixels per cell (`map.png` of `slamkit nav`).
    pub fn map_image(&self, config: &NavLoopConfig) -> RgbImage {
        let grid = &self.grid;
        let inflated = grid.inflated(config.nav().inflate_cells(config.grid.resolution_m));
        let mut image = draw_path(grid, &inflated, &[]);
        for plan in &self.plans {
            mark_points(
                &mut image,
                grid,
                plan.waypoints_m.iter().copied(),
                [230, 120, 120],
            );
        }
        let optimal = self.optimal.waypoints_m.iter().copied();
        mark_points(&mut image, grid, optimal, [30, 160, 30]);
        let driven = self.ground_truth.poses.iter();
        let driven = driven.map(|p| Point2::new(p.pose.translation.x, p.pose.translation.y));
        mark_points(&mut image, grid, driven, [30, 60, 220]);
        upscale(&image, 3)
    }
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
        nav: GroundRobotNav,
        mut timings: StageTimings,
        (optimal, time_s, final_distance_m): (PlannedPath, f64, f64),
        goal_tolerance_m: f64,
    ) -> Result<NavOutcome, SlamError> {
        let errors = &self.localisation_errors_m;
        timings.merge(nav.timings());
        Ok(NavOutcome {
            map: nav
                .map_file()
                .map_err(|e| SlamError::Map(format!("the robot's map: {e}")))?,
            reached: final_distance_m <= goal_tolerance_m,
            time_s,
            path_length_m: self.ground_truth.path_length_m(),
            max_cross_track_m: self.max_cross_track_m,
            localisation_error_mean_m: errors.iter().sum::<f64>() / errors.len().max(1) as f64,
            localisation_error_max_m: errors.iter().copied().fold(0.0, f64::max),
            final_distance_m,
            plan_failures: nav.plan_failures(),
            blocked_steps: self.blocked_steps,
            camera_stats: nav.camera_stats(),
            frames: self.frames,
            grid: nav.grid(),
            timings,
            plans: nav.plans().to_vec(),
            ground_truth: self.ground_truth,
            estimate: self.estimate,
            optimal,
        })
    }
}

/// Drives the simulated robot from the start of `world`'s drive path to `goal` (world frame);
/// see the module documentation. With a `recording`, every step goes into it as the loop runs
/// (the caller finishes it with the outcome's map).
///
/// # Errors
/// A bad configuration, a goal outside the world or inside an obstacle, no path on the true
/// map from start to goal, or a recording that cannot be written.
pub fn run_nav_loop(
    world: World,
    goal: Point2<f64>,
    seed: u64,
    config: &NavLoopConfig,
    mut recording: Option<&mut NavRecording>,
) -> Result<NavOutcome, SlamError> {
    config.validate()?;
    let mut robot = GroundRobot::new(world, &config.sim, seed)?;
    let start = robot.truth();
    let truth_grid = robot.rasterise_world(TRUTH_RESOLUTION_M)?;
    let start_m = Point2::from(start.translation.vector);
    let optimal = plan_inflated(
        &truth_grid,
        &start_m,
        &goal,
        config.nav().inflate_cells(TRUTH_RESOLUTION_M),
    )
    .map_err(|e| {
        SlamError::Goal(format!(
            "{},{} on the true map of the world: {e}",
            goal.x, goal.y
        ))
    })?;
    let camera = &robot.simulation().config.rgbd;
    let mounted = MountedCamera {
        intrinsics: camera.intrinsics,
        base_from_camera: camera.mount.base_from_camera(),
    };
    let mut nav = GroundRobotNav::new(&config.nav(), mounted, &robot.at_base_height(&start), goal)?;
    let rate_hz = camera.rate_hz;
    let dt = 1.0 / rate_hz;
    let mut timings = StageTimings::default();
    let mut scores = Scores::default();
    let mut t = 0.0;
    for index in 0.. {
        t = index as f64 / rate_hz;
        let started = Instant::now();
        let observation = Observation::Rgbd(robot.rgbd_frame(index, t));
        timings.record_since("render", started);
        if let Some(r) = recording.as_deref_mut() {
            let started = Instant::now();
            r.image(&observation)?;
            timings.record_since("record", started);
        }
        let Some(outcome) = nav.process(observation) else {
            return Err(SlamError::Config(
                "the simulated camera's frames are not the session's".into(),
            ));
        };
        let truth = robot.truth();
        let (estimate, status) = (outcome.world_from_base, outcome.status);
        let truth_3d = robot.at_base_height(&truth);
        let estimate_3d = estimate.as_ref().map(|p| robot.at_base_height(p));
        if let Some(r) = recording.as_deref_mut() {
            let started = Instant::now();
            r.step(t, &truth_3d, estimate_3d.as_ref(), &nav)?;
            timings.record_since("record", started);
        }
        scores.record_poses(t, truth_3d, estimate_3d);
        scores.frames.push(FrameRecord {
            t_s: t,
            truth,
            estimate,
            status,
        });
        let command = nav.command(dt);
        let truth_position = Point2::from(truth.translation.vector);
        if let Some(d) = distance_to_polyline(&truth_position, nav.path()) {
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
    let final_distance_m = (Point2::from(robot.truth().translation.vector) - goal).norm();
    scores.finish(
        nav,
        timings,
        (optimal, t, final_distance_m),
        config.goal_tolerance_m,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polyline_distances() {
        let path = [
            Point2::new(0.0, 0.0),
            Point2::new(2.0, 0.0),
            Point2::new(2.0, 2.0),
        ];
        let d = |x, y| distance_to_polyline(&Point2::new(x, y), &path).unwrap_or(f64::NAN);
        assert!((d(1.0, 0.3) - 0.3).abs() < 1e-12);
        assert!((d(2.5, 1.0) - 0.5).abs() < 1e-12);
        assert!((d(-1.0, 0.0) - 1.0).abs() < 1e-12);
        assert_eq!(distance_to_polyline(&Point2::origin(), &[]), None);
        assert_eq!(
            distance_to_polyline(&Point2::new(3.0, 4.0), &[Point2::origin()]),
            Some(5.0)
        );
    }
}
