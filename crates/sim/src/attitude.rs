//! Simulated attitude (roll and pitch) readings, as a flight controller's IMU filter gives them.
//!
//! A multirotor's autopilot estimates roll and pitch from its gyroscopes and accelerometers to a
//! fraction of a degree; layered drone SLAM uses them to ignore planar scans taken while the
//! drone is tilted. A reading is the true angle plus Gaussian noise.

use crate::SimError;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use slamkit_core::Pose3;

/// Noise of the attitude estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AttitudeConfig {
    /// Standard deviation of roll and pitch \[rad\].
    pub sigma_rad: f64,
}

impl Default for AttitudeConfig {
    fn default() -> Self {
        Self {
            sigma_rad: 0.05f64.to_radians(),
        }
    }
}

/// Roll and pitch of the robot base at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeReading {
    /// Time \[s\].
    pub timestamp: f64,
    /// Roll about the base x axis \[rad\].
    pub roll_rad: f64,
    /// Pitch about the base y axis \[rad\].
    pub pitch_rad: f64,
}

impl AttitudeReading {
    /// Angle between the base z axis and the vertical \[rad\].
    pub fn tilt_rad(&self) -> f64 {
        (self.roll_rad.cos() * self.pitch_rad.cos())
            .clamp(-1.0, 1.0)
            .acos()
    }
}

impl AttitudeConfig {
    /// Fails on a negative or non-finite noise.
    pub fn validate(&self) -> Result<(), SimError> {
        if self.sigma_rad.is_finite() && self.sigma_rad >= 0.0 {
            Ok(())
        } else {
            Err(SimError::InvalidConfig(format!("attitude: {self:?}")))
        }
    }

    /// A noisy reading of the attitude of `world_from_base`.
    pub fn read(
        &self,
        world_from_base: &Pose3,
        timestamp: f64,
        rng: &mut ChaCha8Rng,
    ) -> AttitudeReading {
        let (roll, pitch, _) = world_from_base.rotation.euler_angles();
        let mut noisy = |angle: f64| angle + self.sigma_rad * rng.sample::<f64, _>(StandardNormal);
        AttitudeReading {
            timestamp,
            roll_rad: noisy(roll),
            pitch_rad: noisy(pitch),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use rand::SeedableRng;

    #[test]
    fn readings_scatter_around_the_truth() {
        let config = AttitudeConfig::default();
        let pose = Pose3::new(Vector3::new(1.0, 2.0, 0.5), Vector3::new(0.02, -0.01, 0.0));
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let readings: Vec<AttitudeReading> = (0..1000)
            .map(|k| config.read(&pose, f64::from(k), &mut rng))
            .collect();
        let (roll, pitch, _) = pose.rotation.euler_angles();
        let mean_roll = readings.iter().map(|r| r.roll_rad).sum::<f64>() / 1000.0;
        let mean_pitch = readings.iter().map(|r| r.pitch_rad).sum::<f64>() / 1000.0;
        assert!((mean_roll - roll).abs() < 1e-4 && (mean_pitch - pitch).abs() < 1e-4);
        let spread = readings
            .iter()
            .map(|r| (r.roll_rad - roll).powi(2))
            .sum::<f64>()
            / 1000.0;
        assert!((spread.sqrt() - config.sigma_rad).abs() < 1e-4);
        let level = AttitudeReading {
            timestamp: 0.0,
            roll_rad: 0.0,
            pitch_rad: 0.0,
        };
        assert_eq!(level.tilt_rad(), 0.0);
        assert!(AttitudeConfig { sigma_rad: -1.0 }.validate().is_err());
    }
}
