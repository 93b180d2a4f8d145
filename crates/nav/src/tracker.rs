//! Carrot-following path tracker for a unicycle robot.
//!
//! The carrot is the furthest path point, going forward from the robot's progress along the
//! path, that still lies within the look-ahead distance (0.5 m) of the robot (pure-pursuit
//! style look-ahead: R. C. Coulter, "Implementation of the pure pursuit path tracking
//! algorithm", CMU-RI-TR-92-01, 1992). The yaw rate is proportional to the heading error towards
//! the carrot, saturated at ±30°/s; the forward speed is highest (0.25 m/s) when the robot
//! faces the carrot and falls linearly to zero at a heading error of `stop_heading_error_rad`,
//! so the robot turns on the spot before driving off sideways. Both commands pass through a
//! first-order low-pass filter with time constant 1/3 s, which keeps the wheels from jerking.
//! Without a pose (localisation lost) the commands are zero at once and the filter is reset.

use crate::error::NavError;
use nalgebra::Point2;
use serde::{Deserialize, Serialize};
use slamkit_core::Pose2;

/// Parameters of the tracker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrackerConfig {
    /// The carrot is the furthest path point within this distance \[m\].
    pub lookahead_m: f64,
    /// Yaw rate per radian of heading error \[1/s\].
    pub heading_gain_per_s: f64,
    /// Saturation of the yaw rate \[rad/s\].
    pub max_yaw_rate_rad_s: f64,
    /// Forward speed when facing the carrot \[m/s\].
    pub max_speed_m_s: f64,
    /// Heading error at which the forward speed reaches zero \[rad\].
    pub stop_heading_error_rad: f64,
    /// Time constant of the first-order smoothing of both commands \[s\].
    pub smoothing_time_s: f64,
    /// The goal is reached within this distance of the path's last point \[m\].
    pub goal_tolerance_m: f64,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            lookahead_m: 0.5,
            heading_gain_per_s: 1.5,
            max_yaw_rate_rad_s: 30f64.to_radians(),
            max_speed_m_s: 0.25,
            stop_heading_error_rad: 60f64.to_radians(),
            smoothing_time_s: 1.0 / 3.0,
            goal_tolerance_m: 0.1,
        }
    }
}

impl TrackerConfig {
    /// Checks every value.
    pub fn validate(&self) -> Result<(), NavError> {
        let positive = [
            self.lookahead_m,
            self.heading_gain_per_s,
            self.max_yaw_rate_rad_s,
            self.max_speed_m_s,
            self.stop_heading_error_rad,
            self.goal_tolerance_m,
        ];
        let ok = positive.iter().all(|v| v.is_finite() && *v > 0.0)
            && self.smoothing_time_s.is_finite()
            && self.smoothing_time_s >= 0.0;
        if ok {
            Ok(())
        } else {
            Err(NavError::InvalidConfig {
                message: "tracker values must be positive and finite (smoothing may be 0)".into(),
            })
        }
    }
}

/// What the tracker is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum TrackerStatus {
    /// Driving along the path.
    Tracking,
    /// Within the goal tolerance of the path's end: commands are zero.
    GoalReached,
    /// No pose: commands are zero.
    LocalisationLost,
    /// No path to follow: commands are zero.
    NoPath,
}

/// One step's output.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TrackerCommand {
    /// Forward speed \[m/s\].
    pub speed_m_s: f64,
    /// Yaw rate, counter-clockwise positive \[rad/s\].
    pub yaw_rate_rad_s: f64,
    /// Status of the tracker.
    pub status: TrackerStatus,
    /// Index of the carrot in the path.
    pub carrot: usize,
}

/// The tracker; see the module documentation.
#[derive(Debug, Clone)]
pub struct PathTracker {
    config: TrackerConfig,
    path: Vec<Point2<f64>>,
    progress: usize,
    speed_m_s: f64,
    yaw_rate_rad_s: f64,
}

impl PathTracker {
    /// A tracker without a path.
    pub fn new(config: TrackerConfig) -> Result<Self, NavError> {
        config.validate()?;
        Ok(Self {
            config,
            path: Vec::new(),
            progress: 0,
            speed_m_s: 0.0,
            yaw_rate_rad_s: 0.0,
        })
    }

    /// Replaces the path (map frame, start first); non-finite points are dropped. The smoothed
    /// commands carry over, so replanning does not jerk the robot.
    pub fn set_path(&mut self, path_m: &[Point2<f64>]) {
        self.path = path_m
            .iter()
            .filter(|p| p.x.is_finite() && p.y.is_finite())
            .copied()
            .collect();
        self.progress = 0;
    }

    /// The path being followed.
    pub fn path(&self) -> &[Point2<f64>] {
        &self.path
    }

    /// One control step of `dt_s` seconds with the robot at `map_from_base` (`None`: lost).
    pub fn step(&mut self, map_from_base: Option<&Pose2>, dt_s: f64) -> TrackerCommand {
        let stop = |tracker: &mut Self, status| {
            tracker.speed_m_s = 0.0;
            tracker.yaw_rate_rad_s = 0.0;
            TrackerCommand {
                speed_m_s: 0.0,
                yaw_rate_rad_s: 0.0,
                status,
                carrot: tracker.progress,
            }
        };
        let Some(pose) = map_from_base.filter(|p| pose_is_finite(p)) else {
            return stop(self, TrackerStatus::LocalisationLost);
        };
        let Some(&goal) = self.path.last() else {
            return stop(self, TrackerStatus::NoPath);
        };
        let position = Point2::from(pose.translation.vector);
        if (goal - position).norm() <= self.config.goal_tolerance_m {
            return stop(self, TrackerStatus::GoalReached);
        }
        let carrot = self.carrot(&position);
        let to_carrot = self.path[carrot] - position;
        let heading_error = wrap_angle(to_carrot.y.atan2(to_carrot.x) - pose.rotation.angle());
        let max_w = self.config.max_yaw_rate_rad_s;
        let yaw_rate = (self.config.heading_gain_per_s * heading_error).clamp(-max_w, max_w);
        let facing = (1.0 - heading_error.abs() / self.config.stop_heading_error_rad).max(0.0);
        let speed = self.config.max_speed_m_s * facing;
        let dt = if dt_s.is_finite() { dt_s.max(0.0) } else { 0.0 };
        let alpha = if self.config.smoothing_time_s > 0.0 {
            1.0 - (-dt / self.config.smoothing_time_s).exp()
        } else {
            1.0
        };
        self.speed_m_s += alpha * (speed - self.speed_m_s);
        self.yaw_rate_rad_s += alpha * (yaw_rate - self.yaw_rate_rad_s);
        TrackerCommand {
            speed_m_s: self.speed_m_s,
            yaw_rate_rad_s: self.yaw_rate_rad_s,
            status: TrackerStatus::Tracking,
            carrot,
        }
    }

    /// Advances the progress index to the path point nearest the robot (searching forward only,
    /// within one look-ahead of path length) and returns the furthest point within the
    /// look-ahead from there on, or the nearest point when none is that close.
    fn carrot(&mut self, position: &Point2<f64>) -> usize {
        let lookahead = self.config.lookahead_m;
        let mut best = (self.progress, f64::INFINITY);
        let mut walked = 0.0;
        for i in self.progress..self.path.len() {
            if i > self.progress {
                walked += (self.path[i] - self.path[i - 1]).norm();
            }
            let d = (self.path[i] - position).norm();
            if d < best.1 {
                best = (i, d);
            }
            if walked > best.1 + lookahead {
                break;
            }
        }
        self.progress = best.0;
        let mut carrot = best.0;
        for i in best.0..self.path.len() {
            if (self.path[i] - position).norm() > lookahead {
                break;
            }
            carrot = i;
        }
        carrot
    }
}

fn pose_is_finite(pose: &Pose2) -> bool {
    let t = pose.translation.vector;
    t.x.is_finite() && t.y.is_finite() && pose.rotation.angle().is_finite()
}

/// Wraps an angle to (−π, π].
fn wrap_angle(a: f64) -> f64 {
    let wrapped = a.rem_euclid(std::f64::consts::TAU);
    if wrapped > std::f64::consts::PI {
        wrapped - std::f64::consts::TAU
    } else {
        wrapped
    }
}

#[cfg(test)]
#[path = "tracker_tests.rs"]
mod tests;
