//! Robot motion along waypoints, with the ground-truth pose at any time.
//!
//! Both robots move segment by segment. Along a segment every coordinate (x, y, z, yaw) follows
//! the same smooth profile: speed rises as a raised cosine over `accel_time_s`, cruises, and
//! falls back to zero, so acceleration is continuous. A segment takes as long as its slowest
//! coordinate needs at its speed limit (plus one `accel_time_s`), so no limit is exceeded.
//!
//! * Drone: x, y, z and yaw change together; it hovers `hover_s` at each waypoint. A multirotor
//!   accelerates by tilting its thrust, so it pitches and rolls by `atan(a / g)` towards the
//!   horizontal acceleration `a` (Mahony, Kumar, Corke, "Multirotor aerial vehicles", IEEE RAM
//!   19(3), 2012), capped at `max_tilt_rad`.
//! * Differential-drive ground robot: turns in place towards the next waypoint, then drives
//!   straight to it; its base stays level at `base_height_m`.
//!
//! Frames: `world_from_base`, base x forward, y left, z up.

use crate::SimError;
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use slamkit_core::pose::wrap_angle;
use slamkit_core::Pose3;
use std::f64::consts::PI;

/// Standard gravity \[m/s²\].
const GRAVITY_MPS2: f64 = 9.80665;

/// Speed limits and manners of the simulated drone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DroneConfig {
    /// Horizontal cruise speed \[m/s\].
    pub horizontal_speed_mps: f64,
    /// Yaw rate \[rad/s\].
    pub yaw_rate_radps: f64,
    /// Climb and descent rate \[m/s\].
    pub climb_rate_mps: f64,
    /// Time to reach cruise speed from rest \[s\].
    pub accel_time_s: f64,
    /// Hover time at each waypoint \[s\].
    pub hover_s: f64,
    /// Largest roll or pitch \[rad\].
    pub max_tilt_rad: f64,
}

impl Default for DroneConfig {
    fn default() -> Self {
        Self {
            horizontal_speed_mps: 0.1,
            yaw_rate_radps: 0.4,
            climb_rate_mps: 0.2,
            accel_time_s: 1.0,
            hover_s: 1.0,
            max_tilt_rad: 0.2,
        }
    }
}

/// Speed limits and size of the simulated differential-drive robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DiffDriveConfig {
    /// Forward cruise speed \[m/s\].
    pub speed_mps: f64,
    /// Turn rate in place \[rad/s\].
    pub turn_rate_radps: f64,
    /// Time to reach cruise speed from rest \[s\].
    pub accel_time_s: f64,
    /// Height of the base frame above the floor \[m\].
    pub base_height_m: f64,
}

impl Default for DiffDriveConfig {
    fn default() -> Self {
        Self {
            speed_mps: 0.2,
            turn_rate_radps: 0.5,
            accel_time_s: 0.5,
            base_height_m: 0.1,
        }
    }
}

/// The true state of the robot at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotState {
    /// Time \[s\].
    pub timestamp: f64,
    /// Pose of the robot base in the world.
    pub world_from_base: Pose3,
    /// Linear velocity in the world frame \[m/s\].
    pub velocity_mps: Vector3<f64>,
    /// Yaw rate \[rad/s\].
    pub yaw_rate_radps: f64,
}

/// One stretch between two waypoint states `\[x, y, z, yaw\]`.
#[derive(Debug, Clone, Copy)]
struct Segment {
    start_s: f64,
    duration_s: f64,
    accel_s: f64,
    from: [f64; 4],
    delta: [f64; 4],
}

/// A robot moving through waypoints: ground truth at any time.
#[derive(Debug, Clone)]
pub struct WaypointMotion {
    segments: Vec<Segment>,
    /// Tilt cap of a drone; `None` for a ground robot (always level).
    max_tilt_rad: Option<f64>,
}

impl WaypointMotion {
    /// A drone flying through `waypoints` `\[x, y, z, yaw\]` \[m, rad\], hovering at each.
    pub fn drone(waypoints: &[[f64; 4]], config: &DroneConfig) -> Result<Self, SimError> {
        let limits = [
            config.horizontal_speed_mps,
            config.climb_rate_mps,
            config.yaw_rate_radps,
        ];
        check_limits(&limits, config.accel_time_s, waypoints.len())?;
        let mut builder = Builder::new(waypoints[0], config.accel_time_s);
        builder.hold(config.hover_s);
        for w in &waypoints[1..] {
            let delta = builder.delta_to(*w);
            let time = [
                delta[0].hypot(delta[1]) / config.horizontal_speed_mps,
                delta[2].abs() / config.climb_rate_mps,
                delta[3].abs() / config.yaw_rate_radps,
            ];
            builder.move_by(delta, time);
            builder.hold(config.hover_s);
        }
        Ok(Self {
            segments: builder.segments,
            max_tilt_rad: Some(config.max_tilt_rad.abs()),
        })
    }

    /// A differential-drive robot driving through `waypoints` `\[x, y\]` \[m\], starting at the
    /// first and facing the second.
    pub fn diff_drive(waypoints: &[[f64; 2]], config: &DiffDriveConfig) -> Result<Self, SimError> {
        let limits = [config.speed_mps, config.turn_rate_radps];
        check_limits(&limits, config.accel_time_s, waypoints.len())?;
        let [x0, y0] = waypoints[0];
        let [x1, y1] = waypoints[1];
        let start = [x0, y0, config.base_height_m, (y1 - y0).atan2(x1 - x0)];
        let mut builder = Builder::new(start, config.accel_time_s);
        for w in &waypoints[1..] {
            let here = builder.state;
            let heading = (w[1] - here[1]).atan2(w[0] - here[0]);
            let turn = builder.delta_to([here[0], here[1], here[2], heading]);
            builder.move_by(turn, [turn[3].abs() / config.turn_rate_radps, 0.0, 0.0]);
            let drive = builder.delta_to([w[0], w[1], here[2], heading]);
            builder.move_by(
                drive,
                [drive[0].hypot(drive[1]) / config.speed_mps, 0.0, 0.0],
            );
        }
        Ok(Self {
            segments: builder.segments,
            max_tilt_rad: None,
        })
    }

    /// Time from the start to the end of the last segment \[s\].
    pub fn duration_s(&self) -> f64 {
        self.segments
            .last()
            .map_or(0.0, |s| s.start_s + s.duration_s)
    }

    /// The true state at time `t` (clamped to `\[0, duration\]`).
    pub fn state_at(&self, t: f64) -> RobotState {
        let t = t.clamp(0.0, self.duration_s());
        let i = self
            .segments
            .partition_point(|s| s.start_s + s.duration_s < t);
        let Some(seg) = self.segments.get(i).or(self.segments.last()) else {
            return RobotState {
                timestamp: t,
                world_from_base: Pose3::identity(),
                velocity_mps: Vector3::zeros(),
                yaw_rate_radps: 0.0,
            };
        };
        let (s, ds, dds) = profile(t - seg.start_s, seg.duration_s, seg.accel_s);
        let at = |k: usize, f: f64| seg.from[k] + f * seg.delta[k];
        let yaw = at(3, s);
        let velocity = Vector3::new(seg.delta[0], seg.delta[1], seg.delta[2]) * ds;
        let (roll, pitch) = match self.max_tilt_rad {
            Some(max) => tilt(seg.delta[0] * dds, seg.delta[1] * dds, yaw, max),
            None => (0.0, 0.0),
        };
        RobotState {
            timestamp: t,
            world_from_base: Pose3::from_parts(
                Translation3::new(at(0, s), at(1, s), at(2, s)),
                UnitQuaternion::from_euler_angles(roll, pitch, yaw),
            ),
            velocity_mps: velocity,
            yaw_rate_radps: seg.delta[3] * ds,
        }
    }
}

fn check_limits(limits: &[f64], accel_time_s: f64, waypoints: usize) -> Result<(), SimError> {
    if waypoints < 2 {
        return Err(SimError::InvalidConfig(
            "a path needs at least 2 waypoints".into(),
        ));
    }
    if limits.iter().any(|v| !(v.is_finite() && *v > 0.0))
        || accel_time_s.is_nan()
        || accel_time_s < 0.0
    {
        return Err(SimError::InvalidConfig(
            "speed limits must be positive and accel_time_s not negative".into(),
        ));
    }
    Ok(())
}

/// Appends segments while tracking the state reached.
struct Builder {
    segments: Vec<Segment>,
    state: [f64; 4],
    clock_s: f64,
    accel_s: f64,
}

impl Builder {
    fn new(state: [f64; 4], accel_s: f64) -> Self {
        Self {
            segments: Vec::new(),
            state,
            clock_s: 0.0,
            accel_s,
        }
    }

    /// The change from the current state to `target`, yaw along the shorter arc.
    fn delta_to(&self, target: [f64; 4]) -> [f64; 4] {
        let s = self.state;
        [
            target[0] - s[0],
            target[1] - s[1],
            target[2] - s[2],
            wrap_angle(target[3] - s[3]),
        ]
    }

    /// Stay still for `duration_s`.
    fn hold(&mut self, duration_s: f64) {
        if duration_s > 0.0 {
            self.push([0.0; 4], duration_s, 0.0);
        }
    }

    /// Move by `delta`; `cruise_times_s` are the times each coordinate needs at its limit.
    fn move_by(&mut self, delta: [f64; 4], cruise_times_s: [f64; 3]) {
        let cruise = cruise_times_s.into_iter().fold(0.0, f64::max);
        if cruise > 1e-9 {
            self.push(delta, cruise + self.accel_s, self.accel_s);
        }
    }

    fn push(&mut self, delta: [f64; 4], duration_s: f64, accel_s: f64) {
        self.segments.push(Segment {
            start_s: self.clock_s,
            duration_s,
            accel_s,
            from: self.state,
            delta,
        });
        self.clock_s += duration_s;
        for (s, d) in self.state.iter_mut().zip(delta) {
            *s += d;
        }
    }
}

/// Fraction of a segment done at `tau` of `total` \[s\], with its first and second time
/// derivatives: raised-cosine speed ramps of `accel` at both ends, constant speed between.
fn profile(tau: f64, total: f64, accel: f64) -> (f64, f64, f64) {
    if total <= 0.0 {
        return (1.0, 0.0, 0.0);
    }
    let accel = accel.min(total / 2.0);
    let v = 1.0 / (total - accel);
    let ramp = |t: f64| {
        if accel <= 0.0 {
            return (v * t, v, 0.0);
        }
        let w = PI / accel;
        (
            v * (t / 2.0 - (w * t).sin() / (2.0 * w)),
            v * (1.0 - (w * t).cos()) / 2.0,
            v * w * (w * t).sin() / 2.0,
        )
    };
    let tau = tau.clamp(0.0, total);
    if tau < accel {
        ramp(tau)
    } else if tau <= total - accel {
        (v * accel / 2.0 + v * (tau - accel), v, 0.0)
    } else {
        let (s, ds, dds) = ramp(total - tau);
        (1.0 - s, ds, -dds)
    }
}

/// Roll and pitch of a multirotor accelerating at `(ax, ay)` in the world with heading `yaw`:
/// nose down to speed up forwards, bank towards a sideways acceleration.
fn tilt(ax: f64, ay: f64, yaw: f64, max_tilt_rad: f64) -> (f64, f64) {
    let (s, c) = yaw.sin_cos();
    let forward = ax * c + ay * s;
    let left = -ax * s + ay * c;
    let pitch = (forward / GRAVITY_MPS2)
        .atan()
        .clamp(-max_tilt_rad, max_tilt_rad);
    let roll = (-left / GRAVITY_MPS2)
        .atan()
        .clamp(-max_tilt_rad, max_tilt_rad);
    (roll, pitch)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_integrates_its_speed_and_ends_at_one() {
        let (total, accel) = (5.0, 1.0);
        let steps = 50_000;
        let dt = total / steps as f64;
        let (mut s_int, mut v_int) = (0.0, 0.0);
        for k in 0..steps {
            let t = (k as f64 + 0.5) * dt;
            let (_, ds, dds) = profile(t, total, accel);
            s_int += ds * dt;
            v_int += dds * dt;
        }
        assert!((s_int - 1.0).abs() < 1e-6 && v_int.abs() < 1e-6);
        assert_eq!(profile(0.0, total, accel), (0.0, 0.0, 0.0));
        assert!((profile(total, total, accel).0 - 1.0).abs() < 1e-12);
        for tau in [0.3, 0.9, 2.0, 2.5] {
            let sum = profile(tau, total, accel).0 + profile(total - tau, total, accel).0;
            assert!((sum - 1.0).abs() < 1e-12, "not symmetric at {tau}");
        }
    }

    #[test]
    fn drone_respects_limits_and_tilts_when_accelerating() {
        let config = DroneConfig::default();
        let path = [
            [1.0, 1.0, 0.5, 0.0],
            [3.0, 1.0, 0.9, 1.0],
            [3.0, 2.0, 0.9, 1.0],
        ];
        let m = WaypointMotion::drone(&path, &config).unwrap();
        // 2 m at 0.1 m/s, 1 s ramp, three 1 s hovers; then 1 m
        assert!(
            (m.duration_s() - (3.0 + 21.0 + 11.0)).abs() < 1e-9,
            "{}",
            m.duration_s()
        );
        let (mut max_v, mut max_tilt) = (0.0f64, 0.0f64);
        for k in 0..=3500 {
            let s = m.state_at(k as f64 * 0.01);
            max_v = max_v.max(s.velocity_mps.xy().norm());
            let (r, p, _) = s.world_from_base.rotation.euler_angles();
            max_tilt = max_tilt.max(r.abs()).max(p.abs());
            assert!(s.yaw_rate_radps.abs() <= config.yaw_rate_radps + 1e-9);
            assert!(s.velocity_mps.z.abs() <= config.climb_rate_mps + 1e-9);
        }
        assert!((max_v - 0.1).abs() < 1e-3, "{max_v}");
        assert!(max_tilt > 0.005 && max_tilt < 0.05, "{max_tilt}");
        let end = m.state_at(1e9).world_from_base;
        assert!((end.translation.vector - Vector3::new(3.0, 2.0, 0.9)).norm() < 1e-12);
        let start = m.state_at(0.5);
        assert_eq!(
            start.world_from_base.translation.vector,
            Vector3::new(1.0, 1.0, 0.5)
        );
    }

    #[test]
    fn diff_drive_turns_then_drives_level() {
        let m = WaypointMotion::diff_drive(
            &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]],
            &DiffDriveConfig::default(),
        )
        .unwrap();
        // 1 m straight (5.5 s), turn 90 deg (pi/2 / 0.5 + 0.5 s), 1 m (5.5 s)
        let turn = PI / 2.0 / 0.5 + 0.5;
        assert!((m.duration_s() - (5.5 + turn + 5.5)).abs() < 1e-9);
        let mid_turn = m.state_at(5.5 + turn / 2.0).world_from_base;
        assert!(
            (mid_turn.translation.vector.xy() - nalgebra::Vector2::new(1.0, 0.0)).norm() < 1e-9
        );
        let (r, p, y) = mid_turn.rotation.euler_angles();
        assert!(r == 0.0 && p == 0.0 && (y - PI / 4.0).abs() < 1e-9, "{y}");
        assert!(WaypointMotion::diff_drive(&[[0.0, 0.0]], &DiffDriveConfig::default()).is_err());
    }
}
