//! Simulated downward optical-flow velocity sensor, as small drones carry instead of wheel
//! odometry (PX4Flow, or the PMW3901 of the Crazyflie Flow deck).
//!
//! Such a sensor measures the angular rate at which the ground texture moves through its view,
//! `ω = v / d` for a horizontal velocity `v` at a distance `d` above the surface below; the
//! autopilot removes the part due to the body's own rotation (with the gyro) and scales the
//! rest by the range finder's distance. The reading here is the resulting body-frame
//! horizontal velocity, averaged over the integration period (the time since the previous
//! reading), with the two errors that matter for dead reckoning:
//!
//! * white noise on the angular rate, `σ_ω` per reading, which becomes a velocity noise
//!   `σ_ω · d` (it grows with the height). The default, 0.15 rad/s per 0.1 s reading, is PX4's
//!   EKF2 measurement noise for optical flow of the best quality (parameter `EKF2_OF_N_MIN`);
//!   the Crazyflie's Kalman filter assumes about as much for the PMW3901 (2 counts of
//!   0.1 pixel per 10 ms sample, a pixel being 0.0205 rad: 0.013 rad per 0.1 s, against
//!   0.015 rad here);
//! * a scale error fixed for the run (lens focal length, range offset, texture), drawn once
//!   with standard deviation `scale_error_sigma`.
//!
//! Over a surface nearer than `min_distance_m` or farther than `max_distance_m` (or none in
//! range) the sensor gives no reading. Each reading's noise comes from its own random stream.

use crate::SimError;
use nalgebra::Vector2;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::Pose3;

/// Noise and range of the optical-flow sensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OpticalFlowConfig {
    /// Readings per second \[Hz\].
    pub rate_hz: f64,
    /// Standard deviation of each reading's mean angular flow rate \[rad/s\].
    pub rate_noise_radps: f64,
    /// Standard deviation of the run's relative scale error.
    pub scale_error_sigma: f64,
    /// Nearest surface the sensor focuses on \[m\].
    pub min_distance_m: f64,
    /// Farthest surface whose texture the sensor resolves \[m\].
    pub max_distance_m: f64,
}

impl Default for OpticalFlowConfig {
    fn default() -> Self {
        Self {
            rate_hz: 10.0,
            rate_noise_radps: 0.15,
            scale_error_sigma: 0.03,
            min_distance_m: 0.08,
            max_distance_m: 4.0,
        }
    }
}

/// One optical-flow reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlowReading {
    /// End of the integration period \[s\].
    pub timestamp: f64,
    /// Length of the integration period \[s\].
    pub integration_s: f64,
    /// Mean body-frame horizontal velocity `(forward, left)` over the period \[m/s\]
    /// (`None`: no surface in the sensor's range).
    pub velocity_mps: Option<Vector2<f64>>,
}

impl OpticalFlowConfig {
    /// Fails on values no sensor can have.
    pub fn validate(&self) -> Result<(), SimError> {
        let ok = self.rate_hz.is_finite()
            && self.rate_hz > 0.0
            && [self.rate_noise_radps, self.scale_error_sigma]
                .iter()
                .all(|v| v.is_finite() && *v >= 0.0)
            && self.min_distance_m >= 0.0
            && self.max_distance_m > self.min_distance_m;
        if ok {
            Ok(())
        } else {
            Err(SimError::InvalidConfig(format!("optical flow: {self:?}")))
        }
    }

    /// The run's scale factor `1 + s`, `s` drawn from `rng`.
    pub fn scale_factor(&self, rng: &mut ChaCha8Rng) -> f64 {
        1.0 + self.scale_error_sigma * rng.sample::<f64, _>(StandardNormal)
    }

    /// The reading over the period `(start, end)` \[s\] in which the base moved from `from`
    /// to `to`, ending `distance_m` above the surface below, with the run's `scale` factor.
    pub fn read(
        &self,
        (from, to): (&Pose3, &Pose3),
        (start, timestamp): (f64, f64),
        distance_m: Option<f64>,
        scale: f64,
        rng: &mut ChaCha8Rng,
    ) -> FlowReading {
        let integration_s = timestamp - start;
        let in_range = distance_m
            .filter(|d| (self.min_distance_m..=self.max_distance_m).contains(d))
            .filter(|_| integration_s > 0.0);
        let velocity_mps = in_range.map(|d| {
            let step = pose3_to_pose2(from).inverse() * pose3_to_pose2(to);
            let mut noise = || self.rate_noise_radps * d * rng.sample::<f64, _>(StandardNormal);
            let noise = Vector2::new(noise(), noise());
            step.translation.vector * (scale / integration_s) + noise
        });
        FlowReading {
            timestamp,
            integration_s,
            velocity_mps,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use rand::SeedableRng;

    #[test]
    fn readings_scatter_around_the_body_velocity_with_height_scaled_noise() {
        let config = OpticalFlowConfig {
            scale_error_sigma: 0.0,
            ..OpticalFlowConfig::default()
        };
        // heading +90°: 1 cm along world y in 0.1 s is 0.1 m/s forward
        let from = Pose3::new(
            Vector3::new(1.0, 2.0, 1.5),
            Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        );
        let to = Pose3::new(
            Vector3::new(1.0, 2.01, 1.5),
            Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        );
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let readings: Vec<Vector2<f64>> = (0..4000)
            .map(|_| {
                let r = config.read((&from, &to), (0.0, 0.1), Some(1.5), 1.0, &mut rng);
                r.velocity_mps.unwrap()
            })
            .collect();
        let n = readings.len() as f64;
        let mean = readings.iter().sum::<Vector2<f64>>() / n;
        assert!((mean - Vector2::new(0.1, 0.0)).norm() < 0.015, "{mean}");
        let var = readings.iter().map(|v| (v.y - mean.y).powi(2)).sum::<f64>() / n;
        // 0.15 rad/s at 1.5 m: 0.225 m/s
        assert!((var.sqrt() - 0.225).abs() < 0.01, "{}", var.sqrt());
        // out of range or no surface: no reading
        for d in [None, Some(0.05), Some(4.5)] {
            let r = config.read((&from, &to), (0.0, 0.1), d, 1.0, &mut rng);
            assert_eq!(r.velocity_mps, None);
        }
    }

    #[test]
    fn the_scale_error_is_drawn_once_per_run() {
        let config = OpticalFlowConfig::default();
        let scales: Vec<f64> = (0..2000)
            .map(|s| config.scale_factor(&mut ChaCha8Rng::seed_from_u64(s)))
            .collect();
        let mean = scales.iter().sum::<f64>() / 2000.0;
        let sd = (scales.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 2000.0).sqrt();
        assert!(
            (mean - 1.0).abs() < 0.003 && (sd - 0.03).abs() < 0.003,
            "{mean} {sd}"
        );
        assert!(OpticalFlowConfig {
            rate_hz: 0.0,
            ..config.clone()
        }
        .validate()
        .is_err());
        assert!(config.validate().is_ok());
    }
}
