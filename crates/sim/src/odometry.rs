//! Odometry with drift: the true planar motion between two instants, corrupted and integrated.
//!
//! The motion between two poses is split into a rotation, a translation and a second rotation,
//! each corrupted by zero-mean Gaussian noise whose standard deviation grows with the motion,
//! as in the odometry motion model of Thrun, Burgard and Fox (*Probabilistic Robotics*, 2005,
//! table 5.6; here with standard deviations proportional to the motion rather than variances),
//! and scaled by a fixed calibration error (Borenstein & Feng, "Measurement and correction of
//! systematic odometry errors in mobile robots", IEEE T-RA 12(6), 1996), which makes the
//! estimate drift the same way on every run.
//!
//! The ground robot gets wheel odometry ([`OdometryConfig::wheel`]); the drone has no wheels and
//! gets noisier increments such as an optical-flow or visual odometry would give
//! ([`OdometryConfig::visual`]). Odometry starts at the true pose.

use nalgebra::Vector2;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use slamkit_core::pose::wrap_angle;
use slamkit_core::Pose2;

/// Noise of simulated odometry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OdometryConfig {
    /// Systematic relative error of distances (0.02: odometry reads 2 % long).
    pub translation_scale_error: f64,
    /// Systematic relative error of rotations.
    pub rotation_scale_error: f64,
    /// Rotation noise per rotation \[rad/rad\] (Thrun's α1).
    pub rot_per_rot: f64,
    /// Rotation noise per distance \[rad/m\] (α2).
    pub rot_per_m: f64,
    /// Translation noise per distance \[m/m\] (α3).
    pub trans_per_m: f64,
    /// Translation noise per rotation \[m/rad\] (α4).
    pub trans_per_rot: f64,
}

impl Default for OdometryConfig {
    fn default() -> Self {
        Self::wheel()
    }
}

impl OdometryConfig {
    /// Wheel encoders of a small differential-drive robot.
    pub fn wheel() -> Self {
        Self {
            translation_scale_error: 0.02,
            rotation_scale_error: -0.03,
            rot_per_rot: 0.05,
            rot_per_m: 0.02,
            trans_per_m: 0.05,
            trans_per_rot: 0.01,
        }
    }

    /// Visual / optical-flow increments of a drone: noisier, and drifting in scale and yaw.
    pub fn visual() -> Self {
        Self {
            translation_scale_error: -0.04,
            rotation_scale_error: 0.02,
            rot_per_rot: 0.08,
            rot_per_m: 0.05,
            trans_per_m: 0.1,
            trans_per_rot: 0.02,
        }
    }
}

/// Integrates corrupted motion increments into a drifting odometry pose.
#[derive(Debug, Clone)]
pub struct OdometrySimulator {
    config: OdometryConfig,
    rng: ChaCha8Rng,
    last_true: Option<Pose2>,
    estimate: Pose2,
}

impl OdometrySimulator {
    /// A simulator drawing its noise from `rng`.
    pub fn new(config: OdometryConfig, rng: ChaCha8Rng) -> Self {
        Self {
            config,
            rng,
            last_true: None,
            estimate: Pose2::identity(),
        }
    }

    /// The odometry pose once the robot has truly moved to `world_from_base`.
    pub fn update(&mut self, world_from_base: &Pose2) -> Pose2 {
        let Some(last) = self.last_true.replace(*world_from_base) else {
            self.estimate = *world_from_base;
            return self.estimate;
        };
        let delta = last.inverse() * world_from_base;
        let noisy = self.corrupt(&delta);
        self.estimate *= noisy;
        self.estimate
    }

    /// Rotate–translate–rotate decomposition of `delta`, each part scaled and perturbed.
    fn corrupt(&mut self, delta: &Pose2) -> Pose2 {
        let c = &self.config;
        let t = delta.translation.vector;
        let trans = t.norm();
        let rot1 = if trans > 1e-9 { t.y.atan2(t.x) } else { 0.0 };
        let rot2 = wrap_angle(delta.rotation.angle() - rot1);
        let mut gauss = |sigma: f64| sigma * self.rng.sample::<f64, _>(StandardNormal);
        let rot_scale = 1.0 + c.rotation_scale_error;
        let rot1_n = rot1 * rot_scale + gauss(c.rot_per_rot * rot1.abs() + c.rot_per_m * trans);
        let trans_n = trans * (1.0 + c.translation_scale_error)
            + gauss(c.trans_per_m * trans + c.trans_per_rot * (rot1.abs() + rot2.abs()));
        let rot2_n = rot2 * rot_scale + gauss(c.rot_per_rot * rot2.abs() + c.rot_per_m * trans);
        let (s, co) = rot1_n.sin_cos();
        Pose2::new(Vector2::new(trans_n * co, trans_n * s), rot1_n + rot2_n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn drift_follows_the_scale_error_and_noise_averages_out() {
        let config = OdometryConfig {
            rotation_scale_error: 0.0,
            ..OdometryConfig::wheel()
        };
        let mut finals = Vec::new();
        for seed in 0..200 {
            let mut odo = OdometrySimulator::new(config.clone(), ChaCha8Rng::seed_from_u64(seed));
            let start = Pose2::new(Vector2::new(1.0, 2.0), 0.5);
            assert_eq!(odo.update(&start), start);
            let mut last = start;
            for k in 1..=100 {
                last = start * Pose2::new(Vector2::new(0.01 * f64::from(k), 0.0), 0.0);
                odo.update(&last);
            }
            finals.push((last.inverse() * odo.estimate).translation.vector);
        }
        let mean = finals.iter().sum::<Vector2<f64>>() / finals.len() as f64;
        // 1 m driven, 2 % long on average
        assert!((mean.x - 0.02).abs() < 0.003, "{mean}");
        assert!(mean.y.abs() < 0.003, "{mean}");
        let spread = finals.iter().map(|f| (f.x - mean.x).powi(2)).sum::<f64>() / 200.0;
        // 100 steps of 1 cm with sigma 5 % each: std 0.05 * 0.01 * 10 = 5 mm
        assert!((spread.sqrt() - 0.005).abs() < 0.0015, "{}", spread.sqrt());
    }

    #[test]
    fn pure_rotation_stays_in_place() {
        let mut odo = OdometrySimulator::new(OdometryConfig::wheel(), ChaCha8Rng::seed_from_u64(1));
        odo.update(&Pose2::identity());
        let turned = odo.update(&Pose2::new(Vector2::zeros(), 1.0));
        assert!(turned.translation.vector.norm() < 0.05);
        assert!((turned.rotation.angle() - 0.97).abs() < 0.2);
    }
}
