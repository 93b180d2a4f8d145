//! Constant-velocity motion prior for the drone, from its own recent map-matched poses.
//!
//! The drone has no wheels; the simulated drone's odometry is an optical-flow-like increment
//! whose per-scan yaw error exceeds 0.19 rad on 5 % of the scans of the `large` flight (the
//! rotate–translate–rotate noise model gives a sideways step a ±90° first rotation, and its noise
//! grows with it), while a constant-velocity model, which a drone's inertia makes good at 10 Hz,
//! is off by at most 0.0025 rad there. So the pose of a scan is predicted from the velocity over
//! the last `window_s` of matched poses, as MRPT's ICP-SLAM does without odometry, but with the
//! velocity averaged over a window rather than taken from the last step alone (one step's ICP
//! noise is of the order of the step). Velocities are body-frame twists: poses are mapped
//! through the SE(2) logarithm and exponential, so a turn while flying follows an arc.

use nalgebra::{Vector2, Vector3};
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

/// Recent matched poses and the body-frame velocity they imply.
#[derive(Debug, Clone)]
pub struct VelocityTracker {
    window_s: f64,
    history: VecDeque<(f64, Pose2)>,
}

impl VelocityTracker {
    /// A tracker averaging over the last `window_s` seconds; standing still until it has two
    /// poses.
    pub fn new(window_s: f64) -> Self {
        Self {
            window_s,
            history: VecDeque::new(),
        }
    }

    /// Records the pose fixed by a map match at time `t` \[s\]. A time not after the last one
    /// (a log that jumps back) restarts the history.
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
    }

    /// Body-frame twist per second `(vx, vy, ω)` over the window \[m/s, m/s, rad/s\]; zero with
    /// fewer than two poses.
    pub fn twist(&self) -> Vector3<f64> {
        match (self.history.front(), self.history.back()) {
            (Some((t0, p0)), Some((t1, p1))) if t1 > t0 => {
                se2_log(&(p0.inverse() * p1)) / (t1 - t0)
            }
            _ => Vector3::zeros(),
        }
    }

    /// `from` moved on at the current velocity for `dt_s` seconds.
    pub fn predict(&self, from: &Pose2, dt_s: f64) -> Pose2 {
        from * se2_exp(&(self.twist() * dt_s.max(0.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_inverts_exp_and_a_steady_arc_is_predicted_exactly() {
        for xi in [
            Vector3::new(0.3, -0.1, 0.0),
            Vector3::new(0.1, 0.2, 0.4),
            Vector3::new(0.0, 0.0, -2.5),
        ] {
            let back = se2_log(&se2_exp(&xi));
            assert!((back - xi).norm() < 1e-12, "{xi} -> {back}");
        }
        // flying 0.1 m/s sideways while turning at 0.4 rad/s, seen every 0.1 s
        let twist = Vector3::new(0.0, 0.1, 0.4);
        let start = Pose2::new(Vector2::new(1.0, 2.0), 0.3);
        let mut tracker = VelocityTracker::new(1.0);
        for k in 0..15 {
            let t = 0.1 * f64::from(k);
            tracker.observe(t, start * se2_exp(&(twist * t)));
        }
        assert!((tracker.twist() - twist).norm() < 1e-9);
        let at = start * se2_exp(&(twist * 1.4));
        let predicted = tracker.predict(&at, 0.7);
        let truth = start * se2_exp(&(twist * 2.1));
        assert!((predicted.translation.vector - truth.translation.vector).norm() < 1e-9);
        // a restarted log starts a new history: no velocity from one pose
        tracker.observe(0.0, start);
        assert_eq!(tracker.twist(), Vector3::zeros());
    }
}
