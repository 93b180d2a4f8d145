//! Simulated single-beam range finders looking straight up and down from the robot (as
//! time-of-flight sensors on small drones measure height above ground and room to the ceiling).
//!
//! The beams follow the robot's tilt, so a tilted drone reads slightly long. A reading is the
//! true distance plus Gaussian noise, rounded to the resolution; nothing within range (or a
//! dropout) gives `None`.

use crate::lidar::RangeNoise;
use crate::scene::Scene;
use crate::SimError;
use nalgebra::{Point3, Vector3};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use slamkit_core::Pose3;

/// The pair of vertical range finders.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RangeFinderConfig {
    /// Largest measurable distance \[m\].
    pub max_range_m: f64,
    /// Standard deviation of the noise \[m\].
    pub sigma_m: f64,
    /// Probability that a reading is missing.
    pub dropout_probability: f64,
    /// Readings are rounded to multiples of this \[m\].
    pub resolution_m: f64,
    /// Readings per second \[Hz\].
    pub rate_hz: f64,
    /// Height of the up-looking sensor above the base origin \[m\].
    pub up_offset_m: f64,
    /// Depth of the down-looking sensor below the base origin \[m\].
    pub down_offset_m: f64,
}

impl Default for RangeFinderConfig {
    fn default() -> Self {
        Self {
            max_range_m: 4.0,
            sigma_m: 0.005,
            dropout_probability: 0.0,
            resolution_m: 0.001,
            rate_hz: 10.0,
            up_offset_m: 0.03,
            down_offset_m: 0.03,
        }
    }
}

/// One pair of readings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeReading {
    /// Time \[s\].
    pub timestamp: f64,
    /// Distance from the up-looking sensor to the ceiling or an obstacle above \[m\].
    pub up_m: Option<f64>,
    /// Distance from the down-looking sensor to the floor or an obstacle below \[m\].
    pub down_m: Option<f64>,
}

impl RangeFinderConfig {
    /// Fails on values no sensor can have.
    pub fn validate(&self) -> Result<(), SimError> {
        let ok = self.max_range_m > 0.0 && self.noise().is_valid();
        if ok {
            Ok(())
        } else {
            Err(SimError::InvalidConfig(format!("range finder: {self:?}")))
        }
    }

    /// The readings' noise model, in the form the lidar shares.
    fn noise(&self) -> RangeNoise {
        RangeNoise {
            sigma_m: self.sigma_m,
            dropout_probability: self.dropout_probability,
            step_m: self.resolution_m,
            rate_hz: self.rate_hz,
        }
    }

    /// True distances up and down (`None`: nothing within range).
    pub fn true_ranges(&self, scene: &Scene, world_from_base: &Pose3) -> [Option<f64>; 2] {
        [(self.up_offset_m, 1.0), (-self.down_offset_m, -1.0)].map(|(offset, sign)| {
            let origin = world_from_base * Point3::new(0.0, 0.0, offset);
            let dir = world_from_base.rotation * Vector3::new(0.0, 0.0, sign);
            scene
                .cast(&origin, &dir, self.max_range_m)
                .map(|h| h.distance_m)
        })
    }

    /// Noisy readings at `timestamp` from `world_from_base`.
    pub fn read(
        &self,
        scene: &Scene,
        world_from_base: &Pose3,
        timestamp: f64,
        rng: &mut ChaCha8Rng,
    ) -> RangeReading {
        let noise = self.noise();
        let [up, down] = self.true_ranges(scene, world_from_base).map(|truth| {
            let r = noise.reading(truth, rng)?;
            Some(r.clamp(0.0, self.max_range_m))
        });
        RangeReading {
            timestamp,
            up_m: up,
            down_m: down,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::World;
    use rand::SeedableRng;

    #[test]
    fn over_a_box_and_under_a_table() {
        let text = "name = \"t\"\nsize_m = [4.0, 4.0]\nheight_m = 2.0\n\
             flight_path = [[1, 1, 1, 0], [2, 1, 1, 0]]\ndrive_path = [[1, 1], [2, 1]]\n\
             nav_goal = [2, 2]\n[[boxes]]\ncenter = [2, 2]\nsize_m = [0.4, 0.4]\nz_m = [0, 0.5]\n\
             [[boxes]]\ncenter = [1, 3]\nsize_m = [1, 0.6]\nz_m = [0.7, 0.75]\n";
        let scene = Scene::new(&World::from_toml(text, "t").unwrap());
        let config = RangeFinderConfig::default();
        let at = |x: f64, y: f64, z: f64| Pose3::new(Vector3::new(x, y, z), Vector3::zeros());
        let [up, down] = config.true_ranges(&scene, &at(2.0, 2.0, 1.0));
        assert!((up.unwrap() - 0.97).abs() < 1e-9 && (down.unwrap() - 0.47).abs() < 1e-9);
        let [_, floor] = config.true_ranges(&scene, &at(3.0, 2.0, 1.0));
        assert!((floor.unwrap() - 0.97).abs() < 1e-9);
        let [table, _] = config.true_ranges(&scene, &at(1.0, 3.0, 0.3));
        assert!((table.unwrap() - 0.37).abs() < 1e-9);
        // tilted by 0.2 rad the beams read longer: 0.97 / cos 0.2 to the floor
        let tilted = Pose3::new(Vector3::new(3.0, 2.0, 1.0), Vector3::new(0.2, 0.0, 0.0));
        let expected = (1.0 - 0.03 * 0.2f64.cos()) / 0.2f64.cos();
        let [_, slant] = config.true_ranges(&scene, &tilted);
        assert!((slant.unwrap() - expected).abs() < 1e-9);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let errors: Vec<f64> = (0..2000)
            .map(|k| config.read(&scene, &at(2.0, 2.0, 1.0), f64::from(k), &mut rng))
            .map(|r| r.down_m.unwrap() - 0.47)
            .collect();
        let mean = errors.iter().sum::<f64>() / 2000.0;
        let std = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / 2000.0).sqrt();
        assert!(
            mean.abs() < 5e-4 && (std - 0.005).abs() < 5e-4,
            "{mean} {std}"
        );
        let far = RangeFinderConfig {
            max_range_m: 0.5,
            ..config
        };
        assert_eq!(
            far.read(&scene, &at(3.0, 2.0, 1.0), 0.0, &mut rng).down_m,
            None
        );
    }
}
