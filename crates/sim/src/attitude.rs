//! Simulated attitude readings, as a flight controller's IMU gives them: roll and pitch, and the
//! heading integrated from the yaw-rate gyro.
//!
//! A multirotor's autopilot estimates roll and pitch from its gyroscopes and accelerometers to a
//! fraction of a degree; layered drone SLAM uses them to ignore planar scans taken while the
//! drone is tilted. A roll or pitch reading is the true angle plus Gaussian noise.
//!
//! The heading has no absolute reference indoors (no usable magnetometer), so the autopilot
//! integrates the z gyro: the reading is the integral, from 0 at the first reading, of the
//! measured yaw rate `ω + b + n`, with white noise `n` of density `σ_n` (angle random walk) and a
//! bias `b` that starts at the residual of the at-rest calibration before take-off and then
//! wanders as a random walk of density `σ_b` (the usual model, e.g. J. Sola, "Quaternion
//! kinematics for the error-state Kalman filter", 2017, sec. 5.3.3). The defaults follow the
//! Bosch BMI088 datasheet (BST-BMI088-DS001, rev. 1.9, table 2), the IMU of the Crazyflie 2.1:
//! output noise density 0.014 °/s/√Hz and bias stability 2 °/h; its ±1 °/s zero-rate offset is
//! what the take-off calibration removes, to the 0.05 °/s left by averaging 0.5 s of that noise
//! and temperature change, and the random walk (0.004 °/s/√s, 0.04 °/s after 100 s) is a
//! pessimistic stand-in for its 0.015 °/s/K temperature drift while the motors warm it. The gyro
//! is sampled at `rate_hz`, and the rate in between is the mean over the sample period (the
//! true heading change of the period divided by its length).

use crate::SimError;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use slamkit_core::pose::wrap_angle;
use slamkit_core::Pose3;

/// Noise of the attitude estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AttitudeConfig {
    /// Standard deviation of roll and pitch \[rad\].
    pub sigma_rad: f64,
    /// The yaw-rate gyro.
    pub gyro: GyroConfig,
}

impl Default for AttitudeConfig {
    fn default() -> Self {
        Self {
            sigma_rad: 0.05f64.to_radians(),
            gyro: GyroConfig::default(),
        }
    }
}

/// Noise of the z (yaw-rate) gyro; defaults from the Bosch BMI088 datasheet (module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GyroConfig {
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// White rate noise density (angle random walk) \[rad/s/√Hz\].
    pub noise_density_radps_per_sqrt_hz: f64,
    /// Standard deviation of the bias left by the at-rest calibration \[rad/s\].
    pub initial_bias_sigma_radps: f64,
    /// Density of the bias random walk \[rad/s/√s\].
    pub bias_random_walk_radps_per_sqrt_s: f64,
}

impl Default for GyroConfig {
    fn default() -> Self {
        Self {
            rate_hz: 200.0,
            noise_density_radps_per_sqrt_hz: 0.014f64.to_radians(),
            initial_bias_sigma_radps: 0.05f64.to_radians(),
            bias_random_walk_radps_per_sqrt_s: 0.004f64.to_radians(),
        }
    }
}

impl GyroConfig {
    /// Fails on a non-positive rate or a negative or non-finite noise.
    pub fn validate(&self) -> Result<(), SimError> {
        let noises = [
            self.noise_density_radps_per_sqrt_hz,
            self.initial_bias_sigma_radps,
            self.bias_random_walk_radps_per_sqrt_s,
        ];
        if self.rate_hz.is_finite()
            && self.rate_hz > 0.0
            && noises.iter().all(|n| n.is_finite() && *n >= 0.0)
        {
            Ok(())
        } else {
            Err(SimError::InvalidConfig(format!("gyro: {self:?}")))
        }
    }
}

/// A yaw-rate gyro integrated over time: one sequential random stream (the bias wanders).
#[derive(Debug, Clone)]
pub struct YawGyro {
    config: GyroConfig,
    rng: ChaCha8Rng,
    /// Current bias \[rad/s\].
    bias_radps: f64,
    /// Integrated measured heading \[rad\].
    yaw_rad: f64,
    /// Time of `yaw_rad` \[s\] (`None` before the first reading).
    time_s: Option<f64>,
}

impl YawGyro {
    /// A gyro at rest, its calibration residual drawn from `rng`.
    pub fn new(config: GyroConfig, mut rng: ChaCha8Rng) -> Self {
        let bias_radps = config.initial_bias_sigma_radps * rng.sample::<f64, _>(StandardNormal);
        Self {
            config,
            rng,
            bias_radps,
            yaw_rad: 0.0,
            time_s: None,
        }
    }

    /// Current bias \[rad/s\].
    pub fn bias_radps(&self) -> f64 {
        self.bias_radps
    }

    /// The integrated heading at time `t_s` \[rad\] (0 at the first call), the true heading
    /// at any time given by `true_yaw`. Gyro samples fall every `1 / rate_hz` from the first
    /// call; a time not after the last one returns the last heading.
    pub fn integrate_to(&mut self, t_s: f64, true_yaw: impl Fn(f64) -> f64) -> f64 {
        let Some(start) = self.time_s else {
            self.time_s = Some(t_s);
            return self.yaw_rad;
        };
        let span = t_s - start;
        if span.is_nan() || span <= 0.0 {
            return self.yaw_rad;
        }
        let steps = (span * self.config.rate_hz).ceil().max(1.0);
        let dt = span / steps;
        let white = self.config.noise_density_radps_per_sqrt_hz / dt.sqrt();
        let walk = self.config.bias_random_walk_radps_per_sqrt_s * dt.sqrt();
        let mut previous = true_yaw(start);
        for k in 1..=steps as u64 {
            let now = true_yaw(start + dt * k as f64);
            let turn = wrap_angle(now - previous);
            previous = now;
            let noise: f64 = self.rng.sample(StandardNormal);
            self.yaw_rad += turn + (self.bias_radps + white * noise) * dt;
            self.bias_radps += walk * self.rng.sample::<f64, _>(StandardNormal);
        }
        self.time_s = Some(t_s);
        self.yaw_rad
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
    /// Heading integrated from the yaw-rate gyro since the first reading \[rad\] (not
    /// wrapped; only its changes mean something).
    pub gyro_yaw_rad: f64,
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
            self.gyro.validate()
        } else {
            Err(SimError::InvalidConfig(format!("attitude: {self:?}")))
        }
    }

    /// A noisy reading of the roll and pitch of `world_from_base`, with the gyro's integrated
    /// heading `gyro_yaw_rad` at that time.
    pub fn read(
        &self,
        world_from_base: &Pose3,
        timestamp: f64,
        gyro_yaw_rad: f64,
        rng: &mut ChaCha8Rng,
    ) -> AttitudeReading {
        let (roll, pitch, _) = world_from_base.rotation.euler_angles();
        let mut noisy = |angle: f64| angle + self.sigma_rad * rng.sample::<f64, _>(StandardNormal);
        AttitudeReading {
            timestamp,
            roll_rad: noisy(roll),
            pitch_rad: noisy(pitch),
            gyro_yaw_rad,
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
            .map(|k| config.read(&pose, f64::from(k), 0.0, &mut rng))
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
            gyro_yaw_rad: 0.0,
        };
        assert_eq!(level.tilt_rad(), 0.0);
        let bad = AttitudeConfig {
            sigma_rad: -1.0,
            ..AttitudeConfig::default()
        };
        assert!(bad.validate().is_err());
    }

    #[test]
    fn gyro_bias_and_noise_have_the_configured_statistics() {
        let config = GyroConfig::default();
        let runs = 400;
        let (mut start_bias, mut end_bias, mut still_yaw) = (Vec::new(), Vec::new(), Vec::new());
        for seed in 0..runs {
            let mut gyro = YawGyro::new(config.clone(), ChaCha8Rng::seed_from_u64(seed));
            start_bias.push(gyro.bias_radps());
            // standing still for 1 s: the heading wanders by the bias plus the white noise
            gyro.integrate_to(0.0, |_| 0.0);
            still_yaw.push(gyro.integrate_to(1.0, |_| 0.0));
            gyro.integrate_to(100.0, |_| 0.0);
            end_bias.push(gyro.bias_radps() - start_bias[start_bias.len() - 1]);
        }
        let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        let near = |got: f64, want: f64| (got / want - 1.0).abs() < 0.15;
        assert!(near(rms(&start_bias), config.initial_bias_sigma_radps));
        // after 100 s the walk has moved the bias by σ_b · √100
        let walked = config.bias_random_walk_radps_per_sqrt_s * 10.0;
        assert!(near(rms(&end_bias), walked), "{} {walked}", rms(&end_bias));
        // 1 s: bias (σ_b0 · 1 s) and angle random walk (σ_n · √1 s), independent
        let want = config
            .initial_bias_sigma_radps
            .hypot(config.noise_density_radps_per_sqrt_hz);
        assert!(near(rms(&still_yaw), want), "{} {want}", rms(&still_yaw));
    }

    #[test]
    fn gyro_follows_a_known_rotation() {
        let config = GyroConfig::default();
        let mut gyro = YawGyro::new(config.clone(), ChaCha8Rng::seed_from_u64(9));
        // 0.4 rad/s for 10 s, crossing ±π: 4 rad of turn, read every 0.1 s
        let truth = |t: f64| wrap_angle(3.0 + 0.4 * t);
        let mut yaw = 0.0;
        for k in 0..=100 {
            yaw = gyro.integrate_to(0.1 * f64::from(k), truth);
        }
        // within 5 σ of the bias and noise over 10 s
        let sigma = (config.initial_bias_sigma_radps * 10.0)
            .hypot(config.noise_density_radps_per_sqrt_hz * 10f64.sqrt());
        assert!((yaw - 4.0).abs() < 5.0 * sigma, "{yaw}");
        assert!((yaw - 4.0).abs() > 0.0);
        let silent = GyroConfig {
            noise_density_radps_per_sqrt_hz: 0.0,
            initial_bias_sigma_radps: 0.0,
            bias_random_walk_radps_per_sqrt_s: 0.0,
            ..config
        };
        let mut exact = YawGyro::new(silent.clone(), ChaCha8Rng::seed_from_u64(9));
        exact.integrate_to(0.0, truth);
        assert!((exact.integrate_to(10.0, truth) - 4.0).abs() < 1e-9);
        assert!(GyroConfig {
            rate_hz: 0.0,
            ..silent
        }
        .validate()
        .is_err());
    }
}
