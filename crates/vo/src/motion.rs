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
//!    Each residual `(u, v, bf/z)` is whitened by its covariance: the moved point's depth noise
//!    (σ_z growing with z², [`MeasurementNoise`]) propagated through the motion and the
//!    projection, plus the observation's pixel and disparity noise — so a far point's
//!    uncertain depth is trusted less while its well-measured pixel still counts.
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
    /// Weight each refinement residual by its covariance from [`MotionConfig::noise`] (false:
    /// every residual component counts alike).
    pub weight_by_noise: bool,
    /// Noise of the pixels and depths, for the weights.
    pub noise: MeasurementNoise,
}

/// Noise of a feature's pixel and depth.
///
/// The depth noise of a structured-light RGB-D camera grows with the square of depth; for a
/// Kinect v1, Nguyen, Izadi and Lovell ("Modeling Kinect Sensor Noise for Improved 3D
/// Reconstruction and Tracking", 3DIMPVT 2012, eq. 6) measured
/// `σ_z = 0.0012 + 0.0019 (z − 0.4)²` \[m\] (the defaults). A stereo camera has a constant
/// disparity noise `σ_d`, so `σ_z = z² σ_d / bf`. Both terms are added in quadrature.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MeasurementNoise {
    /// Standard deviation of a feature's position in the image \[px\].
    pub pixel_sigma_px: f64,
    /// Axial depth noise: constant term \[m\].
    pub depth_sigma_base_m: f64,
    /// Axial depth noise: coefficient of `(z − depth_sigma_offset_m)²` \[1/m\].
    pub depth_sigma_quadratic_per_m: f64,
    /// Axial depth noise: depth at which the quadratic term vanishes \[m\].
    pub depth_sigma_offset_m: f64,
    /// Standard deviation of a stereo disparity \[px\] (0 for an RGB-D camera).
    pub disparity_sigma_px: f64,
}

impl Default for MeasurementNoise {
    fn default() -> Self {
        Self {
            pixel_sigma_px: 0.5,
            depth_sigma_base_m: 0.0012,
            depth_sigma_quadratic_per_m: 0.0019,
            depth_sigma_offset_m: 0.4,
            disparity_sigma_px: 0.0,
        }
    }
}

impl MeasurementNoise {
    /// Standard deviation of a depth `z_m` \[m\] measured by a camera with focal length ×
    /// baseline `bf` \[px·m\].
    pub fn depth_sigma_m(&self, z_m: f64, bf: f64) -> f64 {
        let axial = self.depth_sigma_base_m
            + self.depth_sigma_quadratic_per_m * (z_m - self.depth_sigma_offset_m).powi(2);
        let stereo = if bf > 0.0 {
            z_m * z_m * self.disparity_sigma_px / bf
        } else {
            0.0
        };
        axial.hypot(stereo)
    }

    fn validate(&self) -> Result<(), VoError> {
        if !(self.pixel_sigma_px > 0.0 && self.pixel_sigma_px.is_finite()) {
            return Err(VoError::config(
                "noise.pixel_sigma_px",
                self.pixel_sigma_px,
                "must be > 0",
            ));
        }
        let fields = [
            ("noise.depth_sigma_base_m", self.depth_sigma_base_m),
            (
                "noise.depth_sigma_quadratic_per_m",
                self.depth_sigma_quadratic_per_m,
            ),
            ("noise.disparity_sigma_px", self.disparity_sigma_px),
        ];
        for (name, v) in fields {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(VoError::config(name, v, "must be finite and >= 0"));
            }
        }
        if self.depth_sigma_base_m + self.depth_sigma_quadratic_per_m + self.disparity_sigma_px
            <= 0.0
        {
            return Err(VoError::config(
                "noise.depth_sigma_base_m",
                self.depth_sigma_base_m,
                "some depth noise must be > 0",
            ));
        }
        if !self.depth_sigma_offset_m.is_finite() {
            return Err(VoError::config(
                "noise.depth_sigma_offset_m",
                self.depth_sigma_offset_m,
                "must be finite",
            ));
        }
        Ok(())
    }
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
            weight_by_noise: true,
            noise: MeasurementNoise::default(),
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
        self.noise.validate()
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

/// One observation residual (u, v and disparity `bf/z`, \[px\]) and its Jacobian with respect
/// to a left perturbation δ = (ω, v) of the motion.
type Residual = (Vector3<f64>, Matrix3x6<f64>);

/// Stereo projection `(u, v, bf/z)` of camera-frame `q` and its Jacobian `∂/∂q`; `None`
/// behind the camera.
pub(crate) fn project(cam: &StereoCamera, q: &Point3<f64>) -> Option<(Vector3<f64>, Matrix3<f64>)> {
    if q.z.is_nan() || q.z <= 1e-6 {
        return None;
    }
    let k = &cam.k;
    let iz = 1.0 / q.z;
    let p = Vector3::new(k.fx * q.x * iz + k.cx, k.fy * q.y * iz + k.cy, cam.bf * iz);
    #[rustfmt::skip]
    let j = Matrix3::new(
        k.fx * iz, 0.0, -k.fx * q.x * iz * iz,
        0.0, k.fy * iz, -k.fy * q.y * iz * iz,
        0.0, 0.0, -cam.bf * iz * iz,
    );
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
    obs.x = c.current_px.x;
    obs.y = c.current_px.y;
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
    Some([(pred - obs, fwd), (pred_back - obs_back, bwd)])
}

/// Covariance \[px²\] of the observation `(u, v, bf/z)` of camera-frame point `p`: the pixel
/// noise in u and v, the depth noise turned into disparity, `σ_d = bf σ_z / z²`.
pub(crate) fn observation_covariance(
    cam: &StereoCamera,
    noise: &MeasurementNoise,
    p: &Point3<f64>,
) -> Matrix3<f64> {
    let s2 = noise.pixel_sigma_px.powi(2);
    let sd = cam.bf * noise.depth_sigma_m(p.z, cam.bf) / (p.z * p.z);
    Matrix3::from_diagonal(&Vector3::new(s2, s2, sd * sd))
}

/// Covariance \[m²\] of a point lifted from a pixel and a depth: the depth noise along its
/// viewing ray (the whole point scales with z), the pixel noise across it.
fn point_covariance(cam: &StereoCamera, noise: &MeasurementNoise, p: &Point3<f64>) -> Matrix3<f64> {
    let ray = p.coords / p.z;
    let sz = noise.depth_sigma_m(p.z, cam.bf);
    let lateral = noise.pixel_sigma_px * p.z;
    let across = Vector3::new(
        (lateral / cam.k.fx).powi(2),
        (lateral / cam.k.fy).powi(2),
        0.0,
    );
    Matrix3::from_diagonal(&across) + ray * ray.transpose() * (sz * sz)
}

/// The matrix `σ_px L⁻¹` (`C = L Lᵀ` the covariance of `π(t · from) − obs(to)`) that turns
/// that residual into pixels of a feature with only pixel noise: the noise of `from`
/// propagated through the motion and the projection (Hartley & Zisserman 2004, §5.2), plus
/// the observation noise of `to`. `None` when `from` lands behind the camera or `C` is
/// singular.
fn whitening(
    cam: &StereoCamera,
    noise: &MeasurementNoise,
    t: &Pose3,
    from: &Point3<f64>,
    to: &Point3<f64>,
) -> Option<Matrix3<f64>> {
    let (_, j) = project(cam, &(t * from))?;
    let r = t.rotation.to_rotation_matrix().into_inner();
    let jr = j * r;
    let mut c = jr * point_covariance(cam, noise, from) * jr.transpose()
        + observation_covariance(cam, noise, to);
    if cam.bf == 0.0 {
        // no disparity term: its residual and Jacobian row are zero, any variance will do
        c[(2, 2)] = noise.pixel_sigma_px.powi(2);
    }
    let l_inv = c.cholesky()?.l().try_inverse()?;
    Some(l_inv * noise.pixel_sigma_px)
}

/// The inliers' residuals with their whitening, fixed at the pose the refinement starts from
/// so that the cost it minimises does not change under it.
struct Problem<'a> {
    cam: &'a StereoCamera,
    huber_px: f64,
    terms: Vec<(&'a Correspondence, [Matrix3<f64>; 2])>,
}

impl<'a> Problem<'a> {
    fn new(
        data: &'a [Correspondence],
        inliers: &[usize],
        cam: &'a StereoCamera,
        start: &Pose3,
        config: &MotionConfig,
    ) -> Self {
        let noise = &config.noise;
        let start_inv = start.inverse();
        let terms = inliers
            .iter()
            .filter_map(|&i| data.get(i))
            .filter_map(|c| {
                let w = if config.weight_by_noise {
                    [
                        whitening(cam, noise, start, &c.reference, &c.current)?,
                        whitening(cam, noise, &start_inv, &c.current, &c.reference)?,
                    ]
                } else {
                    [Matrix3::identity(); 2]
                };
                Some((c, w))
            })
            .collect();
        Self {
            cam,
            huber_px: config.huber_px,
            terms,
        }
    }

    /// Whitened residuals of every term under `pose`.
    fn residuals(&self, pose: &Pose3) -> impl Iterator<Item = Residual> + '_ {
        let pose = *pose;
        let pose_inv = pose.inverse();
        self.terms.iter().flat_map(move |(c, w)| {
            symmetric_residuals(self.cam, &pose, &pose_inv, c)
                .into_iter()
                .flat_map(move |res| {
                    res.into_iter()
                        .zip(w.iter())
                        .map(|((r, j), w)| (w * r, w * j))
                })
        })
    }

    fn cost(&self, pose: &Pose3) -> f64 {
        let delta = self.huber_px;
        self.residuals(pose)
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

    /// The Gauss–Newton step with Huber weights at `pose`; `None` for a singular system.
    fn step(&self, pose: &Pose3) -> Option<Vector6<f64>> {
        let mut h = Matrix6::<f64>::zeros();
        let mut g = Vector6::<f64>::zeros();
        for (r, j) in self.residuals(pose) {
            let w = huber_weight(r.norm(), self.huber_px);
            h += w * j.transpose() * j;
            g += w * j.transpose() * r;
        }
        h.cholesky().map(|ch| ch.solve(&(-g)))
    }
}

/// Gauss–Newton with Huber weights on the symmetric stereo reprojection error of `inliers`
/// (each correspondence measured in both frames), each residual weighted by its covariance
/// when [`MotionConfig::weight_by_noise`] is set; keeps `pose` when a step fails or does not
/// lower the cost.
pub fn refine(
    data: &[Correspondence],
    inliers: &[usize],
    cam: &StereoCamera,
    mut pose: Pose3,
    config: &MotionConfig,
) -> Pose3 {
    let problem = Problem::new(data, inliers, cam, &pose, config);
    let mut cost = problem.cost(&pose);
    for _ in 0..config.refine_iterations {
        let Some(delta) = problem.step(&pose) else {
            break;
        };
        let step = Pose3::from_parts(
            Translation3::new(delta[3], delta[4], delta[5]),
            UnitQuaternion::from_scaled_axis(delta.fixed_rows::<3>(0).into_owned()),
        );
        let candidate = step * pose;
        let new_cost = problem.cost(&candidate);
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

#[cfg(test)]
mod tests;
