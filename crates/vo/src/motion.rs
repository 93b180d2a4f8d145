//! Frame-to-reference motion from 3D–3D feature correspondences.
//!
//! 1. RANSAC (Fischler & Bolles, CACM 1981) over minimal 3-point samples, each fitted in closed
//!    form by Horn's quaternion method (B. K. P. Horn, "Closed-form solution of absolute
//!    orientation using unit quaternions", JOSA A 4(4), 1987); the draw count adapts to the
//!    inlier ratio (Hartley & Zisserman 2004, eq. 4.18) — both from `slamkit_core`.
//!    A correspondence is an inlier when the reference point, moved by the candidate motion,
//!    reprojects within a few pixels of where the feature was seen: pixel error, unlike a 3D
//!    distance, does not punish the depth noise of far points (Kinect noise grows with z²,
//!    stereo noise with z²/baseline).
//! 2. Horn refit on all inliers.
//! 3. A few Gauss–Newton steps on the inliers' stereo reprojection error (left u, v and right
//!    u, as ORB-SLAM2's stereo motion-only bundle adjustment, Mur-Artal & Tardós, T-RO 2017)
//!    with Huber weights, measured both ways — reference points into the current frame and
//!    current points into the reference — so the depth noise of neither frame is taken as
//!    exact (the symmetric transfer error of Hartley & Zisserman 2004, §4.2.2); on a left
//!    perturbation `T ← exp(δ) T` of SE(3) (Barfoot, *State Estimation for Robotics*, §7.1).
//!
//! Too few inliers (fewer than `min_inliers`, or below `min_inlier_ratio` of the
//! correspondences) is a failed motion: the caller keeps its pose and its reference features.

use nalgebra::{
    Matrix3, Matrix3x6, Matrix6, Point2, Point3, Translation3, UnitQuaternion, Vector2, Vector3,
    Vector6,
};
use serde::{Deserialize, Serialize};
use slamkit_core::camera::Intrinsics;
use slamkit_core::{horn, ransac, Estimator, GeometryError, Pose3, RansacConfig};

use crate::error::VoError;

/// Motion-estimation settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MotionConfig {
    /// Largest reprojection error of an inlier \[px\].
    pub inlier_threshold_px: f64,
    /// Wanted probability that one RANSAC sample was outlier-free, in (0, 1).
    pub confidence: f64,
    /// Upper limit on RANSAC samples.
    pub max_iterations: u32,
    /// Seed of the RANSAC sampler.
    pub seed: u64,
    /// Gauss–Newton steps on the reprojection error after the Horn refit (0 = none).
    pub refine_iterations: usize,
    /// Huber threshold of the refinement \[px\].
    pub huber_px: f64,
    /// Fewest inliers of an accepted motion (at least 5).
    pub min_inliers: usize,
    /// Smallest accepted inlier fraction of the correspondences, in \[0, 1\].
    pub min_inlier_ratio: f64,
}

impl Default for MotionConfig {
    fn default() -> Self {
        Self {
            inlier_threshold_px: 2.0,
            confidence: 0.999,
            max_iterations: 300,
            seed: 0,
            refine_iterations: 5,
            huber_px: 1.0,
            min_inliers: 5,
            min_inlier_ratio: 0.2,
        }
    }
}

impl MotionConfig {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`VoError::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<(), VoError> {
        if !(self.inlier_threshold_px > 0.0 && self.inlier_threshold_px.is_finite()) {
            return Err(VoError::config(
                "inlier_threshold_px",
                self.inlier_threshold_px,
                "must be > 0",
            ));
        }
        if !(self.confidence > 0.0 && self.confidence < 1.0) {
            return Err(VoError::config(
                "confidence",
                self.confidence,
                "must be in (0, 1)",
            ));
        }
        if self.max_iterations == 0 {
            return Err(VoError::config("max_iterations", 0, "must be > 0"));
        }
        if !(self.huber_px > 0.0 && self.huber_px.is_finite()) {
            return Err(VoError::config("huber_px", self.huber_px, "must be > 0"));
        }
        if self.min_inliers < 5 {
            return Err(VoError::config(
                "min_inliers",
                self.min_inliers,
                "must be >= 5",
            ));
        }
        if !(0.0..=1.0).contains(&self.min_inlier_ratio) {
            return Err(VoError::config(
                "min_inlier_ratio",
                self.min_inlier_ratio,
                "must be in [0, 1]",
            ));
        }
        Ok(())
    }
}

/// A feature seen in the reference and in the current frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correspondence {
    /// Its 3D position in the reference frame \[m\].
    pub reference: Point3<f64>,
    /// Its 3D position in the current camera frame \[m\].
    pub current: Point3<f64>,
    /// Where it was seen in the current image \[px\].
    pub current_px: Point2<f64>,
}

/// An accepted motion.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionEstimate {
    /// Maps reference-frame points into the current camera frame.
    pub current_from_reference: Pose3,
    /// Indices of the inlier correspondences, ascending.
    pub inliers: Vec<usize>,
    /// RANSAC samples drawn.
    pub iterations: u32,
    /// RMS reprojection error of the inliers after refinement \[px\].
    pub rms_px: f64,
}

/// Why no motion was accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum MotionFailure {
    /// Fewer correspondences than a motion needs.
    TooFewCorrespondences {
        /// Correspondences given.
        got: usize,
    },
    /// The best motion had too few inliers.
    TooFewInliers {
        /// Inliers of the best motion.
        inliers: usize,
        /// Correspondences given.
        of: usize,
    },
}

/// Horn on 3-point samples, scored by reprojection error in the current image.
struct ReprojectionHorn<'a> {
    k: &'a Intrinsics,
}

impl Estimator for ReprojectionHorn<'_> {
    type Datum = Correspondence;
    type Model = Pose3;

    fn sample_size(&self) -> usize {
        3
    }

    fn fit_sample(
        &self,
        data: &[Correspondence],
        sample: &[usize],
    ) -> Result<Pose3, GeometryError> {
        fit_horn(data, sample)
    }

    fn fit_inliers(
        &self,
        data: &[Correspondence],
        inliers: &[usize],
    ) -> Result<Pose3, GeometryError> {
        fit_horn(data, inliers)
    }

    fn residual(&self, model: &Pose3, c: &Correspondence) -> f64 {
        reprojection(self.k, model, c).map_or(f64::INFINITY, |r| r.norm())
    }
}

fn fit_horn(data: &[Correspondence], indices: &[usize]) -> Result<Pose3, GeometryError> {
    let (src, dst): (Vec<_>, Vec<_>) = indices
        .iter()
        .filter_map(|&i| data.get(i))
        .map(|c| (c.reference, c.current))
        .unzip();
    Ok(horn(&src, &dst, false)?.dst_from_src)
}

/// Reprojection residual `π(T p) − u` \[px\] in the current image; `None` behind the camera.
fn reprojection(k: &Intrinsics, t: &Pose3, c: &Correspondence) -> Option<Vector2<f64>> {
    let q = t * c.reference;
    if q.z.is_nan() || q.z <= 1e-6 {
        return None;
    }
    let u = Vector2::new(k.fx * q.x / q.z + k.cx, k.fy * q.y / q.z + k.cy);
    let r = u - c.current_px.coords;
    (r.x.is_finite() && r.y.is_finite()).then_some(r)
}

/// Estimates `current_from_reference` from `data`, seen by a camera with intrinsics `k`
/// (undistorted pixels).
///
/// # Errors
/// A [`MotionFailure`] when the data do not support a motion.
pub fn estimate_motion(
    data: &[Correspondence],
    cam: &StereoCamera,
    config: &MotionConfig,
) -> Result<MotionEstimate, MotionFailure> {
    let k = &cam.k;
    let needed = config.min_inliers.max(5);
    if data.len() < needed {
        return Err(MotionFailure::TooFewCorrespondences { got: data.len() });
    }
    let ransac_config = RansacConfig {
        confidence: config.confidence,
        threshold: config.inlier_threshold_px,
        max_iterations: config.max_iterations,
        min_inliers: needed,
        seed: config.seed,
    };
    let estimator = ReprojectionHorn { k };
    let found =
        ransac(&estimator, data, &ransac_config).map_err(|_| MotionFailure::TooFewInliers {
            inliers: 0,
            of: data.len(),
        })?;
    let mut pose = found.model;
    let mut inliers = found.inliers;
    for _ in 0..2 {
        pose = refine(data, &inliers, cam, pose, config);
        inliers = inliers_of(data, k, &pose, config.inlier_threshold_px);
    }
    let ratio = inliers.len() as f64 / data.len() as f64;
    if inliers.len() < needed || ratio < config.min_inlier_ratio {
        return Err(MotionFailure::TooFewInliers {
            inliers: inliers.len(),
            of: data.len(),
        });
    }
    let rms_px = rms(data, &inliers, k, &pose);
    Ok(MotionEstimate {
        current_from_reference: pose,
        inliers,
        iterations: found.iterations,
        rms_px,
    })
}

fn inliers_of(
    data: &[Correspondence],
    k: &Intrinsics,
    pose: &Pose3,
    threshold_px: f64,
) -> Vec<usize> {
    data.iter()
        .enumerate()
        .filter(|(_, c)| reprojection(k, pose, c).is_some_and(|r| r.norm() <= threshold_px))
        .map(|(i, _)| i)
        .collect()
}

fn rms(data: &[Correspondence], inliers: &[usize], k: &Intrinsics, pose: &Pose3) -> f64 {
    let (sum, n) = inliers
        .iter()
        .filter_map(|&i| data.get(i).and_then(|c| reprojection(k, pose, c)))
        .fold((0.0, 0usize), |(s, n), r| (s + r.norm_squared(), n + 1));
    if n == 0 {
        f64::NAN
    } else {
        (sum / n as f64).sqrt()
    }
}

/// The camera the motion is measured with: intrinsics and the stereo term.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoCamera {
    /// Intrinsics of the tracked (left) image, undistorted pixels.
    pub k: Intrinsics,
    /// Focal length × baseline \[px·m\]: a point at depth z has disparity `bf / z`. For RGB-D
    /// a virtual baseline (as ORB-SLAM2 does) turns depth into the same kind of measurement;
    /// 0 leaves the disparity term out.
    pub bf: f64,
}

/// One stereo observation residual (left u, v and right u, \[px\]) and its Jacobian with
/// respect to a left perturbation δ = (ω, v) of the motion.
type Residual = (Vector3<f64>, Matrix3x6<f64>);

/// Stereo projection `(u, v, u − bf/z)` of camera-frame `q` and its Jacobian `∂/∂q`; `None`
/// behind the camera.
fn project(cam: &StereoCamera, q: &Point3<f64>) -> Option<(Vector3<f64>, Matrix3<f64>)> {
    if q.z.is_nan() || q.z <= 1e-6 {
        return None;
    }
    let k = &cam.k;
    let iz = 1.0 / q.z;
    let u = k.fx * q.x * iz + k.cx;
    let p = Vector3::new(u, k.fy * q.y * iz + k.cy, u - cam.bf * iz);
    let du = Vector3::new(k.fx * iz, 0.0, -k.fx * q.x * iz * iz);
    let j = Matrix3::from_rows(&[
        du.transpose(),
        Vector3::new(0.0, k.fy * iz, -k.fy * q.y * iz * iz).transpose(),
        (du + Vector3::new(0.0, 0.0, cam.bf * iz * iz)).transpose(),
    ]);
    p.iter().all(|v| v.is_finite()).then_some((p, j))
}

/// The two residuals of a correspondence under `t` = current_from_reference: the reference
/// point moved into the current frame against the current observation (the tracked pixel and
/// the current disparity), and the current point moved back against the reference
/// observation. Each point carries its own frame's depth noise; measuring both ways cancels,
/// to first order, the bias of `z = bf / d` (farther on average than the truth) that a one-way
/// fit turns into a too-long translation.
fn symmetric_residuals(
    cam: &StereoCamera,
    t: &Pose3,
    t_inv: &Pose3,
    c: &Correspondence,
) -> Option<[Residual; 2]> {
    let q = t * c.reference;
    let (pred, jq) = project(cam, &q)?;
    let (mut obs, _) = project(cam, &c.current)?;
    let disparity = obs.x - obs.z;
    obs.x = c.current_px.x;
    obs.y = c.current_px.y;
    obs.z = c.current_px.x - disparity;
    let mut fwd = Matrix3x6::zeros();
    fwd.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-jq * q.coords.cross_matrix()));
    fwd.fixed_view_mut::<3, 3>(0, 3).copy_from(&jq);
    let q_back = t_inv * c.current;
    let (pred_back, jb) = project(cam, &q_back)?;
    let (obs_back, _) = project(cam, &c.reference)?;
    let rt = t_inv.rotation.to_rotation_matrix().into_inner();
    let mut bwd = Matrix3x6::zeros();
    bwd.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(jb * rt * c.current.coords.cross_matrix()));
    bwd.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-jb * rt));
    let mut out = [(pred - obs, fwd), (pred_back - obs_back, bwd)];
    if cam.bf == 0.0 {
        for (r, j) in &mut out {
            r.z = 0.0;
            j.row_mut(2).fill(0.0);
        }
    }
    Some(out)
}

/// Gauss–Newton with Huber weights on the symmetric stereo reprojection error of `inliers`
/// (each correspondence measured in both frames); keeps `pose` when a step fails or does not
/// lower the cost.
pub fn refine(
    data: &[Correspondence],
    inliers: &[usize],
    cam: &StereoCamera,
    mut pose: Pose3,
    config: &MotionConfig,
) -> Pose3 {
    let mut cost = huber_cost(data, inliers, cam, &pose, config.huber_px);
    for _ in 0..config.refine_iterations {
        let mut h = Matrix6::<f64>::zeros();
        let mut g = Vector6::<f64>::zeros();
        let pose_inv = pose.inverse();
        for c in inliers.iter().filter_map(|&i| data.get(i)) {
            let Some(res) = symmetric_residuals(cam, &pose, &pose_inv, c) else {
                continue;
            };
            for (r, j) in &res {
                let w = huber_weight(r.norm(), config.huber_px);
                h += w * j.transpose() * j;
                g += w * j.transpose() * r;
            }
        }
        let Some(delta) = h.cholesky().map(|ch| ch.solve(&(-g))) else {
            break;
        };
        let step = Pose3::from_parts(
            Translation3::new(delta[3], delta[4], delta[5]),
            UnitQuaternion::from_scaled_axis(delta.fixed_rows::<3>(0).into_owned()),
        );
        let candidate = step * pose;
        let new_cost = huber_cost(data, inliers, cam, &candidate, config.huber_px);
        if new_cost.is_nan() || new_cost >= cost {
            break;
        }
        pose = candidate;
        let converged = cost - new_cost < 1e-9 * cost.max(1e-12);
        cost = new_cost;
        if converged || delta.norm() < 1e-10 {
            break;
        }
    }
    pose
}

fn huber_weight(r: f64, delta: f64) -> f64 {
    if r <= delta {
        1.0
    } else {
        delta / r
    }
}

fn huber_cost(
    data: &[Correspondence],
    inliers: &[usize],
    cam: &StereoCamera,
    pose: &Pose3,
    delta: f64,
) -> f64 {
    let pose_inv = pose.inverse();
    inliers
        .iter()
        .filter_map(|&i| data.get(i))
        .filter_map(|c| symmetric_residuals(cam, pose, &pose_inv, c))
        .flatten()
        .map(|(r, _)| {
            let e = r.norm();
            if e <= delta {
                0.5 * e * e
            } else {
                delta * (e - 0.5 * delta)
            }
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn camera() -> StereoCamera {
        StereoCamera {
            k: kinect(),
            bf: 585.0 * 0.075,
        }
    }

    fn kinect() -> Intrinsics {
        Intrinsics {
            fx: 585.0,
            fy: 585.0,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        }
    }

    /// `n` features 1–5 m in front of the camera, seen after `truth`; the first `good` with
    /// 0.3 px pixel noise and 1 % depth noise, the rest moved to random pixels and depths.
    fn scene(seed: u64, truth: &Pose3, n: usize, good: usize) -> Vec<Correspondence> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let k = kinect();
        (0..n)
            .map(|i| {
                let u = Point2::new(rng.gen_range(0.0..640.0), rng.gen_range(0.0..480.0));
                let z: f64 = rng.gen_range(1.0..5.0);
                let reference = Point3::new((u.x - k.cx) / k.fx * z, (u.y - k.cy) / k.fy * z, z);
                let mut current = truth * reference;
                let mut px = Point2::new(
                    k.fx * current.x / current.z + k.cx,
                    k.fy * current.y / current.z + k.cy,
                );
                if i < good {
                    px += Vector2::new(rng.gen_range(-0.3..0.3), rng.gen_range(-0.3..0.3));
                    current.coords *= 1.0 + rng.gen_range(-0.01..0.01);
                } else {
                    px = Point2::new(rng.gen_range(0.0..640.0), rng.gen_range(0.0..480.0));
                    let z = rng.gen_range(1.0..5.0);
                    current = Point3::new((px.x - k.cx) / k.fx * z, (px.y - k.cy) / k.fy * z, z);
                }
                Correspondence {
                    reference,
                    current,
                    current_px: px,
                }
            })
            .collect()
    }

    fn motion() -> Pose3 {
        Pose3::new(
            Vector3::new(0.05, -0.02, 0.10),
            Vector3::new(0.02, -0.03, 0.01),
        )
    }

    #[test]
    fn recovers_synthetic_motion_with_outliers() {
        let truth = motion();
        let data = scene(7, &truth, 300, 180);
        let est = estimate_motion(&data, &camera(), &MotionConfig::default()).unwrap();
        let err = truth.inverse() * est.current_from_reference;
        assert!(err.translation.vector.norm() < 2e-3, "{err}");
        assert!(err.rotation.angle() < 1e-3, "{err}");
        let wrong = est.inliers.iter().filter(|&&i| i >= 180).count();
        assert!(
            est.inliers.len() >= 170 && wrong <= 3,
            "{} inliers, {wrong} wrong",
            est.inliers.len()
        );
    }

    #[test]
    fn refinement_lowers_reprojection_error() {
        let truth = motion();
        let data = scene(8, &truth, 200, 200);
        let all: Vec<usize> = (0..200).collect();
        let start = fit_horn(&data, &all).unwrap();
        let config = MotionConfig::default();
        let refined = refine(&data, &all, &camera(), start, &config);
        let before = rms(&data, &all, &kinect(), &start);
        let after = rms(&data, &all, &kinect(), &refined);
        assert!(after < before, "{after} vs {before}");
        let err = truth.inverse() * refined;
        assert!(err.translation.vector.norm() < 2e-3, "{err}");
    }

    #[test]
    fn too_few_inliers_fail() {
        let data = scene(9, &motion(), 100, 4);
        let got = estimate_motion(&data, &camera(), &MotionConfig::default());
        assert!(
            matches!(got, Err(MotionFailure::TooFewInliers { .. })),
            "{got:?}"
        );
        let got = estimate_motion(&data[..4], &camera(), &MotionConfig::default());
        assert_eq!(got, Err(MotionFailure::TooFewCorrespondences { got: 4 }));
    }

    #[test]
    fn config_ranges_are_checked() {
        assert!(MotionConfig::default().validate().is_ok());
        let bad = MotionConfig {
            min_inliers: 3,
            ..Default::default()
        };
        assert!(bad.validate().is_err());
    }
}
