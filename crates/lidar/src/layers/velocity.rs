//! Constant-velocity motion prior for the drone: a Kalman filter over its velocity.
//!
//! The drone has no wheels; the simulated drone's odometry is an optical-flow-like increment
//! whose per-scan yaw error exceeds 0.19 rad on 5 % of the scans of the `large` flight (the
//! rotate–translate–rotate noise model gives a sideways step a ±90° first rotation, and its noise
//! grows with it), while a constant-velocity model, which a drone's inertia makes good at 10 Hz,
//! is off by at most 0.0025 rad there. So the pose of a scan is predicted from the drone's
//! velocity, as MRPT's ICP-SLAM does without odometry, but with the velocity estimated from
//! every match rather than taken from the last step alone (one step's ICP noise is of the order
//! of the step).
//!
//! A drone's velocity is inertial: when it yaws while flying, it keeps flying the same way in
//! the room, and its velocity turns the other way in its own frame. (A car's, or a constant
//! twist's, turns with it and follows an arc; modelled so, the `office` drone, turning 0.8 rad
//! while flying diagonally, was predicted off its path at every turn.) So a step moves by the
//! body-frame velocity and then turns it back by the step's turn.
//!
//! A multirotor accelerates by tilting its thrust: a pitch `θ` and roll `φ` mean a horizontal
//! acceleration `g·tan θ` forward and `−g·tan φ` to the left (Mahony, Kumar and Corke,
//! "Multirotor aerial vehicles", IEEE RAM 19(3), 2012). The tracker integrates that acceleration,
//! which carries the velocity through the take-offs and stops whose scans are not matched (they
//! are the tilted ones).
//!
//! The heading is the weak part of a prior from matched poses: a drone turning in front of one
//! wall or a pillar gives scans that do not pin its heading. When the drone's IMU gives its
//! heading integrated from the yaw-rate gyro, the heading change between scans is taken from it
//! instead (its error grows by a few hundredths of a degree per second, against tenths of a
//! radian of ICP heading drift in the `office` flight).
//!
//! Nothing in the matched poses observes the velocity along a direction the scans do not pin
//! (a corridor seen by one wall). So the horizontal velocity is a Kalman filter's, over the
//! position error and the velocity (body frame): the tilt's acceleration drives it (its error,
//! the attitude's noise, is the process noise, with a position random walk for what the
//! constant-velocity model misses); a downward optical-flow sensor's readings measure the
//! velocity (white noise, 0.25 m/s per reading at 1.5 m height); and each accepted match
//! measures the position along the directions its scan pins, with the variance its information
//! gives ([`VelocityTracker::position_update`]). A weakly pinned step then moves the velocity by
//! the filter's gain rather than by the step over a window: the 1 s window mean it replaced
//! turned one such 0.06 m step into 0.06–0.08 m/s, which along the next, unpinned, stretch
//! nothing took out again (`office` seeds 10 and 11: 2.7 and 1.9 m off over the last leg).
//! The turn rate, used without a gyro, is still the mean over the last `window_s` of matched
//! headings.

use super::kalman::scalar_update;
use nalgebra::{Matrix2, Matrix2x4, Matrix3, Matrix4, Rotation2, Vector2, Vector3, Vector4};
use serde::{Deserialize, Serialize};
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

/// Noise of the velocity filter's inputs ([`VelocityTracker`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VelocityNoise {
    /// Density of the tilt acceleration's white error \[m/s²/√Hz\]: the attitude's 0.05° of
    /// noise per reading at 10 Hz is 0.0027.
    pub accel_density: f64,
    /// ... plus this fraction of the acceleration, for the model's error while accelerating.
    pub accel_relative: f64,
    /// Density of a position random walk \[m/√s\]: what a constant velocity between scans misses.
    pub position_walk: f64,
    /// Standard deviation of one optical-flow velocity reading \[m/s\]. The sensor's is its
    /// angular rate's (0.15 rad/s) times the distance to the floor, 0.06 m/s at 0.4 m and
    /// 0.3 m/s at 2 m; modelled so, `office` seeds 1–20 gave an ICP median of 0.188 m against
    /// 0.175 m with the 1.5 m value for every height (BENCHMARKS.md, "Velocity from a Kalman
    /// filter").
    pub flow_sigma_mps: f64,
}

impl Default for VelocityNoise {
    /// Measured on `office` seeds 1–20 at commit 5efc158 (BENCHMARKS.md, "Velocity from a
    /// Kalman filter"), ICP median of the mean errors: 0.175 m as set; `position_walk` 0.01
    /// 0.206 m, 0.001 0.187 m; `accel_density` 0.006 0.226 m. Without the innovation gate,
    /// `accel_relative` 0.1 gave 0.209 m against 0.236 m at 0.3 (`accel_density` 0.006) and
    /// 0.212 m at 0.05 (0.0015), and `position_walk` 0.03 0.251 m.
    fn default() -> Self {
        Self {
            accel_density: 0.003,
            accel_relative: 0.1,
            position_walk: 0.003,
            flow_sigma_mps: 0.25,
        }
    }
}

impl VelocityNoise {
    /// Each field with whether it is in range: finite and non-negative, the flow's positive.
    pub(crate) fn field_checks(&self) -> [(&'static str, f64, bool); 4] {
        let non_negative = |field, value: f64| (field, value, value >= 0.0);
        [
            non_negative("velocity.accel_density", self.accel_density),
            non_negative("velocity.accel_relative", self.accel_relative),
            non_negative("velocity.position_walk", self.position_walk),
            (
                "velocity.flow_sigma_mps",
                self.flow_sigma_mps,
                self.flow_sigma_mps > 0.0,
            ),
        ]
    }
}

/// The drone's velocity: a Kalman filter over the position error and the horizontal velocity
/// in the body frame of the latest pose, and the turn rate of the recent matched headings.
#[derive(Debug, Clone)]
pub struct VelocityTracker {
    noise: VelocityNoise,
    window_s: f64,
    /// Matched poses of the last `window_s`, for the turn rate.
    history: VecDeque<(f64, Pose2)>,
    /// Current twist `(vx, vy, ω)` \[m/s, m/s, rad/s\].
    velocity: Vector3<f64>,
    /// Covariance of `(δx, δy, vx, vy)`, body frame.
    covariance: Matrix4<f64>,
    /// Position correction from the flow's readings (body frame), added to the next step.
    pending: Vector2<f64>,
}

/// A filter update worked out for one match, applied with [`VelocityTracker::apply`] only if
/// the match is the one kept.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionUpdate {
    /// Correction of the predicted position, body frame \[m\].
    pub translation: Vector2<f64>,
    velocity: Vector2<f64>,
    covariance: Matrix4<f64>,
}

impl VelocityTracker {
    /// A drone standing still where it is known to be, whose turn rate is the mean over the
    /// last `window_s` seconds of matched headings.
    pub fn new(noise: VelocityNoise, window_s: f64) -> Self {
        Self {
            noise,
            window_s,
            history: VecDeque::new(),
            velocity: Vector3::zeros(),
            covariance: Matrix4::zeros(),
            pending: Vector2::zeros(),
        }
    }

    /// Records the pose fixed by a map match at time `t` \[s\]; the turn rate becomes the
    /// window's mean. A time not after the last one (a log that jumps back) restarts the
    /// history.
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
            if t1 > t0 {
                self.velocity.z = (p0.rotation.inverse() * p1.rotation).angle() / (t1 - t0);
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

    /// Current body-frame twist `(vx, vy, ω)` \[m/s, m/s, rad/s\].
    pub fn twist(&self) -> Vector3<f64> {
        self.velocity
    }

    /// `from` moved on for `dt_s` seconds at the current velocity, accelerating by `accel`
    /// (body frame, \[m/s²\]), turning by `turn_rad` (the gyro's heading change) instead of
    /// the turn rate's when given; the velocity becomes the one at the end, and the
    /// covariance grows by the acceleration's error over the step.
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
        let step = (v + dv / 2.0) * dt + std::mem::take(&mut self.pending);
        let end = Rotation2::new(-turn) * (v + dv);
        self.velocity = Vector3::new(end.x, end.y, self.velocity.z);
        self.propagate(dt, accel.norm(), turn);
        from * Pose2::new(step, turn)
    }

    /// The covariance carried over a step of `dt` seconds with acceleration `accel` (its size
    /// \[m/s²\]) and into the frame turned by `turn` \[rad\].
    fn propagate(&mut self, dt: f64, accel: f64, turn: f64) {
        let n = &self.noise;
        let qa = n.accel_density.powi(2) + (n.accel_relative * accel).powi(2);
        let mut f = Matrix4::identity();
        let mut q = Matrix4::zeros();
        for i in 0..2 {
            f[(i, i + 2)] = dt;
            q[(i, i)] = qa * dt.powi(3) / 3.0 + n.position_walk.powi(2) * dt;
            q[(i, i + 2)] = qa * dt * dt / 2.0;
            q[(i + 2, i)] = qa * dt * dt / 2.0;
            q[(i + 2, i + 2)] = qa * dt;
        }
        let r = Rotation2::new(-turn).into_inner();
        let mut rotate = Matrix4::zeros();
        rotate.fixed_view_mut::<2, 2>(0, 0).copy_from(&r);
        rotate.fixed_view_mut::<2, 2>(2, 2).copy_from(&r);
        self.covariance = rotate * (f * self.covariance * f.transpose() + q) * rotate.transpose();
    }

    /// The prediction came from the scans' odometry, whose error the filter does not model:
    /// the position is taken as unknown (uncorrelated with the velocity), so that the next
    /// match is kept whole along the directions it pins, and the flow's pending position
    /// correction is dropped (the odometry moved the pose, not this filter).
    pub fn unknown_position(&mut self) {
        const UNKNOWN_M2: f64 = 1e6;
        self.pending = Vector2::zeros();
        for i in 0..2 {
            for j in 0..4 {
                self.covariance[(i, j)] = 0.0;
                self.covariance[(j, i)] = 0.0;
            }
            self.covariance[(i, i)] = UNKNOWN_M2;
        }
    }

    /// The drone is where it is known to be but its velocity is not known (found mid-flight
    /// in a saved map): zero, with a standard deviation of `sigma_mps` on each axis, so that
    /// the first flow readings and matches set it.
    pub fn unknown_velocity(&mut self, sigma_mps: f64) {
        self.velocity = Vector3::zeros();
        self.covariance = Matrix4::zeros();
        self.covariance[(2, 2)] = sigma_mps.powi(2);
        self.covariance[(3, 3)] = sigma_mps.powi(2);
        self.pending = Vector2::zeros();
        self.history.clear();
    }

    /// Updates the velocity with an optical-flow reading (`velocity_mps`, body frame, the mean
    /// since the last scan); the position correction it implies goes into the next step.
    pub fn measure_flow(&mut self, velocity_mps: &Vector2<f64>) {
        let p = self.covariance;
        let s =
            p.fixed_view::<2, 2>(2, 2) + Matrix2::identity() * self.noise.flow_sigma_mps.powi(2);
        let Some(inverse) = s.try_inverse() else {
            return;
        };
        let gain = p.fixed_view::<4, 2>(0, 2) * inverse;
        let correction = gain * (velocity_mps - self.velocity.xy());
        self.pending += correction.xy();
        self.velocity.x += correction.z;
        self.velocity.y += correction.w;
        let mut h = Matrix2x4::zeros();
        h[(0, 2)] = 1.0;
        h[(1, 3)] = 1.0;
        self.covariance = (Matrix4::identity() - gain * h) * p;
    }

    /// The update for a match whose position correction of the prediction is `t` (body frame),
    /// measured along each eigendirection of the translation block of the scan's `information`
    /// with an eigenvalue λ of at least `min_eigenvalue`, with variance `sigma_m² / λ`; not
    /// along the others (nothing pins them). `None` when a correction is further than
    /// `max_sigmas` standard deviations of the prediction and the scan together: a false match,
    /// as a scan snapping to the next of a row of desk legs 0.3 m apart.
    pub fn position_update(
        &self,
        t: &Vector2<f64>,
        information: &Matrix3<f64>,
        min_eigenvalue: f64,
        sigma_m: f64,
        max_sigmas: f64,
    ) -> Option<PositionUpdate> {
        let eigen = information
            .fixed_view::<2, 2>(0, 0)
            .into_owned()
            .symmetric_eigen();
        let mut x = Vector4::zeros();
        let mut p = self.covariance;
        for (lambda, u) in eigen
            .eigenvalues
            .iter()
            .zip(eigen.eigenvectors.column_iter())
        {
            if *lambda < min_eigenvalue || *lambda <= 0.0 {
                continue;
            }
            let h = Vector4::new(u.x, u.y, 0.0, 0.0);
            let innovation = u.dot(t) - h.dot(&x);
            let (correction, after) =
                scalar_update(&p, &h, innovation, sigma_m * sigma_m / lambda, max_sigmas)?;
            x += correction;
            p = after;
        }
        Some(PositionUpdate {
            translation: x.xy(),
            velocity: self.velocity.xy() + Vector2::new(x.z, x.w),
            covariance: p,
        })
    }

    /// Takes the update of the match that was kept: the position error is reset to zero (the
    /// pose carries the correction), the velocity and covariance are the update's.
    pub fn apply(&mut self, update: &PositionUpdate) {
        self.velocity.x = update.velocity.x;
        self.velocity.y = update.velocity.y;
        self.covariance = update.covariance;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Information of a scan pinning the position in every direction (with the heading).
    fn pinned() -> Matrix3<f64> {
        Matrix3::identity() * 500.0
    }

    /// A tracker that has followed a drone speeding up from rest to `velocity` (body frame,
    /// heading 0) in the first second, its tilt showing the acceleration, and flying on level
    /// for 19 s, matched every 0.1 s by fully pinned scans; and the drone's pose then.
    fn flying(velocity: Vector2<f64>) -> (VelocityTracker, Pose2) {
        let mut tracker = VelocityTracker::new(VelocityNoise::default(), 1.0);
        let mut pose = Pose2::identity();
        for k in 1..=200 {
            let t = 0.1 * f64::from(k);
            let (accel, at) = if t <= 1.0 + 1e-9 {
                (velocity, velocity * (t * t / 2.0))
            } else {
                (Vector2::zeros(), velocity * (t - 0.5))
            };
            let predicted = tracker.advance(&pose, 0.1, &accel, Some(0.0));
            let t = (predicted.inverse() * Pose2::new(at, 0.0))
                .translation
                .vector;
            let update = tracker
                .position_update(&t, &pinned(), 5.0, 0.05, 3.0)
                .unwrap();
            tracker.apply(&update);
            pose = predicted * Pose2::new(update.translation, 0.0);
        }
        (tracker, pose)
    }

    #[test]
    fn log_inverts_exp_and_the_turn_rate_is_the_matched_headings() {
        for xi in [
            Vector3::new(0.3, -0.1, 0.0),
            Vector3::new(0.1, 0.2, 0.4),
            Vector3::new(0.0, 0.0, -2.5),
        ] {
            let back = se2_log(&se2_exp(&xi));
            assert!((back - xi).norm() < 1e-12, "{xi} -> {back}");
        }
        // yawing at 0.4 rad/s, seen every 0.1 s
        let pose = |t: f64| Pose2::new(Vector2::new(1.0, 2.0), 0.3 + 0.4 * t);
        let mut tracker = VelocityTracker::new(VelocityNoise::default(), 1.0);
        for k in 0..15 {
            tracker.observe(0.1 * f64::from(k), pose(0.1 * f64::from(k)));
        }
        assert!((tracker.twist().z - 0.4).abs() < 1e-9);
        // without a gyro the prediction turns at that rate; with one, by the gyro's turn
        let level = Vector2::zeros();
        let turned = tracker.clone().advance(&pose(1.4), 0.5, &level, None);
        assert!((turned.rotation.angle() - pose(1.9).rotation.angle()).abs() < 1e-9);
        let gyro = tracker.advance(&pose(1.4), 0.5, &level, Some(-0.1));
        assert!(((pose(1.4).inverse() * gyro).rotation.angle() + 0.1).abs() < 1e-12);
        // a restarted log starts a new history: no turn rate from one pose
        let mut restarted = VelocityTracker::new(VelocityNoise::default(), 1.0);
        restarted.observe(0.0, pose(0.0));
        assert_eq!(restarted.twist(), Vector3::zeros());
    }

    #[test]
    fn pinned_matches_teach_the_velocity_and_a_drone_yawing_on_a_straight_path_is_predicted() {
        let (mut tracker, pose) = flying(Vector2::new(0.1, 0.02));
        let twist = tracker.twist();
        assert!(
            (twist.xy() - Vector2::new(0.1, 0.02)).norm() < 1e-3,
            "{twist}"
        );
        assert!(
            (pose.translation.vector - Vector2::new(1.95, 0.39)).norm() < 1e-3,
            "{pose}"
        );
        // yawing by 0.5 rad over the next second, the drone flies on the same way in the
        // room: its body-frame velocity turns back by the step's turn
        let level = Vector2::zeros();
        let mut p = pose;
        for _ in 0..10 {
            p = tracker.advance(&p, 0.1, &level, Some(0.05));
        }
        let expected = pose.translation.vector + Vector2::new(0.1, 0.02);
        assert!((p.translation.vector - expected).norm() < 1e-3, "{p}");
        let body = Rotation2::new(-0.5) * Vector2::new(0.1, 0.02);
        assert!((tracker.twist().xy() - body).norm() < 1e-3);
    }

    #[test]
    fn a_weakly_pinned_step_moves_the_velocity_by_the_filters_gain_and_a_far_one_is_dropped() {
        let (mut tracker, pose) = flying(Vector2::new(0.1, 0.0));
        tracker.advance(&pose, 0.1, &Vector2::zeros(), Some(0.0));
        // one scan pins y weakly (eigenvalue 10: σ 0.016 m, x not at all) and moves it 0.04 m
        let weak = Matrix3::from_diagonal(&Vector3::new(0.0, 10.0, 100.0));
        let update = tracker
            .position_update(&Vector2::new(0.2, 0.04), &weak, 5.0, 0.05, 3.0)
            .unwrap();
        assert_eq!(update.translation.x, 0.0, "x is not pinned");
        assert!(update.translation.y > 0.0 && update.translation.y < 0.04);
        tracker.apply(&update);
        // a 1 s window of matched poses would have turned this step into 0.04 m/s
        let v = tracker.twist();
        assert!(v.y.abs() < 0.01 && (v.x - 0.1).abs() < 1e-3, "{v}");
        // 0.1 m is more than three standard deviations of the prediction and the scan together
        let far = tracker.position_update(&Vector2::new(0.0, 0.1), &weak, 5.0, 0.05, 3.0);
        assert!(far.is_none());
        // nothing pins anything: no correction, the velocity unchanged
        let none = tracker
            .position_update(&Vector2::new(0.2, 0.06), &Matrix3::zeros(), 5.0, 0.05, 3.0)
            .unwrap();
        assert_eq!(none.translation, Vector2::zeros());
        assert_eq!(none.velocity, v.xy());
    }

    #[test]
    fn the_flow_takes_out_a_velocity_error_no_scan_sees() {
        // the filter holds 0.1 m/s forward, the drone flies at 0.15 m/s (a speed-up the tilt
        // under-read) with no scan pinning anything; the flow reads it with ±0.25 m/s of noise
        let (mut tracker, start) = flying(Vector2::new(0.1, 0.0));
        let level = Vector2::zeros();
        let mut pose = start;
        for k in 0..1200 {
            let noise = if k % 2 == 0 { 0.25 } else { -0.25 };
            tracker.measure_flow(&Vector2::new(0.15 + noise, -noise));
            pose = tracker.advance(&pose, 0.1, &level, Some(0.0));
        }
        let v = tracker.twist().xy();
        assert!((v - Vector2::new(0.15, 0.0)).norm() < 0.01, "{v}");
        // and the position followed: 120 s at 0.1 m/s at least, 0.15 m/s at most
        let moved = pose.translation.x - start.translation.x;
        assert!(moved > 12.0 && moved < 18.0, "{moved}");
    }

    #[test]
    fn an_odometry_prediction_forgets_the_position_and_the_flows_pending_correction() {
        let (mut tracker, pose) = flying(Vector2::new(0.1, 0.0));
        tracker.measure_flow(&Vector2::new(0.5, 0.0));
        tracker.unknown_position();
        let still = tracker.advance(&pose, 0.0, &Vector2::zeros(), Some(0.0));
        assert_eq!(still.translation.vector, pose.translation.vector);
        // a match is kept whole along what it pins (x), nothing along y
        let pins_x = Matrix3::from_diagonal(&Vector3::new(100.0, 0.0, 100.0));
        let update = tracker
            .position_update(&Vector2::new(0.3, 0.2), &pins_x, 5.0, 0.05, 3.0)
            .unwrap();
        assert!((update.translation - Vector2::new(0.3, 0.0)).norm() < 1e-6);
    }

    #[test]
    fn tilt_carries_the_velocity_through_a_stop() {
        // flying forward at 0.1 m/s, then braking at 0.1 m/s² (nose up) for one second
        let (mut tracker, start) = flying(Vector2::new(0.1, 0.0));
        let pitch = (-0.1 / GRAVITY_MPS2).atan();
        let brake = tilt_acceleration(0.0, pitch);
        assert!((brake - Vector2::new(-0.1, 0.0)).norm() < 1e-12);
        let mut pose = start;
        for _ in 0..10 {
            pose = tracker.advance(&pose, 0.1, &brake, None);
        }
        // 0.1 m/s for 1 s minus half of 0.1 m/s² · 1 s²: 0.05 m further, standing still
        let moved = pose.translation.x - start.translation.x;
        assert!((moved - 0.05).abs() < 1e-3, "{moved}");
        assert!(tracker.twist().xy().norm() < 1e-3);
        // a roll to the right (positive) accelerates to the right (negative y)
        assert!(tilt_acceleration(0.01, 0.0).y < 0.0);
    }
}
