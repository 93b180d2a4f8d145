//! Seeded random fixtures shared by the unit tests of this crate.

use crate::Pose3;
use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// A uniformly random vector in the cube `[-half, half]³`.
pub fn random_vector(rng: &mut ChaCha8Rng, half: f64) -> Vector3<f64> {
    let mut coord = || (rng.gen::<f64>() * 2.0 - 1.0) * half;
    Vector3::new(coord(), coord(), coord())
}

/// `n` points uniform in the cube `[-half, half]³`.
pub fn random_points(rng: &mut ChaCha8Rng, n: usize, half: f64) -> Vec<Point3<f64>> {
    (0..n)
        .map(|_| Point3::from(random_vector(rng, half)))
        .collect()
}

/// A random pose: rotation up to π about a random axis, translation within ±10 m.
pub fn random_pose(rng: &mut ChaCha8Rng) -> Pose3 {
    let axis_angle = random_vector(rng, 1.0).normalize() * rng.gen_range(0.0..std::f64::consts::PI);
    Pose3::from_parts(
        Translation3::from(random_vector(rng, 10.0)),
        UnitQuaternion::from_scaled_axis(axis_angle),
    )
}
