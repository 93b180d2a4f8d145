//! Odometry a robot cannot have driven: a jump (one corrupt reading, a counter reset, a driver
//! restart) replaced by no motion, so the readings after it continue from where the robot was.
//!
//! Every method takes its motion prior from the odometry increment between scans. One reading
//! with x = 10⁶ m in the Intel log put the map's next keyframes a thousand kilometres away
//! and asked the occupancy grid for terabytes. The gate keeps a correction `offset` laid over
//! the raw readings: an increment longer or faster than the robot can move (its speed limit
//! times the time since the last reading, plus a slack for timestamp jitter) is absorbed into
//! the offset, i.e. taken as no motion, and counted; the scan matcher then finds the real
//! motion from the scans alone. A spike and its return are two such steps; a reset is one.
//!
//! ```
//! use slamkit_core::Pose2;
//! use slamkit_slam::odometry_gate::{OdometryGate, OdometryGateConfig};
//!
//! let mut gate = OdometryGate::new(OdometryGateConfig::default());
//! let mut x_at = |t: f64, x: f64| {
//!     let odometry = Pose2::new(nalgebra::Vector2::new(x, 0.0), 0.0);
//!     let filtered = gate.filter(t, Some(odometry)).expect("a reading");
//!     (filtered.translation.x * 1e6).round() / 1e6
//! };
//! assert_eq!(x_at(0.0, 0.0), 0.0);
//! assert_eq!(x_at(0.1, 0.05), 0.05); // 0.5 m/s
//! assert_eq!(x_at(0.2, 1e6), 0.05); // a jump: no motion
//! assert_eq!(x_at(0.3, 0.10), 0.05); // and back: no motion again
//! assert_eq!(x_at(0.4, 0.15), 0.10); // then on as before
//! assert_eq!(gate.rejected(), 2);
//! ```

use serde::{Deserialize, Serialize};
use slamkit_core::pose::wrap_angle;
use slamkit_core::Pose2;

/// How fast a robot can move between two odometry readings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OdometryGateConfig {
    /// Fastest the robot drives \[m/s\] (small indoor robots and drones: under 3).
    pub max_speed_mps: f64,
    /// Fastest the robot turns \[rad/s\].
    pub max_turn_rate_radps: f64,
    /// Added to the distance the speed allows, for timestamp jitter and readings out of
    /// order \[m\].
    pub slack_m: f64,
    /// Added to the angle the turn rate allows \[rad\].
    pub slack_rad: f64,
}

impl Default for OdometryGateConfig {
    fn default() -> Self {
        Self {
            max_speed_mps: 5.0,
            max_turn_rate_radps: 4.0,
            slack_m: 0.25,
            slack_rad: 0.25,
        }
    }
}

impl OdometryGateConfig {
    /// Checks that every limit is positive (or infinite, to let every reading through).
    pub fn validate(&self) -> Result<(), String> {
        for (name, value) in [
            ("max_speed_mps", self.max_speed_mps),
            ("max_turn_rate_radps", self.max_turn_rate_radps),
            ("slack_m", self.slack_m),
            ("slack_rad", self.slack_rad),
        ] {
            if value.is_nan() || value < 0.0 {
                return Err(format!("odometry_gate.{name} = {value}: must be >= 0"));
            }
        }
        Ok(())
    }
}

/// The gate over one odometry stream; see the module documentation.
#[derive(Debug, Clone)]
pub struct OdometryGate {
    config: OdometryGateConfig,
    /// Laid over every raw reading: `filtered = offset * raw`.
    offset: Pose2,
    /// The last reading seen and the time it was first seen.
    last: Option<(f64, Pose2)>,
    rejected: usize,
}

impl OdometryGate {
    /// A gate that has seen no reading.
    pub fn new(config: OdometryGateConfig) -> Self {
        Self {
            config,
            offset: Pose2::identity(),
            last: None,
            rejected: 0,
        }
    }

    /// The reading at `timestamp` with the jumps so far taken out; `None` stays `None` and does
    /// not count as a reading. Non-finite readings are the caller's to drop first.
    pub fn filter(&mut self, timestamp: f64, raw: Option<Pose2>) -> Option<Pose2> {
        let raw = raw?;
        if let Some((t, last)) = self.last {
            let step = last.inverse() * raw;
            let dt = if timestamp > t { timestamp - t } else { 0.0 };
            let c = &self.config;
            let too_far = step.translation.vector.norm() > c.max_speed_mps * dt + c.slack_m;
            let too_fast =
                wrap_angle(step.rotation.angle()).abs() > c.max_turn_rate_radps * dt + c.slack_rad;
            if too_far || too_fast {
                // filtered stays where it was: offset * raw == offset_old * last
                self.offset = self.offset * last * raw.inverse();
                self.rejected += 1;
            }
        }
        // A repeated reading is stale odometry, not a standstill: the next new reading covers
        // the time since this one was first seen.
        if self.last.map_or(true, |(_, last)| last != raw) {
            self.last = Some((timestamp, raw));
        }
        Some(self.offset * raw)
    }

    /// Readings taken as no motion so far.
    pub fn rejected(&self) -> usize {
        self.rejected
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    fn pose(x: f64, y: f64, a: f64) -> Option<Pose2> {
        Some(Pose2::new(Vector2::new(x, y), a))
    }

    fn close(a: Option<Pose2>, b: Option<Pose2>) -> bool {
        let (a, b) = (a.unwrap(), b.unwrap());
        (a.translation.vector - b.translation.vector).norm() < 1e-9
            && (a.rotation.angle() - b.rotation.angle()).abs() < 1e-9
    }

    #[test]
    fn a_robot_within_its_limits_passes_unchanged() {
        let mut gate = OdometryGate::new(OdometryGateConfig::default());
        for i in 0..100 {
            let t = f64::from(i) * 0.1;
            // 1 m/s on a circle of 2 m radius
            let raw = pose(2.0 * (t / 2.0).sin(), 2.0 - 2.0 * (t / 2.0).cos(), t / 2.0);
            assert!(close(gate.filter(t, raw), raw), "{t}");
        }
        assert_eq!(gate.rejected(), 0);
        assert_eq!(gate.filter(11.0, None), None);
    }

    #[test]
    fn a_reset_is_one_step_of_no_motion_and_the_rest_follows_on() {
        let mut gate = OdometryGate::new(OdometryGateConfig::default());
        gate.filter(0.0, pose(3.0, 1.0, 0.5));
        gate.filter(0.1, pose(3.05, 1.0, 0.5));
        // the driver restarts: odometry from the origin again, heading 0
        assert!(close(
            gate.filter(0.2, pose(0.0, 0.0, 0.0)),
            pose(3.05, 1.0, 0.5)
        ));
        // 0.1 m forward in the new frame is 0.1 m along heading 0.5 in the old one
        let moved = gate.filter(0.3, pose(0.1, 0.0, 0.0));
        assert!(close(
            moved,
            pose(3.05 + 0.1 * 0.5f64.cos(), 1.0 + 0.1 * 0.5f64.sin(), 0.5)
        ));
        assert_eq!(gate.rejected(), 1);
    }

    #[test]
    fn odometry_that_froze_may_catch_up() {
        let mut gate = OdometryGate::new(OdometryGateConfig::default());
        gate.filter(0.0, pose(0.0, 0.0, 0.0));
        for i in 1..=20 {
            gate.filter(f64::from(i) * 0.1, pose(0.0, 0.0, 0.0));
        }
        // 1 m in 2 s since the reading changed last: 0.5 m/s
        assert!(close(
            gate.filter(2.1, pose(1.0, 0.0, 0.0)),
            pose(1.0, 0.0, 0.0)
        ));
        assert_eq!(gate.rejected(), 0);
    }

    #[test]
    fn a_spin_faster_than_the_turn_rate_is_refused() {
        let mut gate = OdometryGate::new(OdometryGateConfig::default());
        gate.filter(0.0, pose(0.0, 0.0, 0.0));
        assert!(close(
            gate.filter(0.05, pose(0.0, 0.0, 2.0)),
            pose(0.0, 0.0, 0.0)
        ));
        assert_eq!(gate.rejected(), 1);
        // out-of-order time: only the slack is allowed
        assert!(close(
            gate.filter(0.0, pose(0.0, 0.0, 2.1)),
            pose(0.0, 0.0, 0.1)
        ));
        assert_eq!(gate.rejected(), 1);
    }

    #[test]
    fn bad_limits_are_refused() {
        let config = OdometryGateConfig {
            max_speed_mps: f64::NAN,
            ..OdometryGateConfig::default()
        };
        assert!(config.validate().unwrap_err().contains("max_speed_mps"));
        assert!(OdometryGateConfig::default().validate().is_ok());
    }
}
