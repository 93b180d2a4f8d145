//! Constant-velocity motion prior for the drone, from its own recent map-matched poses.
//!
//! The drone has no wheels; the simulated drone's odometry is an optical-flow-like increment
//! whose per-scan yaw error exceeds 0.19 rad on 5 % of the scans of the `large` flight (the
//! rotate–translate–rotate noise model gives a sideways step a ±90° first rotation, and its noise
//! grows with it), while a constant-velocity model, which a drone's inertia makes good at 10 Hz,
//! is off by at most 0.0025 rad there. So the pose of a scan is predicted from the velocity over
//! the last `window_s` of matched poses, as MRPT's ICP-SLAM does without odometry, but with the
//! velocity averaged over a window rather than taken from the last step alone (one step's ICP
//! noise is of the order of the step).
//!
//! A drone's velocity is inertial: when it yaws while flying, it keeps flying the same way in
//! the room, and its velocity turns the other way in its own frame. (A car's, or a constant
//! twist's, turns with it and follows an arc; modelled so, the `office` drone, turning 0.8 rad
//! while flying diagonally, was predicted off its path at every turn, and only a quick pull
//! towards the optical flow, with all its noise, brought the prior back.) So the velocity is
//! the world-frame displacement over the window expressed in the latest pose's frame, and a
//! step moves by it and then turns it back by the step's turn.
//!
//! A multirotor accelerates by tilting its thrust: a pitch `θ` and roll `φ` mean a horizontal
//! acceleration `g·tan θ` forward and `−g·tan φ` to the left (Mahony, Kumar and Corke,
//! "Multirotor aerial vehicles", IEEE RAM 19(3), 2012). The tracker integrates that acceleration
//! between matches, which carries the velocity through the take-offs and stops whose scans are
//! not matched (they are the tilted ones), and brings the window's mean velocity up to the
//! current one with the acceleration of every scan in the window, matched or not. (Corrected
//! with the current acceleration alone, the first match after a tilted start set the velocity
//! to the window's mean, half the speed reached: `office` seed 12 flew its last leg, along one
//! wall, at 0.1 m/s with a prior of 0.055–0.07 m/s for 25 s, and ended 2 m off.)
//!
//! The heading is the weak part of that prior: a drone turning in front of one wall or a pillar
//! gives scans that do not pin its heading, and a velocity from the poses of such scans carries
//! their heading error on. When the drone's IMU gives its heading integrated from the yaw-rate
//! gyro, the heading change between scans is taken from it instead (its error grows by a few
//! hundredths of a degree per second, against tenths of a radian of ICP heading drift in the
//! `office` flight); the translation stays the constant-velocity one.
//!
//! Nothing in the matched poses observes the velocity along a direction the scans do not pin
//! (a corridor seen by one wall), so a velocity error there, once in, stays. A downward
//! optical-flow sensor measures the body-frame velocity with white noise (about 2 cm per
//! 0.1 s at 1.5 m height, 0.25 m/s per reading); [`VelocityTracker::blend_measured`] pulls
//! the velocity towards it with a time constant of several seconds, so that its noise is
//! averaged over the drone's inertia (which the tilt's acceleration carries through the
//! changes of speed) and its mean bounds the drift.

use nalgebra::{Rotation2, Vector2, Vector3};
/// Standard gravity \[m/s²\].
const GRAVITY_MPS2: f64 = 9.80665;
use slamkit_core::Pose2;
use std::collections::VecDeque;

/// Twist `(vx, vy, ω)` whose exponential is `pose` (SE(2) logarithm) \[m, m, rad\].
pub fn se2_log(pose: &Pose2) -> Vector3<f64> {
    let theta = pose.rotation.angle();
    let t = pose.translation.vector;
    let (a, b) = v_coefficients(theta);
    // V = [[a, -b], [b, a]]; V⁻¹ = [[a, b], [-b, a]] / (a² + b²)
    let det = a * a + b * b;
    Vector3::new((a * t.x + b * t.y) / det, (-b * t.x + a * t.y) / det, theta)
}

/// The pose reached by following the twist `xi = (vx, vy, ω)` for unit time (SE(2)
/// exponential).
pub fn se2_exp(xi: &Vector3<f64>) -> Pose2 {
    let (a, b) = v_coefficients(xi.z);
    Pose2::new(Vector2::new(a * xi.x - b * xi.y, b * xi.x + a * xi.y), xi.z)
}

/// `(sin θ / θ, (1 − cos θ) / θ)`, with their limits at θ = 0.
fn v_coefficients(theta: f64) -> (f64, f64) {
    if theta.abs() < 1e-6 {
        (1.0 - theta * theta / 6.0, theta / 2.0)
    } else {
        (theta.sin() / theta, (1.0 - theta.cos()) / theta)
    }
}

/// Horizontal body-frame acceleration `(forward, left)` of a multirotor flying level at roll
/// `roll_rad` and pitch `pitch_rad` \[m/s²\].
pub fn tilt_acceleration(roll_rad: f64, pitch_rad: f64) -> Vector2<f64> {
    Vector2::new(pitch_rad.tan(), -roll_rad.tan()) * GRAVITY_MPS2
}

/// Recent matched poses and the body-frame velocity they imply.
#[derive(Debug, Clone)]
pub struct VelocityTracker {
    window_s: f64,
    max_speed_mps: f64,
    history: VecDeque<(f64, Pose2)>,
    /// The acceleration the tilt showed at each scan, world frame: `(time, acceleration)`, over
    /// the interval that ends at that time \[s, m/s²\].
    accelerations: VecDeque<(f64, Vector2<f64>)>,
    /// Current twist `(vx, vy, ω)` \[m/s, m/s, rad/s\].
    velocity: Vector3<f64>,
}

impl VelocityTracker {
    /// A tracker averaging over the last `window_s` seconds, whose horizontal speed is at most
    /// `max_speed_mps` (the drone's top speed: matches that slid along a direction the scans
    /// do not pin cannot run the prior away); standing still until it has two poses.
    pub fn new(window_s: f64, max_speed_mps: f64) -> Self {
        Self {
            window_s,
            max_speed_mps,
            history: VecDeque::new(),
            accelerations: VecDeque::new(),
            velocity: Vector3::zeros(),
        }
    }

    /// Records the acceleration `accel_world` (world frame, \[m/s²\]) the tilt showed over the
    /// interval ending at time `t` \[s\], matched or not: the accelerations of the scans not
    /// matched (the tilted ones, while the drone speeds up) are what [`Self::observe`] needs
    /// to bring the window's mean velocity up to the current one.
    pub fn record_acceleration(&mut self, t: f64, accel_world: Vector2<f64>) {
        if self
            .accelerations
            .back()
            .is_some_and(|(last, _)| t <= *last)
        {
            self.accelerations.clear();
        }
        self.accelerations.push_back((t, accel_world));
        while self
            .accelerations
            .front()
            .is_some_and(|(first, _)| t - first > 2.0 * self.window_s)
        {
            self.accelerations.pop_front();
        }
    }

    /// How far the velocity at `t1` is above its mean over `[t0, t1]`, world frame:
    /// `(1/T) ∫ a(s) (s − t0) ds` over the recorded accelerations.
    fn window_lag(&self, t0: f64, t1: f64) -> Vector2<f64> {
        let mut sum = Vector2::zeros();
        let mut previous: Option<f64> = None;
        for (t, a) in &self.accelerations {
            if let Some(start) = previous {
                let (lo, hi) = (start.max(t0), t.min(t1));
                if hi > lo {
                    sum += a * ((lo + hi) / 2.0 - t0) * (hi - lo);
                }
            }
            previous = Some(*t);
        }
        sum / (t1 - t0)
    }

    /// Records the pose fixed by a map match at time `t` \[s\]; the velocity becomes the
    /// window's mean brought up to `t` by the accelerations recorded in it. A time not after
    /// the last one (a log that jumps back) restarts the history.
    pub fn observe(&mut self, t: f64, pose: Pose2) {
        if self.history.back().is_some_and(|(last, _)| t <= *last) {
            self.history.clear();
        }
        self.history.push_back((t, pose));
        while self
            .history
            .get(1)
            .is_some_and(|(second, _)| t - second >= self.window_s)
        {
            self.history.pop_front();
        }
        if let (Some((t0, p0)), Some((t1, p1))) = (self.history.front(), self.history.back()) {
            let span = t1 - t0;
            if span > 0.0 {
                let lag = p1.rotation.inverse() * self.window_lag(*t0, *t1);
                let moved = p1.rotation.inverse() * (p1.translation.vector - p0.translation.vector);
                let turned = (p0.rotation.inverse() * p1.rotation).angle();
                let v = Vector3::new(
                    moved.x / span + lag.x,
                    moved.y / span + lag.y,
                    turned / span,
                );
                let speed = v.xy().norm();
                let scale = if speed > self.max_speed_mps {
                    self.max_speed_mps / speed
                } else {
                    1.0
                };
                self.velocity = Vector3::new(v.x * scale, v.y * scale, v.z);
            }
        }
    }

    /// Moves every recorded pose: `moved(t, pose)` is the new pose of the one of time `t` (after
    /// a re-localisation). The body-frame velocity is unchanged.
    pub fn relocate(&mut self, moved: impl Fn(f64, &Pose2) -> Pose2) {
        for (t, pose) in &mut self.history {
            *pose = moved(*t, pose);
        }
    }

    /// Current body-frame twist `(vx, vy, ω)` \[m/s, m/s, rad/s\]; zero before two poses.
    pub fn twist(&self) -> Vector3<f64> {
        self.velocity
    }

    /// `from` moved on for `dt_s` seconds at the current velocity, accelerating by `accel`
    /// (body frame, \[m/s²\]), turning by `turn_rad` (the gyro's heading change) instead of
    /// the velocity's when given; the velocity becomes the one at the end.
    pub fn advance(
        &mut self,
        from: &Pose2,
        dt_s: f64,
        accel: &Vector2<f64>,
        turn_rad: Option<f64>,
    ) -> Pose2 {
        let dt = dt_s.max(0.0);
        let turn = turn_rad
            .filter(|t| t.is_finite())
            .unwrap_or(self.velocity.z * dt);
        // the acceleration over the step, in `from`'s frame, at the mid heading
        let dv = Rotation2::new(turn / 2.0) * (accel * dt);
        let v = self.velocity.xy();
        let step = (v + dv / 2.0) * dt;
        let end = Rotation2::new(-turn) * (v + dv);
        self.velocity = Vector3::new(end.x, end.y, self.velocity.z);
        from * Pose2::new(step, turn)
    }

    /// Pulls the current horizontal velocity towards a measured body-frame one
    /// (`velocity_mps`, an optical-flow sensor's mean over the last `dt_s` seconds), as a
    /// first-order filter with time constant `time_constant_s`: the drone's inertia keeps the
    /// flow's white noise out of a single scan's prior, the flow keeps the velocity from
    /// drifting in the directions the scans do not observe.
    pub fn blend_measured(&mut self, velocity_mps: &Vector2<f64>, dt_s: f64, time_constant_s: f64) {
        let k = if time_constant_s > 0.0 {
            (dt_s.max(0.0) / time_constant_s).min(1.0)
        } else {
            1.0
        };
        self.velocity.x += k * (velocity_mps.x - self.velocity.x);
        self.velocity.y += k * (velocity_mps.y - self.velocity.y);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_inverts_exp_and_a_drone_yawing_on_a_straight_path_is_predicted_exactly() {
        for xi in [
            Vector3::new(0.3, -0.1, 0.0),
            Vector3::new(0.1, 0.2, 0.4),
            Vector3::new(0.0, 0.0, -2.5),
        ] {
            let back = se2_log(&se2_exp(&xi));
            assert!((back - xi).norm() < 1e-12, "{xi} -> {back}");
        }
        // flying 0.1 m/s along the room's y while yawing at 0.4 rad/s, seen every 0.1 s
        let (start, heading) = (Vector2::new(1.0, 2.0), 0.3);
        let pose = |t: f64| Pose2::new(start + Vector2::new(0.0, 0.1) * t, heading + 0.4 * t);
        let mut tracker = VelocityTracker::new(1.0, 1.0);
        let level = Vector2::<f64>::zeros();
        for k in 0..15 {
            tracker.observe(0.1 * f64::from(k), pose(0.1 * f64::from(k)));
        }
        // in the body frame the velocity has turned against the yaw
        let body = Rotation2::new(-(heading + 0.4 * 1.4)) * Vector2::new(0.0, 0.1);
        let twist = tracker.twist();
        assert!((twist.xy() - body).norm() < 1e-9 && (twist.z - 0.4).abs() < 1e-9);
        let at = pose(1.4);
        let predicted = tracker.advance(&at, 0.7, &level, None);
        let truth = pose(2.1);
        assert!((predicted.translation.vector - truth.translation.vector).norm() < 1e-9);
        assert!((predicted.rotation.angle() - truth.rotation.angle()).abs() < 1e-9);
        // and on: the velocity turned back by the step's turn
        let next = tracker.advance(&predicted, 0.7, &level, None);
        assert!((next.translation.vector - pose(2.8).translation.vector).norm() < 1e-9);
        // with the gyro's turn the path is the same, only the heading is the gyro's
        let gyro = tracker.clone().advance(&next, 0.7, &level, Some(-0.1));
        assert!((gyro.translation.vector - pose(3.5).translation.vector).norm() < 1e-9);
        let turned = (next.inverse() * gyro).rotation.angle();
        assert!((turned + 0.1).abs() < 1e-12, "{turned}");
        // a restarted log starts a new history: no velocity from one pose
        let mut restarted = VelocityTracker::new(1.0, 1.0);
        restarted.observe(0.0, pose(0.0));
        assert_eq!(restarted.twist(), Vector3::zeros());
        // a jump of 1 m in 0.5 s is capped at the top speed, the turn rate kept
        let from = pose(0.0);
        restarted.observe(0.0, from);
        restarted.observe(0.5, from * Pose2::new(Vector2::new(1.0, 0.0), 0.1));
        let capped = restarted.twist();
        assert!((capped.xy().norm() - 1.0).abs() < 1e-12 && (capped.z - 0.2).abs() < 1e-12);
    }

    #[test]
    fn a_match_after_unmatched_acceleration_keeps_the_speed_reached() {
        // at rest, matched every 0.1 s for 1 s; then 0.1 m/s² forward for 0.5 s (tilted
        // scans, not matched), then 0.5 s at the 0.05 m/s reached, and a match at t = 2 s
        let mut tracker = VelocityTracker::new(1.0, 1.0);
        let x = |t: f64| match t {
            t if t <= 1.0 => 0.0,
            t if t <= 1.5 => 0.05 * (t - 1.0).powi(2),
            t => 0.0125 + 0.05 * (t - 1.5),
        };
        for k in 0..=20 {
            let t = 0.1 * f64::from(k);
            let accel = if t > 1.0 + 1e-9 && t <= 1.5 + 1e-9 {
                0.1
            } else {
                0.0
            };
            tracker.record_acceleration(t, Vector2::new(accel, 0.0));
            if k <= 10 || k == 20 {
                tracker.observe(t, Pose2::new(Vector2::new(x(t), 0.0), 0.0));
            }
        }
        // the window's mean is 0.0375 m/s; the speed at its end 0.05 m/s
        assert!(
            (tracker.twist().x - 0.05).abs() < 1e-9,
            "{}",
            tracker.twist()
        );
    }

    #[test]
    fn tilt_carries_the_velocity_through_a_stop() {
        // flying forward at 0.1 m/s, then braking at 0.1 m/s² (nose up) for one second
        let mut tracker = VelocityTracker::new(1.0, 1.0);
        for k in 0..11 {
            let t = 0.1 * f64::from(k);
            tracker.observe(t, Pose2::new(Vector2::new(0.1 * t, 0.0), 0.0));
        }
        let pitch = (-0.1 / GRAVITY_MPS2).atan();
        let brake = tilt_acceleration(0.0, pitch);
        assert!((brake - Vector2::new(-0.1, 0.0)).norm() < 1e-12);
        let mut pose = Pose2::new(Vector2::new(0.1, 0.0), 0.0);
        for _ in 0..10 {
            pose = tracker.advance(&pose, 0.1, &brake, None);
        }
        // 0.1 m/s for 1 s minus half of 0.1 m/s² · 1 s²: 0.05 m further, standing still
        assert!((pose.translation.x - 0.15).abs() < 1e-9, "{pose}");
        assert!(tracker.twist().norm() < 1e-12);
        // a roll to the right (positive) accelerates to the right (negative y)
        assert!(tilt_acceleration(0.01, 0.0).y < 0.0);
    }
}
