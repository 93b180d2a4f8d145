//! Floor alignment: a map frame whose x–z plane is the floor.
//!
//! A camera on a ground robot sees the floor in the lower part of its image. The floor plane is
//! fitted to points on it, either robustly with RANSAC (M. A. Fischler, R. C. Bolles, "Random
//! sample consensus", CACM 24(6), 1981: three points fix a plane, the plane with most points
//! within `threshold_m` wins and is refitted to them by least squares), the default, or, as the
//! seed robot did, through the averages of three image regions. The rotation that turns the
//! floor's upward normal onto the map's up axis comes from Rodrigues' formula
//! `R = I + [v]× + [v]×² (1 − c) / s²`, with `v = n × u`, `s = |v|`, `c = n · u`.
//!
//! The map frame keeps the camera's conventions (x right, y down, z forward), so a level camera
//! gets no rotation: up is −y and the floor is the plane y = 0. A point's height above the floor
//! is `-y` in the map frame; its floor coordinates are `(x, z)`.

use nalgebra::{Matrix3, Point3, Rotation3, Translation3, Unit, Vector3};
use serde::{Deserialize, Serialize};
use slamkit_core::{ransac, Estimator, GeometryError, Pose3, RansacConfig};

/// Why no floor could be found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FloorError {
    /// Fewer finite points than a plane needs.
    #[error("floor fit needs at least {min} finite points, got {got}")]
    TooFewPoints {
        /// Finite points given.
        got: usize,
        /// Points needed.
        min: usize,
    },
    /// The points are collinear or coincide, so they fix no plane.
    #[error("floor points are degenerate (collinear or coincident)")]
    Degenerate,
    /// RANSAC found no plane with enough support.
    #[error("no floor plane: {0}")]
    NoPlane(#[from] GeometryError),
    /// The plane passes through (or within 1 mm of) the camera, so up is undefined.
    #[error("floor plane passes through the camera ({distance_m} m away)")]
    CameraOnPlane {
        /// Camera distance from the plane \[m\].
        distance_m: f64,
    },
}

/// A plane `normal · p + offset = 0`, `normal` of unit length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// Unit normal.
    pub normal: Unit<Vector3<f64>>,
    /// Signed offset \[m\]: minus the distance of the origin along the normal.
    pub offset_m: f64,
}

impl Plane {
    /// The plane through three points, or `None` when they are (nearly) collinear.
    pub fn through(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> Option<Plane> {
        let n = (b - a).cross(&(c - a));
        let scale = (b - a).norm() * (c - a).norm();
        if !(n.norm() > 1e-9 * scale && scale > 0.0) {
            return None;
        }
        let normal = Unit::new_normalize(n);
        Some(Plane {
            normal,
            offset_m: -normal.dot(&a.coords),
        })
    }

    /// Least-squares plane: through the centroid, normal along the covariance's smallest
    /// eigenvector. `None` for fewer than three points or a degenerate set.
    pub fn fit(points: &[Point3<f64>]) -> Option<Plane> {
        if points.len() < 3 {
            return None;
        }
        let centroid = points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len() as f64;
        let cov = points.iter().fold(Matrix3::zeros(), |m, p| {
            let d = p.coords - centroid;
            m + d * d.transpose()
        });
        let eig = cov.symmetric_eigen();
        let mut order = [0, 1, 2];
        order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
        // A plane needs spread along two axes.
        let spread = eig.eigenvalues[order[1]] > 1e-12 * eig.eigenvalues[order[2]].max(1e-300);
        if !spread {
            return None;
        }
        let normal = Unit::new_normalize(eig.eigenvectors.column(order[0]).into_owned());
        Some(Plane {
            normal,
            offset_m: -normal.dot(&centroid),
        })
    }

    /// Signed distance of `p` from the plane \[m\], positive on the normal's side.
    pub fn signed_distance_m(&self, p: &Point3<f64>) -> f64 {
        self.normal.dot(&p.coords) + self.offset_m
    }
}

/// RANSAC's plane model: three points per sample, residual the distance to the plane \[m\].
#[derive(Debug, Clone, Copy, Default)]
pub struct PlaneEstimator;

impl Estimator for PlaneEstimator {
    type Datum = Point3<f64>;
    type Model = Plane;

    fn sample_size(&self) -> usize {
        3
    }

    fn fit_sample(&self, data: &[Point3<f64>], sample: &[usize]) -> Result<Plane, GeometryError> {
        match (
            data.get(sample[0]),
            data.get(sample[1]),
            data.get(sample[2]),
        ) {
            (Some(a), Some(b), Some(c)) => Plane::through(a, b, c).ok_or(degenerate()),
            _ => Err(degenerate()),
        }
    }

    fn fit_inliers(&self, data: &[Point3<f64>], inliers: &[usize]) -> Result<Plane, GeometryError> {
        let points: Vec<Point3<f64>> = inliers
            .iter()
            .filter_map(|&i| data.get(i))
            .copied()
            .collect();
        Plane::fit(&points).ok_or(degenerate())
    }

    fn residual(&self, model: &Plane, datum: &Point3<f64>) -> f64 {
        model.signed_distance_m(datum).abs()
    }
}

fn degenerate() -> GeometryError {
    GeometryError::Degenerate { set: "floor" }
}

/// Settings of the RANSAC floor fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FloorConfig {
    /// Points within this distance of a plane support it \[m\].
    pub threshold_m: f64,
    /// Fewest supporting points for a floor.
    pub min_inliers: usize,
    /// Upper limit on RANSAC samples.
    pub max_iterations: u32,
    /// Seed of RANSAC's sampling.
    pub seed: u64,
}

impl Default for FloorConfig {
    fn default() -> Self {
        Self {
            threshold_m: 0.02,
            min_inliers: 50,
            max_iterations: 500,
            seed: 0,
        }
    }
}

/// The floor plane fitted robustly to `points` (camera frame); NaN and infinite points are
/// ignored.
///
/// # Errors
/// [`FloorError::TooFewPoints`] with fewer than three finite points, [`FloorError::NoPlane`]
/// when no plane gathers `min_inliers`.
pub fn fit_floor_ransac(points: &[Point3<f64>], config: &FloorConfig) -> Result<Plane, FloorError> {
    let finite: Vec<Point3<f64>> = points
        .iter()
        .filter(|p| p.coords.iter().all(|v| v.is_finite()))
        .copied()
        .collect();
    if finite.len() < 3 {
        return Err(FloorError::TooFewPoints {
            got: finite.len(),
            min: 3,
        });
    }
    let ransac_config = RansacConfig {
        threshold: config.threshold_m,
        max_iterations: config.max_iterations,
        min_inliers: config.min_inliers,
        seed: config.seed,
        ..RansacConfig::default()
    };
    Ok(ransac(&PlaneEstimator, &finite, &ransac_config)?.model)
}

/// The seed robot's floor: the plane through the means of three regions of floor points (e.g.
/// three patches at the bottom of the depth image). Non-finite points are ignored.
///
/// # Errors
/// [`FloorError::TooFewPoints`] when a region has no finite point, [`FloorError::Degenerate`]
/// when the three means are collinear.
pub fn fit_floor_regions(regions: [&[Point3<f64>]; 3]) -> Result<Plane, FloorError> {
    let mut means = [Point3::origin(); 3];
    for (mean, region) in means.iter_mut().zip(regions) {
        let finite: Vec<&Point3<f64>> = region
            .iter()
            .filter(|p| p.coords.iter().all(|v| v.is_finite()))
            .collect();
        if finite.is_empty() {
            return Err(FloorError::TooFewPoints { got: 0, min: 1 });
        }
        *mean = Point3::from(
            finite.iter().map(|p| p.coords).sum::<Vector3<f64>>() / finite.len() as f64,
        );
    }
    Plane::through(&means[0], &means[1], &means[2]).ok_or(FloorError::Degenerate)
}

/// The rotation turning unit vector `from` onto unit vector `to`, by Rodrigues' formula; a half
/// turn about an axis perpendicular to `from` when they are opposite.
pub fn rotation_between(from: &Unit<Vector3<f64>>, to: &Unit<Vector3<f64>>) -> Rotation3<f64> {
    let v = from.cross(to);
    let c = from.dot(to);
    let s2 = v.norm_squared();
    if s2 < 1e-24 {
        if c > 0.0 {
            return Rotation3::identity();
        }
        // Any axis perpendicular to `from`.
        let helper = if from.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let axis = Unit::new_normalize(from.cross(&helper));
        return Rotation3::from_axis_angle(&axis, std::f64::consts::PI);
    }
    let k = v.cross_matrix();
    Rotation3::from_matrix_unchecked(Matrix3::identity() + k + k * k * ((1.0 - c) / s2))
}

/// The map frame of a floor seen from a camera at the camera frame's origin: `map_from_camera`
/// rotates the floor's upward normal (the side the camera is on) onto −y and puts the floor at
/// y = 0, keeping the camera straight above the map origin.
///
/// # Errors
/// [`FloorError::CameraOnPlane`] when the camera is within 1 mm of the plane.
pub fn map_from_camera(floor: &Plane) -> Result<Pose3, FloorError> {
    let distance_m = floor.signed_distance_m(&Point3::origin());
    let above = distance_m.abs() > 1e-3; // false for NaN too
    if !above {
        return Err(FloorError::CameraOnPlane { distance_m });
    }
    let up = if distance_m > 0.0 {
        floor.normal
    } else {
        -floor.normal
    };
    let rotation = rotation_between(&up, &-Vector3::y_axis());
    // The camera sits |distance| above the floor: after rotation it is at y = -|distance|.
    let translation = Translation3::new(0.0, -distance_m.abs(), 0.0);
    Ok(Pose3::from_parts(translation, rotation.into()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A floor 1.2 m below a camera pitched 25° down and rolled 5°, with 30 % clutter.
    fn tilted_floor(seed: u64) -> (Vec<Point3<f64>>, Pose3) {
        let camera_from_map = Pose3::from_parts(
            Translation3::new(0.0, 0.0, 0.0),
            (Rotation3::from_euler_angles(25f64.to_radians(), 0.0, 5f64.to_radians())).into(),
        ) * Pose3::translation(0.0, 1.2, 0.0);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut points = Vec::new();
        for i in 0..400 {
            let p = if i % 10 < 7 {
                Point3::new(
                    rng.gen_range(-1.5..1.5),
                    rng.gen_range(-0.003..0.003),
                    rng.gen_range(0.5..4.0),
                )
            } else {
                Point3::new(
                    rng.gen_range(-1.5..1.5),
                    rng.gen_range(-1.5..-0.1),
                    rng.gen_range(0.5..4.0),
                )
            };
            points.push(camera_from_map * p);
        }
        (points, camera_from_map.inverse())
    }

    #[test]
    fn ransac_floor_levels_a_tilted_camera() {
        let (mut points, truth) = tilted_floor(3);
        points.push(Point3::new(f64::NAN, 0.0, 1.0));
        let plane = fit_floor_ransac(&points, &FloorConfig::default()).unwrap();
        let map_from_camera = map_from_camera(&plane).unwrap();
        // Floor points land on y = 0, the camera 1.2 m above it.
        let on_floor = points.iter().take(7).map(|p| map_from_camera * p);
        for p in on_floor {
            assert!(p.y.abs() < 0.01, "{p}");
        }
        assert!((map_from_camera.translation.y + 1.2).abs() < 0.005);
        // Up agrees with the truth: the rotations differ only by a yaw about y.
        let up = map_from_camera.rotation * truth.rotation.inverse() * Vector3::y();
        assert!((up - Vector3::y()).norm() < 0.01, "{up}");
    }

    #[test]
    fn three_regions_give_the_same_floor() {
        let (points, truth) = tilted_floor(4);
        // Three patches of floor: near left, near right, far.
        let patch = |keep: fn(&Point3<f64>) -> bool| -> Vec<Point3<f64>> {
            points
                .iter()
                .take(380)
                .enumerate()
                .filter(|(i, p)| i % 10 < 7 && keep(&(truth * *p)))
                .map(|(_, p)| *p)
                .collect()
        };
        let a = patch(|p| p.x < -0.5 && p.z < 2.0);
        let b = patch(|p| p.x > 0.5 && p.z < 2.0);
        let c = patch(|p| p.z > 3.0);
        let (a, b, c) = (a.as_slice(), b.as_slice(), c.as_slice());
        let regions = fit_floor_regions([a, b, c]).unwrap();
        assert!(a.len() > 10 && b.len() > 10 && c.len() > 10);
        let ransac = fit_floor_ransac(&points, &FloorConfig::default()).unwrap();
        assert!(regions.normal.dot(&ransac.normal).abs() > 0.999);
    }

    #[test]
    fn rodrigues_turns_vectors_onto_each_other() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..100 {
            let a = Unit::new_normalize(Vector3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            ));
            let b = Unit::new_normalize(Vector3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            ));
            let r = rotation_between(&a, &b);
            assert!((r * a.into_inner() - b.into_inner()).norm() < 1e-9);
            assert!((r.matrix().determinant() - 1.0).abs() < 1e-9);
        }
        let x = Vector3::x_axis();
        assert!((rotation_between(&x, &-x) * Vector3::x() + Vector3::x()).norm() < 1e-12);
        assert_eq!(rotation_between(&x, &x), Rotation3::identity());
    }

    #[test]
    fn bad_input_gives_errors() {
        let nan = [Point3::new(f64::NAN, 0.0, 0.0); 10];
        assert!(matches!(
            fit_floor_ransac(&nan, &FloorConfig::default()),
            Err(FloorError::TooFewPoints { .. })
        ));
        assert!(matches!(
            fit_floor_ransac(&[], &FloorConfig::default()),
            Err(FloorError::TooFewPoints { .. })
        ));
        let line: Vec<Point3<f64>> = (0..100)
            .map(|i| Point3::new(f64::from(i), 1.0, 1.0))
            .collect();
        assert!(fit_floor_ransac(&line, &FloorConfig::default()).is_err());
        let p = [Point3::new(0.0, 1.0, 1.0)];
        assert!(matches!(
            fit_floor_regions([&p, &p, &p]),
            Err(FloorError::Degenerate)
        ));
        assert!(matches!(
            fit_floor_regions([&p, &[], &p]),
            Err(FloorError::TooFewPoints { .. })
        ));
        let through_camera = Plane::through(
            &Point3::new(1.0, 0.0, 0.0),
            &Point3::new(0.0, 0.0, 1.0),
            &Point3::origin(),
        )
        .unwrap();
        assert!(matches!(
            map_from_camera(&through_camera),
            Err(FloorError::CameraOnPlane { .. })
        ));
    }
}
