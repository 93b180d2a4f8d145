//! Simulated planar lidar: beams fanned out in the lidar's own plane, which tilts with the
//! robot, ray-cast against the 3D world.
//!
//! Each reading is the true distance plus Gaussian noise, rounded to the sensor's resolution.
//! A beam that hits nothing within range, or drops out (dark or specular surfaces), reads the
//! maximum range, the "no return" convention of [`LaserScan`]; a target nearer than the minimum
//! range reads 0 (invalid). The scan is taken at one instant: motion during a sweep (skew) is
//! not modelled. The default sensor is a 270°, 512-beam, 3 m unit (as on the seed's drone).

use crate::scene::Scene;
use crate::SimError;
use nalgebra::{Point3, Translation3, Vector2, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use slamkit_core::{LaserScan, Pose2, Pose3};

/// A planar lidar's geometry and noise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Lidar2dConfig {
    /// Field of view, centred on the forward axis \[rad\].
    pub fov_rad: f64,
    /// Number of beams, spread evenly from −fov/2 to +fov/2.
    pub beams: usize,
    /// Largest measurable range; also the "no return" reading \[m\].
    pub max_range_m: f64,
    /// Targets nearer than this read 0 (invalid) \[m\].
    pub min_range_m: f64,
    /// Standard deviation of the range noise \[m\].
    pub range_sigma_m: f64,
    /// Probability that a beam returns nothing.
    pub dropout_probability: f64,
    /// Readings are rounded to multiples of this \[m\].
    pub resolution_m: f64,
    /// Scans per second \[Hz\].
    pub rate_hz: f64,
    /// Position of the lidar on the robot base `\[x, y, z\]` \[m\] (axes aligned with the base).
    pub mount_xyz_m: [f64; 3],
}

impl Default for Lidar2dConfig {
    fn default() -> Self {
        Self {
            fov_rad: 270f64.to_radians(),
            beams: 512,
            max_range_m: 3.0,
            min_range_m: 0.05,
            range_sigma_m: 0.01,
            dropout_probability: 0.01,
            resolution_m: 0.001,
            rate_hz: 10.0,
            mount_xyz_m: [0.0, 0.0, 0.05],
        }
    }
}

impl Lidar2dConfig {
    /// Fails on values no sensor can have.
    pub fn validate(&self) -> Result<(), SimError> {
        let ok = self.beams >= 2
            && self.fov_rad > 0.0
            && self.fov_rad <= std::f64::consts::TAU
            && self.max_range_m > self.min_range_m
            && self.min_range_m >= 0.0
            && self.noise().is_valid();
        if ok {
            Ok(())
        } else {
            Err(SimError::InvalidConfig(format!("lidar2d: {self:?}")))
        }
    }

    /// The beams' noise model, in the form the range finders share.
    fn noise(&self) -> RangeNoise {
        RangeNoise {
            sigma_m: self.range_sigma_m,
            dropout_probability: self.dropout_probability,
            step_m: self.resolution_m,
            rate_hz: self.rate_hz,
        }
    }

    /// Angle between neighbouring beams \[rad\].
    pub fn angle_increment_rad(&self) -> f64 {
        self.fov_rad / (self.beams.max(2) - 1) as f64
    }

    /// Pose of the lidar on the base, in 3D.
    pub fn base_from_lidar(&self) -> Pose3 {
        let [x, y, z] = self.mount_xyz_m;
        Pose3::from_parts(Translation3::new(x, y, z), Default::default())
    }

    /// True distance of every beam (`None`: nothing within `max_range_m`).
    pub fn true_ranges(&self, scene: &Scene, world_from_base: &Pose3) -> Vec<Option<f64>> {
        let world_from_lidar = world_from_base * self.base_from_lidar();
        let origin = Point3::from(world_from_lidar.translation.vector);
        let angle_min = -self.fov_rad / 2.0;
        (0..self.beams)
            .map(|i| {
                let a = angle_min + i as f64 * self.angle_increment_rad();
                let dir = world_from_lidar.rotation * Vector3::new(a.cos(), a.sin(), 0.0);
                scene
                    .cast(&origin, &dir, self.max_range_m)
                    .map(|h| h.distance_m)
            })
            .collect()
    }

    /// A noisy scan taken at `timestamp` from `world_from_base`; `odometry` is left empty.
    pub fn scan(
        &self,
        scene: &Scene,
        world_from_base: &Pose3,
        timestamp: f64,
        rng: &mut ChaCha8Rng,
    ) -> LaserScan {
        let ranges_m = self
            .true_ranges(scene, world_from_base)
            .into_iter()
            .map(|truth| self.measure(truth, rng))
            .collect();
        let [x, y, _] = self.mount_xyz_m;
        LaserScan {
            timestamp,
            angle_min_rad: -self.fov_rad / 2.0,
            angle_increment_rad: self.angle_increment_rad(),
            ranges_m,
            max_range_m: self.max_range_m,
            odometry: None,
            base_from_laser: Pose2::new(Vector2::new(x, y), 0.0),
        }
    }

    /// One reading from the true distance: noise, dropout, range limits, rounding.
    ///
    /// A dropout (a beam that hit something but returned nothing usable) reads 0, the invalid
    /// reading of real scanners; only a beam with nothing within range reads the maximum range
    /// ("no return"), which mappers use to clear free space.
    fn measure(&self, truth: Option<f64>, rng: &mut ChaCha8Rng) -> f64 {
        let noisy = self.noise().reading(truth, rng);
        match truth {
            Some(r) if r < self.min_range_m => 0.0,
            Some(_) => noisy.map_or(0.0, |r| r.clamp(self.min_range_m, self.max_range_m)),
            None => self.max_range_m,
        }
    }
}

/// The noise model the lidar's beams and the range finders share: Gaussian noise, dropouts,
/// rounding, a reading rate.
pub(crate) struct RangeNoise {
    /// Standard deviation of the noise \[m\].
    pub sigma_m: f64,
    /// Probability that a reading drops out.
    pub dropout_probability: f64,
    /// Readings are rounded to multiples of this \[m\].
    pub step_m: f64,
    /// Readings per second \[Hz\].
    pub rate_hz: f64,
}

impl RangeNoise {
    /// Whether a sensor can have these values.
    pub(crate) fn is_valid(&self) -> bool {
        self.sigma_m >= 0.0
            && (0.0..=1.0).contains(&self.dropout_probability)
            && self.step_m > 0.0
            && self.rate_hz > 0.0
    }

    /// The reading of the true distance `truth`: plus noise, rounded; `None` when nothing is in
    /// range or the reading drops out. It draws the same two random numbers (noise, then
    /// dropout) whatever `truth` is, so one reading's outcome does not shift the random stream
    /// of the next.
    pub(crate) fn reading(&self, truth: Option<f64>, rng: &mut ChaCha8Rng) -> Option<f64> {
        let noise: f64 = rng.sample(StandardNormal);
        let dropped = rng.gen_bool(self.dropout_probability);
        let r = truth.filter(|_| !dropped)?;
        Some(quantise(r + self.sigma_m * noise, self.step_m))
    }
}

/// `value` rounded to a multiple of `step`, as `k / (1 / step)` so that millimetre readings
/// print and parse back to the same number.
fn quantise(value: f64, step: f64) -> f64 {
    let per_unit = (1.0 / step).round();
    (value * per_unit).round() / per_unit
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::World;
    use rand::SeedableRng;

    fn box_room() -> Scene {
        let text = "name = \"t\"\nsize_m = [4.0, 4.0]\nheight_m = 2.0\n\
             flight_path = [[1, 1, 1, 0], [2, 1, 1, 0]]\ndrive_path = [[1, 1], [2, 1]]\n\
             nav_goal = [2, 2]\n[[boxes]]\ncenter = [2, 2]\nsize_m = [0.4, 0.4]\nz_m = [0, 0.5]\n";
        Scene::new(&World::from_toml(text, "t").unwrap())
    }

    #[test]
    fn beams_see_walls_at_their_angles() {
        let config = Lidar2dConfig::default();
        let scene = box_room();
        // 1 m from the x = 4 wall, facing it; lidar 5 cm above the base at z 1.0
        let pose = Pose3::new(Vector3::new(3.0, 2.0, 0.95), Vector3::zeros());
        let ranges = config.true_ranges(&scene, &pose);
        let inc = config.angle_increment_rad();
        for (i, r) in ranges.iter().enumerate() {
            let a = -config.fov_rad / 2.0 + i as f64 * inc;
            if a.abs() < 0.7 {
                assert!((r.unwrap() - 1.0 / a.cos()).abs() < 1e-9, "beam {i}");
            }
        }
        // backwards (beyond the fov) the box at 1 m is invisible; at 90 degrees left the
        // y = 4 wall is 2 m away
        let left = ((std::f64::consts::FRAC_PI_2 + config.fov_rad / 2.0) / inc).round() as usize;
        let a = -config.fov_rad / 2.0 + left as f64 * inc;
        assert!((ranges[left].unwrap() - 2.0 / a.sin()).abs() < 1e-9);
        // tilted 0.1 rad nose down, the lidar (5 cm above the base) leans forward by
        // 0.05 sin 0.1 and its forward beams slant down to the wall
        let tilted = Pose3::new(Vector3::new(3.0, 2.0, 0.95), Vector3::new(0.0, 0.1, 0.0));
        let mid = config.true_ranges(&scene, &tilted)[255..257].to_vec();
        let expected = (1.0 - 0.05 * 0.1f64.sin()) / 0.1f64.cos() / (inc / 2.0).cos();
        assert!(
            (mid[0].unwrap() - expected).abs() < 1e-9,
            "{mid:?} vs {expected}"
        );
    }

    #[test]
    fn noise_statistics_and_dropouts() {
        let config = Lidar2dConfig::default();
        let scene = box_room();
        let pose = Pose3::new(Vector3::new(3.0, 2.0, 0.95), Vector3::zeros());
        let truth = config.true_ranges(&scene, &pose);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (mut errors, mut dropouts, mut hits) = (Vec::new(), 0, 0);
        for k in 0..100 {
            let scan = config.scan(&scene, &pose, f64::from(k) * 0.1, &mut rng);
            for (measured, t) in scan.ranges_m.iter().zip(&truth) {
                let Some(t) = t.filter(|t| *t < config.max_range_m - 0.05) else {
                    continue;
                };
                hits += 1;
                if *measured == 0.0 {
                    dropouts += 1;
                } else {
                    errors.push(measured - t);
                }
            }
        }
        let n = errors.len() as f64;
        let mean = errors.iter().sum::<f64>() / n;
        let std = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
        assert!(mean.abs() < 2e-4, "mean {mean}");
        assert!((std - 0.01).abs() < 5e-4, "std {std}");
        let rate = f64::from(dropouts) / f64::from(hits);
        assert!((rate - 0.01).abs() < 0.003, "dropout rate {rate}");
        let scan = config.scan(&scene, &pose, 0.0, &mut rng);
        assert!(scan
            .ranges_m
            .iter()
            .all(|r| (r * 1000.0 - (r * 1000.0).round()).abs() < 1e-9));
    }
}
