//! Motion gating: pause mapping and planning while the camera turns too fast.
//!
//! Fast rotations blur the images and smear depth, so what the mapper would insert then is
//! wrong and a plan made from it is worse than the last one. The gate watches the camera's
//! angular rate, from consecutive poses or from a gyro, and closes while any axis exceeds its
//! limit; it reopens once the rates have stayed below the limits for `settle_time_s`.

use crate::error::NavError;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use slamkit_core::Pose3;

/// Limits of the gate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MotionGateConfig {
    /// Largest angular rate about each camera axis (x right, y down, z forward) at which
    /// mapping and planning still run \[rad/s\].
    pub max_rate_rad_s: [f64; 3],
    /// Time the rates must stay within the limits before the gate reopens \[s\].
    pub settle_time_s: f64,
}

impl Default for MotionGateConfig {
    fn default() -> Self {
        Self {
            max_rate_rad_s: [45f64.to_radians(); 3],
            settle_time_s: 0.2,
        }
    }
}

/// The gate; see the module documentation.
#[derive(Debug, Clone)]
pub struct MotionGate {
    config: MotionGateConfig,
    calm_for_s: f64,
}

/// Angular velocity of the camera between two poses `dt_s` apart, in the camera frame
/// \[rad/s\]; `None` for a non-positive or non-finite interval or non-finite poses.
pub fn angular_rate(
    world_from_camera_prev: &Pose3,
    world_from_camera: &Pose3,
    dt_s: f64,
) -> Option<Vector3<f64>> {
    if !(dt_s.is_finite() && dt_s > 0.0) {
        return None;
    }
    let delta = world_from_camera_prev.rotation.inverse() * world_from_camera.rotation;
    let rate = delta.scaled_axis() / dt_s;
    rate.iter().all(|r| r.is_finite()).then_some(rate)
}

impl MotionGate {
    /// A gate, open.
    pub fn new(config: MotionGateConfig) -> Result<Self, NavError> {
        let ok = config
            .max_rate_rad_s
            .iter()
            .all(|r| r.is_finite() && *r > 0.0)
            && config.settle_time_s.is_finite()
            && config.settle_time_s >= 0.0;
        if !ok {
            return Err(NavError::InvalidConfig {
                message: "gate limits must be positive and finite".into(),
            });
        }
        Ok(Self {
            calm_for_s: config.settle_time_s,
            config,
        })
    }

    /// Feeds the camera's angular rate over the last `dt_s` seconds (`None`: unknown, which
    /// closes the gate) and returns whether mapping and planning may run now.
    pub fn update(&mut self, rate_rad_s: Option<&Vector3<f64>>, dt_s: f64) -> bool {
        let calm = rate_rad_s.is_some_and(|r| {
            r.iter()
                .zip(&self.config.max_rate_rad_s)
                .all(|(v, max)| v.abs() <= *max)
        });
        if calm {
            self.calm_for_s += if dt_s.is_finite() { dt_s.max(0.0) } else { 0.0 };
        } else {
            self.calm_for_s = 0.0;
        }
        self.is_open()
    }

    /// Whether mapping and planning may run.
    pub fn is_open(&self) -> bool {
        self.calm_for_s >= self.config.settle_time_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn closes_on_fast_turns_and_reopens_after_settling() {
        let mut gate = MotionGate::new(MotionGateConfig::default()).unwrap();
        assert!(gate.is_open());
        let slow = Vector3::new(0.0, 0.3, 0.0);
        let fast = Vector3::new(0.0, 1.5, 0.0);
        assert!(gate.update(Some(&slow), 0.033));
        assert!(!gate.update(Some(&fast), 0.033));
        let mut open_after = 0;
        for i in 1..20 {
            if gate.update(Some(&slow), 0.033) {
                open_after = i;
                break;
            }
        }
        assert_eq!(open_after, 7, "0.2 s at 30 Hz");
        assert!(!gate.update(None, 0.033), "unknown rates close the gate");
    }

    #[test]
    fn rate_from_poses() {
        let a = Pose3::identity();
        let b = Pose3::from_parts(
            Translation3::new(1.0, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.1, 0.0),
        );
        let rate = angular_rate(&a, &b, 0.1).unwrap();
        assert!((rate - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-9);
        assert!(angular_rate(&a, &b, 0.0).is_none());
        assert!(angular_rate(&a, &b, f64::NAN).is_none());
    }
}
