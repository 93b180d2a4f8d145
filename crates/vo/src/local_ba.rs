//! Local bundle adjustment: the poses of the recent keyframes and the map points they observe
//! refined together on their stereo reprojection error (Triggs et al., "Bundle Adjustment — A
//! Modern Synthesis", 1999; the local BA of ORB-SLAM2, Mur-Artal & Tardós, T-RO 2017).
//!
//! Each observation is a keyframe's measurement `(u, v, bf/z)` of a point: the pixel where it
//! was seen and the disparity of its measured depth (RGB-D through a virtual baseline, as
//! ORB-SLAM2), whitened by its covariance ([`MeasurementNoise`]: pixel noise in u and v, the
//! depth noise turned into disparity) so that a far point's uncertain depth counts less than
//! its pixel. A Huber kernel on the whitened error (in standard deviations) keeps a wrong match
//! from pulling the solution; the kernel's weights are re-evaluated each iteration
//! (iteratively reweighted least squares).
//!
//! Levenberg–Marquardt on left perturbations `T ← exp(δ) T` of each `camera_from_world`
//! (Barfoot, *State Estimation for Robotics*, §7.1) and additive point updates. The points are
//! many and the poses few, so each step eliminates the points first (the Schur complement,
//! Triggs et al. §6.1): every point's 3×3 block is inverted on its own, leaving a dense system
//! of 6 unknowns per free pose, solved by Cholesky; the point updates follow by back
//! substitution. The oldest keyframes are held fixed: they fix the gauge (the world frame)
//! and tie the window to the map before it.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix3x6, Matrix6, Matrix6x3, Point2, Point3, Vector3};
use serde::{Deserialize, Serialize};
use slamkit_core::Pose3;

use crate::error::VoError;
use crate::motion::{observation_covariance, project, MeasurementNoise, StereoCamera};

/// Local bundle adjustment settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LocalBaConfig {
    /// Refine the local map after each key frame. Off by default: it lowers 7-Scenes
    /// RedKitchen's `--slam` ATE (KLT 0.0351 → 0.0325 m, ORB 0.0446 → 0.0344 m) but raises
    /// the simulated office robot's (`slamkit nav --world office --seed 1`: mean localisation
    /// error 0.041 → 0.091 m, largest 0.094 → 0.299 m, goal missed), and why is not known yet.
    pub enabled: bool,
    /// The newest this many key frames are adjusted \[key frames\].
    pub window_keyframes: usize,
    /// The oldest this many of them are held fixed (the gauge) \[key frames\].
    pub fixed_keyframes: usize,
    /// Levenberg–Marquardt iterations at most.
    pub iterations: usize,
    /// Huber threshold of the whitened error \[standard deviations\]; √7.815, the χ² 95 %
    /// quantile of 3 degrees of freedom, as ORB-SLAM2.
    pub huber_sigma: f64,
}

impl Default for LocalBaConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            window_keyframes: 10,
            fixed_keyframes: 2,
            iterations: 5,
            huber_sigma: 7.815_f64.sqrt(),
        }
    }
}

impl LocalBaConfig {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`VoError::InvalidConfig`] for a window not larger than its fixed key frames, no fixed
    /// key frame, or a threshold that is not positive and finite.
    pub fn validate(&self) -> Result<(), VoError> {
        if self.fixed_keyframes == 0 {
            return Err(VoError::config(
                "local_map.bundle.fixed_keyframes",
                0,
                "must be > 0",
            ));
        }
        if self.window_keyframes <= self.fixed_keyframes {
            return Err(VoError::config(
                "local_map.bundle.window_keyframes",
                self.window_keyframes,
                "must be > fixed_keyframes",
            ));
        }
        if !(self.huber_sigma.is_finite() && self.huber_sigma > 0.0) {
            return Err(VoError::config(
                "local_map.bundle.huber_sigma",
                self.huber_sigma,
                "must be finite and > 0",
            ));
        }
        Ok(())
    }
}

/// One keyframe's measurement of one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BundleObservation {
    /// Index of the keyframe in [`Bundle::camera_from_world`].
    pub keyframe: usize,
    /// Index of the point in [`Bundle::points`].
    pub point: usize,
    /// Where the point was seen \[px\].
    pub pixel: Point2<f64>,
    /// Its measured depth \[m\].
    pub depth_m: f64,
}

/// Keyframe poses, points and observations; the adjustment refines poses and points in place.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Bundle {
    /// Per keyframe, `camera_from_world`.
    pub camera_from_world: Vec<Pose3>,
    /// Per keyframe, true when its pose is held.
    pub fixed: Vec<bool>,
    /// World points \[m\].
    pub points: Vec<Point3<f64>>,
    /// The observations.
    pub observations: Vec<BundleObservation>,
}

/// What an adjustment did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BundleSummary {
    /// Robust cost before \[σ²\].
    pub initial_cost: f64,
    /// Robust cost after \[σ²\].
    pub final_cost: f64,
    /// Accepted steps.
    pub steps: usize,
    /// Observations beyond the Huber threshold at the end.
    pub outliers: usize,
}

/// Whitened residual of observation `o` and its Jacobians (pose, point); `None` behind the
/// camera.
type Linearised = (Vector3<f64>, Matrix3x6<f64>, Matrix3<f64>);

/// The terms of one bundle: camera, per observation its whitening (`L⁻¹` of the measurement
/// covariance, diagonal) and its measurement.
struct Terms<'a> {
    cam: &'a StereoCamera,
    /// Per observation: measurement `(u, v, bf/z)` and the inverse standard deviations.
    measured: Vec<(Vector3<f64>, Vector3<f64>)>,
    huber: f64,
}

impl<'a> Terms<'a> {
    fn new(bundle: &Bundle, cam: &'a StereoCamera, noise: &MeasurementNoise, huber: f64) -> Self {
        let measured = bundle
            .observations
            .iter()
            .map(|o| {
                let z = o.depth_m;
                let at = Point3::new(0.0, 0.0, z);
                let c = observation_covariance(cam, noise, &at);
                let disparity = if cam.bf > 0.0 { cam.bf / z } else { 0.0 };
                let inv = Vector3::new(
                    c[(0, 0)].sqrt().recip(),
                    c[(1, 1)].sqrt().recip(),
                    if cam.bf > 0.0 {
                        c[(2, 2)].sqrt().recip()
                    } else {
                        0.0
                    },
                );
                let ok = z.is_finite() && z > 0.0 && inv.iter().all(|v| v.is_finite());
                let m = Vector3::new(o.pixel.x, o.pixel.y, disparity);
                (m, if ok { inv } else { Vector3::zeros() })
            })
            .collect();
        Self {
            cam,
            measured,
            huber,
        }
    }

    fn linearise(
        &self,
        i: usize,
        t: &Pose3,
        p: &Point3<f64>,
        with_jacobians: bool,
    ) -> Option<Linearised> {
        let (m, inv) = self.measured.get(i)?;
        let q = t * p;
        let (pred, jq) = project(self.cam, &q)?;
        let w = Matrix3::from_diagonal(inv);
        let r = w * (pred - m);
        if !with_jacobians {
            return Some((r, Matrix3x6::zeros(), Matrix3::zeros()));
        }
        let wj = w * jq;
        let mut jp = Matrix3x6::zeros();
        jp.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(-wj * q.coords.cross_matrix()));
        jp.fixed_view_mut::<3, 3>(0, 3).copy_from(&wj);
        let jl = wj * t.rotation.to_rotation_matrix().into_inner();
        Some((r, jp, jl))
    }

    /// Huber cost of a whitened error `e` \[σ\].
    fn rho(&self, e: f64) -> f64 {
        if e <= self.huber {
            e * e
        } else {
            2.0 * self.huber * e - self.huber * self.huber
        }
    }

    fn cost(&self, bundle: &Bundle, poses: &[Pose3], points: &[Point3<f64>]) -> f64 {
        bundle
            .observations
            .iter()
            .enumerate()
            .filter_map(|(i, o)| {
                let (r, _, _) =
                    self.linearise(i, poses.get(o.keyframe)?, points.get(o.point)?, false)?;
                Some(self.rho(r.norm()))
            })
            .sum()
    }
}

/// Refines `bundle`'s free poses and its points by Levenberg–Marquardt on the Huber-weighted
/// whitened stereo reprojection error, seen by `cam` with `noise`; keeps them where no step
/// lowers the cost.
///
/// ```
/// use nalgebra::{Point2, Point3, Vector3};
/// use slamkit_core::camera::Intrinsics;
/// use slamkit_core::Pose3;
/// use slamkit_vo::local_ba::{adjust, Bundle, BundleObservation, LocalBaConfig};
/// use slamkit_vo::motion::{MeasurementNoise, StereoCamera};
///
/// let cam = StereoCamera { k: Intrinsics::from_array([500.0, 500.0, 320.0, 240.0], 640, 480), bf: 40.0 };
/// let truth = [Pose3::identity(), Pose3::translation(-0.2, 0.0, 0.0)];
/// let points: Vec<Point3<f64>> = (0..20)
///     .map(|i| Point3::new(f64::from(i % 5) * 0.3 - 0.6, f64::from(i / 5) * 0.3 - 0.45, 3.0))
///     .collect();
/// let mut observations = Vec::new();
/// for (keyframe, t) in truth.iter().enumerate() {
///     for (point, p) in points.iter().enumerate() {
///         let q = t * p;
///         let pixel = Point2::new(500.0 * q.x / q.z + 320.0, 500.0 * q.y / q.z + 240.0);
///         observations.push(BundleObservation { keyframe, point, pixel, depth_m: q.z });
///     }
/// }
/// let mut bundle = Bundle {
///     camera_from_world: vec![truth[0], Pose3::translation(-0.15, 0.02, 0.03)],
///     fixed: vec![true, false],
///     points,
///     observations,
/// };
/// adjust(&mut bundle, &cam, &MeasurementNoise::default(), &LocalBaConfig::default());
/// let error = (bundle.camera_from_world[1].translation.vector - truth[1].translation.vector).norm();
/// assert!(error < 1e-6);
/// ```
pub fn adjust(
    bundle: &mut Bundle,
    cam: &StereoCamera,
    noise: &MeasurementNoise,
    config: &LocalBaConfig,
) -> BundleSummary {
    let terms = Terms::new(bundle, cam, noise, config.huber_sigma);
    let mut free_index: Vec<Option<usize>> = Vec::with_capacity(bundle.camera_from_world.len());
    let mut free = 0;
    for k in 0..bundle.camera_from_world.len() {
        if bundle.fixed.get(k).copied().unwrap_or(true) {
            free_index.push(None);
        } else {
            free_index.push(Some(free));
            free += 1;
        }
    }
    let mut by_point: Vec<Vec<usize>> = vec![Vec::new(); bundle.points.len()];
    for (i, o) in bundle.observations.iter().enumerate() {
        if let Some(v) = by_point.get_mut(o.point) {
            v.push(i);
        }
    }
    let initial_cost = terms.cost(bundle, &bundle.camera_from_world, &bundle.points);
    let mut cost = initial_cost;
    let mut lambda = 1e-4;
    let mut steps = 0;
    for _ in 0..config.iterations {
        let system = normal_equations(bundle, &terms, &free_index, free, &by_point);
        let mut accepted = false;
        // a rejected step raises the damping and tries again from the same linearisation
        for _ in 0..6 {
            let Some((poses, points)) = solve(bundle, &system, &free_index, free, lambda) else {
                lambda *= 10.0;
                continue;
            };
            let new_cost = terms.cost(bundle, &poses, &points);
            if new_cost.is_finite() && new_cost < cost {
                let converged = cost - new_cost < 1e-9 * cost;
                bundle.camera_from_world = poses;
                bundle.points = points;
                cost = new_cost;
                lambda = (lambda / 10.0).max(1e-9);
                steps += 1;
                accepted = !converged;
                break;
            }
            lambda *= 10.0;
        }
        if !accepted {
            break;
        }
    }
    let outliers = bundle
        .observations
        .iter()
        .enumerate()
        .filter(|(i, o)| {
            let (Some(t), Some(p)) = (
                bundle.camera_from_world.get(o.keyframe),
                bundle.points.get(o.point),
            ) else {
                return false;
            };
            terms
                .linearise(*i, t, p, false)
                .map_or(true, |(r, _, _)| r.norm() > config.huber_sigma)
        })
        .count();
    BundleSummary {
        initial_cost,
        final_cost: cost,
        steps,
        outliers,
    }
}

/// The Gauss–Newton system at the current estimate, Huber-weighted: per free pose its 6×6
/// block and gradient, per pose pair the off-diagonal blocks, per point its 3×3 block and
/// gradient, per observation the pose–point block.
struct NormalEquations {
    pose_blocks: Vec<Matrix6<f64>>,
    pose_gradient: Vec<nalgebra::Vector6<f64>>,
    point_blocks: Vec<Matrix3<f64>>,
    point_gradient: Vec<Vector3<f64>>,
    /// Per observation: `J_poseᵀ W J_point` (zero for a fixed pose or a point behind).
    cross: Vec<Matrix6x3<f64>>,
    by_point: Vec<Vec<usize>>,
}

fn normal_equations(
    bundle: &Bundle,
    terms: &Terms,
    free_index: &[Option<usize>],
    free: usize,
    by_point: &[Vec<usize>],
) -> NormalEquations {
    let mut s = NormalEquations {
        pose_blocks: vec![Matrix6::zeros(); free],
        pose_gradient: vec![nalgebra::Vector6::zeros(); free],
        point_blocks: vec![Matrix3::zeros(); bundle.points.len()],
        point_gradient: vec![Vector3::zeros(); bundle.points.len()],
        cross: vec![Matrix6x3::zeros(); bundle.observations.len()],
        by_point: by_point.to_vec(),
    };
    for (i, o) in bundle.observations.iter().enumerate() {
        let (Some(t), Some(p)) = (
            bundle.camera_from_world.get(o.keyframe),
            bundle.points.get(o.point),
        ) else {
            continue;
        };
        let Some((r, jp, jl)) = terms.linearise(i, t, p, true) else {
            continue;
        };
        let e = r.norm();
        let w = if e <= terms.huber {
            1.0
        } else {
            terms.huber / e
        };
        if let (Some(b), Some(g)) = (
            s.point_blocks.get_mut(o.point),
            s.point_gradient.get_mut(o.point),
        ) {
            *b += w * jl.transpose() * jl;
            *g += w * jl.transpose() * r;
        }
        if let Some(k) = free_index.get(o.keyframe).copied().flatten() {
            if let (Some(b), Some(g)) = (s.pose_blocks.get_mut(k), s.pose_gradient.get_mut(k)) {
                *b += w * jp.transpose() * jp;
                *g += w * jp.transpose() * r;
            }
            if let Some(c) = s.cross.get_mut(i) {
                *c = w * jp.transpose() * jl;
            }
        }
    }
    s
}

/// One damped step: the points eliminated (Schur complement), the poses' system solved by
/// Cholesky, the points back-substituted; the moved poses and points, or `None` when the
/// reduced system is not positive definite.
fn solve(
    bundle: &Bundle,
    s: &NormalEquations,
    free_index: &[Option<usize>],
    free: usize,
    lambda: f64,
) -> Option<(Vec<Pose3>, Vec<Point3<f64>>)> {
    let n = 6 * free;
    let mut reduced = DMatrix::<f64>::zeros(n, n);
    let mut rhs = DVector::<f64>::zeros(n);
    for (k, (b, g)) in s.pose_blocks.iter().zip(&s.pose_gradient).enumerate() {
        let mut damped = *b;
        for d in 0..6 {
            damped[(d, d)] += lambda * (b[(d, d)] + 1e-9);
        }
        reduced
            .fixed_view_mut::<6, 6>(6 * k, 6 * k)
            .copy_from(&damped);
        rhs.fixed_rows_mut::<6>(6 * k).copy_from(&(-g));
    }
    let damp3 = |b: &Matrix3<f64>| {
        let mut d = *b;
        for i in 0..3 {
            d[(i, i)] += lambda * (b[(i, i)] + 1e-9);
        }
        d
    };
    // per point: V⁻¹, or None for a point without a usable block (it stays)
    let inverses: Vec<Option<Matrix3<f64>>> = s
        .point_blocks
        .iter()
        .map(|b| damp3(b).try_inverse())
        .collect();
    let pose_of = |i: usize| {
        bundle
            .observations
            .get(i)
            .and_then(|o| free_index.get(o.keyframe).copied().flatten())
    };
    for (l, obs) in s.by_point.iter().enumerate() {
        let (Some(Some(v_inv)), Some(gl)) = (inverses.get(l), s.point_gradient.get(l)) else {
            continue;
        };
        for &a in obs {
            let (Some(ka), Some(wa)) = (pose_of(a), s.cross.get(a)) else {
                continue;
            };
            let wv = wa * v_inv;
            let mut r = rhs.fixed_rows_mut::<6>(6 * ka);
            r += wv * gl;
            for &b in obs {
                let (Some(kb), Some(wb)) = (pose_of(b), s.cross.get(b)) else {
                    continue;
                };
                let mut block = reduced.fixed_view_mut::<6, 6>(6 * ka, 6 * kb);
                block -= wv * wb.transpose();
            }
        }
    }
    let dx = if n == 0 {
        DVector::zeros(0)
    } else {
        reduced.cholesky()?.solve(&rhs)
    };
    let poses: Vec<Pose3> = bundle
        .camera_from_world
        .iter()
        .zip(free_index)
        .map(|(t, k)| match k {
            Some(k) => {
                let d = dx.fixed_rows::<6>(6 * k);
                let step = Pose3::new(
                    Vector3::new(d[3], d[4], d[5]),
                    Vector3::new(d[0], d[1], d[2]),
                );
                step * t
            }
            None => *t,
        })
        .collect();
    let points: Vec<Point3<f64>> = bundle
        .points
        .iter()
        .enumerate()
        .map(|(l, p)| {
            let (Some(Some(v_inv)), Some(gl), Some(obs)) =
                (inverses.get(l), s.point_gradient.get(l), s.by_point.get(l))
            else {
                return *p;
            };
            let mut g = -gl;
            for &a in obs {
                if let (Some(ka), Some(wa)) = (pose_of(a), s.cross.get(a)) {
                    g -= wa.transpose() * dx.fixed_rows::<6>(6 * ka);
                }
            }
            p + v_inv * g
        })
        .collect();
    Some((poses, points))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use slamkit_core::camera::Intrinsics;

    fn camera() -> StereoCamera {
        StereoCamera {
            k: Intrinsics::from_array([500.0, 500.0, 320.0, 240.0], 640, 480),
            bf: 40.0,
        }
    }

    /// Six keyframes along a curve looking at 120 points 2–6 m ahead, observed exactly; the
    /// bundle starts from poses off by centimetres and degrees and points off by 5 cm.
    fn scene(rng: &mut rand_chacha::ChaCha8Rng) -> (Vec<Pose3>, Vec<Point3<f64>>, Bundle) {
        let cam = camera();
        let truth: Vec<Pose3> = (0..6)
            .map(|i| {
                let s = f64::from(i);
                Pose3::new(
                    Vector3::new(0.1 * s, 0.02 * s * s, 0.15 * s),
                    Vector3::new(0.01 * s, -0.03 * s, 0.005 * s),
                )
                .inverse()
            })
            .collect();
        let points: Vec<Point3<f64>> = (0..120)
            .map(|_| {
                Point3::new(
                    rng.gen_range(-2.0..2.0),
                    rng.gen_range(-1.5..1.5),
                    rng.gen_range(2.5..6.5),
                )
            })
            .collect();
        let mut observations = Vec::new();
        for (keyframe, t) in truth.iter().enumerate() {
            for (point, p) in points.iter().enumerate() {
                let q = t * p;
                let pixel = cam.k.to_pixel(&Point2::new(q.x / q.z, q.y / q.z));
                if q.z > 0.0 && cam.k.contains(&pixel) {
                    observations.push(BundleObservation {
                        keyframe,
                        point,
                        pixel,
                        depth_m: q.z,
                    });
                }
            }
        }
        let start: Vec<Pose3> = truth
            .iter()
            .enumerate()
            .map(|(i, t)| {
                if i < 2 {
                    return *t;
                }
                let jitter = Pose3::new(
                    Vector3::new(
                        rng.gen_range(-0.05..0.05),
                        rng.gen_range(-0.05..0.05),
                        rng.gen_range(-0.05..0.05),
                    ),
                    Vector3::new(
                        rng.gen_range(-0.03..0.03),
                        rng.gen_range(-0.03..0.03),
                        rng.gen_range(-0.03..0.03),
                    ),
                );
                jitter * t
            })
            .collect();
        let noisy: Vec<Point3<f64>> = points
            .iter()
            .map(|p| {
                p + Vector3::new(
                    rng.gen_range(-0.05..0.05),
                    rng.gen_range(-0.05..0.05),
                    rng.gen_range(-0.05..0.05),
                )
            })
            .collect();
        let bundle = Bundle {
            camera_from_world: start,
            fixed: (0..6).map(|i| i < 2).collect(),
            points: noisy,
            observations,
        };
        (truth, points, bundle)
    }

    fn worst_pose_error(bundle: &Bundle, truth: &[Pose3]) -> f64 {
        bundle
            .camera_from_world
            .iter()
            .zip(truth)
            .map(|(a, b)| (a.inverse().translation.vector - b.inverse().translation.vector).norm())
            .fold(0.0, f64::max)
    }

    #[test]
    fn noisy_poses_and_points_converge_to_the_truth() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (truth, points, mut bundle) = scene(&mut rng);
        assert!(worst_pose_error(&bundle, &truth) > 0.02);
        let config = LocalBaConfig {
            iterations: 20,
            ..LocalBaConfig::default()
        };
        let summary = adjust(
            &mut bundle,
            &camera(),
            &MeasurementNoise::default(),
            &config,
        );
        assert!(
            summary.final_cost < 1e-12 * summary.initial_cost,
            "{summary:?}"
        );
        assert!(worst_pose_error(&bundle, &truth) < 1e-6);
        for (t, b) in truth.iter().zip(&bundle.camera_from_world) {
            assert!(t.rotation.angle_to(&b.rotation) < 1e-7);
        }
        // every point some keyframe sees (a point no keyframe sees has nothing to move it)
        let worst_point = bundle
            .observations
            .iter()
            .map(|o| (bundle.points[o.point] - points[o.point]).norm())
            .fold(0.0, f64::max);
        assert!(worst_point < 1e-6, "{worst_point}");
        assert_eq!(summary.outliers, 0);
        // the held keyframes stay where they were
        assert_eq!(bundle.camera_from_world[..2], truth[..2]);
    }

    #[test]
    fn the_huber_kernel_ignores_a_wrong_match() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
        let (truth, _, mut bundle) = scene(&mut rng);
        // a few observations of the last keyframe matched to the wrong feature, 40 px off
        let last = bundle.camera_from_world.len() - 1;
        let mut moved = 0;
        for o in bundle
            .observations
            .iter_mut()
            .filter(|o| o.keyframe == last)
        {
            if moved < 4 {
                o.pixel.x += 40.0;
                moved += 1;
            }
        }
        let robust = LocalBaConfig {
            iterations: 20,
            ..LocalBaConfig::default()
        };
        let plain = LocalBaConfig {
            huber_sigma: 1e9,
            ..robust.clone()
        };
        let mut least_squares = bundle.clone();
        let summary = adjust(
            &mut bundle,
            &camera(),
            &MeasurementNoise::default(),
            &robust,
        );
        adjust(
            &mut least_squares,
            &camera(),
            &MeasurementNoise::default(),
            &plain,
        );
        let with_kernel = worst_pose_error(&bundle, &truth);
        let without = worst_pose_error(&least_squares, &truth);
        assert_eq!(summary.outliers, 4, "{summary:?}");
        assert!(with_kernel < 2e-3, "{with_kernel}");
        assert!(without > 3.0 * with_kernel, "{without} vs {with_kernel}");
    }

    #[test]
    fn bad_settings_are_rejected() {
        for bad in [
            LocalBaConfig {
                fixed_keyframes: 0,
                ..LocalBaConfig::default()
            },
            LocalBaConfig {
                window_keyframes: 2,
                ..LocalBaConfig::default()
            },
            LocalBaConfig {
                huber_sigma: f64::NAN,
                ..LocalBaConfig::default()
            },
        ] {
            assert!(bad.validate().is_err());
        }
        assert!(LocalBaConfig::default().validate().is_ok());
    }
}
