//! Odometry motion model and the odometry source of the particle filters.
//!
//! The robot's motion between two scans is the odometry increment `prev_from_cur` (in the frame
//! of the earlier pose). Particles move by that increment perturbed with zero-mean Gaussian
//! noise whose standard deviation grows with the distance and the angle travelled (S. Thrun,
//! W. Burgard, D. Fox, *Probabilistic Robotics*, 2005, section 5.4; the four coefficients are
//! GMapping's `srr`, `srt`, `str`, `stt`, Grisetti et al., IEEE T-RO 23(1), 2007).
//!
//! Logs without wheel odometry (a drone, a hand-held scanner) get odometry from scan-to-scan ICP
//! ([`scan_odometry`]), as MRPT's ICP-based rbpf-slam does.

use crate::cloud::{estimate_normals, scan_points};
use crate::icp::{align, IcpConfig};
use crate::nn::PointIndex;
use nalgebra::{Matrix3, Vector3};
use rand::Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use slamkit_core::pose::wrap_angle;
use slamkit_core::{LaserScan, Pose2};

/// Noise of the odometry motion model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MotionModelConfig {
    /// Translation noise per metre travelled \[m/m\] (GMapping `srr`).
    pub trans_per_trans: f64,
    /// Translation noise per radian turned \[m/rad\] (GMapping `srt`).
    pub trans_per_rot: f64,
    /// Rotation noise per metre travelled \[rad/m\] (GMapping `str`).
    pub rot_per_trans: f64,
    /// Rotation noise per radian turned \[rad/rad\] (GMapping `stt`).
    pub rot_per_rot: f64,
    /// Translation noise added to every step, so a still robot keeps some spread \[m\].
    pub min_trans_sigma_m: f64,
    /// Rotation noise added to every step \[rad\].
    pub min_rot_sigma_rad: f64,
}

impl Default for MotionModelConfig {
    /// GMapping's defaults.
    fn default() -> Self {
        Self {
            trans_per_trans: 0.1,
            trans_per_rot: 0.2,
            rot_per_trans: 0.1,
            rot_per_rot: 0.2,
            min_trans_sigma_m: 0.005,
            min_rot_sigma_rad: 0.2f64.to_radians(),
        }
    }
}

impl MotionModelConfig {
    /// True when every coefficient is finite and non-negative and the floors are positive.
    pub fn is_valid(&self) -> bool {
        let coefficients = [
            self.trans_per_trans,
            self.trans_per_rot,
            self.rot_per_trans,
            self.rot_per_rot,
        ];
        coefficients.iter().all(|c| c.is_finite() && *c >= 0.0)
            && self.min_trans_sigma_m.is_finite()
            && self.min_trans_sigma_m > 0.0
            && self.min_rot_sigma_rad.is_finite()
            && self.min_rot_sigma_rad > 0.0
    }

    /// Standard deviations `(σx, σy, σθ)` of the noise on `increment` \[m, m, rad\].
    pub fn sigmas(&self, increment: &Pose2) -> Vector3<f64> {
        let trans = increment.translation.vector.norm();
        let rot = increment.rotation.angle().abs();
        let s_t = self.trans_per_trans * trans + self.trans_per_rot * rot + self.min_trans_sigma_m;
        let s_r = self.rot_per_trans * trans + self.rot_per_rot * rot + self.min_rot_sigma_rad;
        Vector3::new(s_t, s_t, s_r)
    }

    /// A noisy version of the odometry increment `prev_from_cur`.
    pub fn sample(&self, increment: &Pose2, rng: &mut impl Rng) -> Pose2 {
        let s = self.sigmas(increment);
        let mut noise = || rng.sample::<f64, _>(StandardNormal);
        let (ex, ey, et) = (noise() * s.x, noise() * s.y, noise() * s.z);
        let t = increment.translation.vector;
        Pose2::new(
            nalgebra::Vector2::new(t.x + ex, t.y + ey),
            increment.rotation.angle() + et,
        )
    }

    /// Inverse covariance of the noise on `increment`, for scoring candidate poses.
    pub fn information(&self, increment: &Pose2) -> Matrix3<f64> {
        let s = self.sigmas(increment);
        Matrix3::from_diagonal(&Vector3::new(
            1.0 / (s.x * s.x),
            1.0 / (s.y * s.y),
            1.0 / (s.z * s.z),
        ))
    }
}

/// Difference `(dx, dy, dθ)` of two poses, expressed in the frame of `reference`:
/// the coordinates of `reference⁻¹ · pose`.
pub fn pose_difference(reference: &Pose2, pose: &Pose2) -> Vector3<f64> {
    let d = reference.inverse() * pose;
    Vector3::new(
        d.translation.vector.x,
        d.translation.vector.y,
        wrap_angle(d.rotation.angle()),
    )
}

/// ICP settings of [`scan_odometry`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScanOdometryConfig {
    /// Scan-to-scan ICP.
    pub icp: IcpConfig,
    /// Beams shorter than this are dropped \[m\].
    pub min_range_m: f64,
    /// Beams at or beyond this are dropped \[m\].
    pub max_range_m: f64,
    /// Alignments below this goodness are rejected and the last motion repeated, in \[0, 1\].
    pub min_goodness: f64,
}

impl Default for ScanOdometryConfig {
    fn default() -> Self {
        Self {
            icp: IcpConfig::default(),
            min_range_m: 0.1,
            max_range_m: 30.0,
            min_goodness: 0.5,
        }
    }
}

/// Odometry pose of every scan from scan-to-scan ICP, starting at the identity. Each scan is
/// aligned to the previous one from a constant-velocity guess; a scan that cannot be aligned
/// (too few points, low goodness) repeats the last motion. Returns the poses and the number of
/// scans that could not be aligned.
pub fn scan_odometry(scans: &[LaserScan], config: &ScanOdometryConfig) -> (Vec<Pose2>, usize) {
    let mut odometry = ScanOdometry::new(config.clone());
    let poses = scans.iter().map(|scan| odometry.push(scan)).collect();
    (poses, odometry.failures())
}

/// [`scan_odometry`] one scan at a time, for online use.
pub struct ScanOdometry {
    config: ScanOdometryConfig,
    previous: Option<PointIndex>,
    pose: Pose2,
    motion: Pose2,
    started: bool,
    failures: usize,
}

impl ScanOdometry {
    /// Odometry starting at the identity with the first scan.
    pub fn new(config: ScanOdometryConfig) -> Self {
        Self {
            config,
            previous: None,
            pose: Pose2::identity(),
            motion: Pose2::identity(),
            started: false,
            failures: 0,
        }
    }

    /// The odometry pose of `scan`, the next scan in time.
    pub fn push(&mut self, scan: &LaserScan) -> Pose2 {
        let config = &self.config;
        let points = scan_points(scan, config.min_range_m, config.max_range_m);
        let guess = self.motion;
        let aligned = self
            .previous
            .as_ref()
            .and_then(|target| align(&points, target, &guess, &config.icp).ok())
            .filter(|r| r.goodness >= config.min_goodness);
        match aligned {
            Some(result) => self.motion = result.target_from_source,
            None if self.previous.is_some() => self.failures += 1,
            None => {}
        }
        if self.started {
            self.pose *= self.motion;
        }
        self.started = true;
        if points.len() >= config.icp.min_correspondences {
            let normals = estimate_normals(&points, 6, 0.5, 0.2);
            self.previous = Some(PointIndex::new(points, Some(normals)));
        }
        self.pose
    }

    /// Scans that could not be aligned so far.
    pub fn failures(&self) -> usize {
        self.failures
    }
}

/// Odometry pose of every scan: the log's wheel odometry when every scan has it and
/// `use_wheel_odometry` is set, scan-to-scan ICP otherwise. The second value counts scans ICP
/// could not align (0 with wheel odometry); the third says whether wheel odometry was used.
pub fn odometry_poses(
    scans: &[LaserScan],
    use_wheel_odometry: bool,
    icp: &ScanOdometryConfig,
) -> (Vec<Pose2>, usize, bool) {
    let wheel: Option<Vec<Pose2>> = scans.iter().map(|s| s.odometry).collect();
    match wheel {
        Some(poses) if use_wheel_odometry && poses.iter().all(is_finite_pose) => (poses, 0, true),
        _ => {
            let (poses, failures) = scan_odometry(scans, icp);
            (poses, failures, false)
        }
    }
}

/// True when the pose holds no NaN or infinity.
pub fn is_finite_pose(pose: &Pose2) -> bool {
    let t = pose.translation.vector;
    t.x.is_finite() && t.y.is_finite() && pose.rotation.angle().is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim_scan::SegmentWorld;
    use nalgebra::Vector2;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn samples_have_the_configured_spread() {
        let model = MotionModelConfig::default();
        let increment = Pose2::new(Vector2::new(1.0, 0.0), 0.5);
        let s = model.sigmas(&increment);
        assert!((s.x - (0.1 + 0.1 + 0.005)).abs() < 1e-12);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let n = 20_000;
        let diffs: Vec<Vector3<f64>> = (0..n)
            .map(|_| pose_difference(&increment, &model.sample(&increment, &mut rng)))
            .collect();
        // The noise is applied to the increment's coordinates; differences seen from the
        // nominal end pose are rotated, but their norms keep the spread.
        let mean_rot = diffs.iter().map(|d| d.z).sum::<f64>() / n as f64;
        let var_rot = diffs.iter().map(|d| (d.z - mean_rot).powi(2)).sum::<f64>() / n as f64;
        assert!(mean_rot.abs() < 0.01, "{mean_rot}");
        assert!(
            (var_rot.sqrt() - s.z).abs() < 0.01 * s.z + 0.002,
            "{}",
            var_rot.sqrt()
        );
        let var_xy = diffs.iter().map(|d| d.xy().norm_squared()).sum::<f64>() / n as f64;
        assert!(((var_xy / 2.0).sqrt() - s.x).abs() < 0.02 * s.x, "{var_xy}");
    }

    #[test]
    fn icp_odometry_follows_a_simulated_drive() {
        let world = SegmentWorld::room();
        let truth: Vec<Pose2> = (0..30)
            .map(|i| Pose2::new(Vector2::new(-4.0 + 0.15 * i as f64, -1.5), 0.02 * i as f64))
            .collect();
        let scans: Vec<LaserScan> = truth
            .iter()
            .map(|p| world.scan(p, 361, std::f64::consts::PI, 30.0))
            .collect();
        let (poses, used_wheel) = {
            let (poses, failures, wheel) =
                odometry_poses(&scans, true, &ScanOdometryConfig::default());
            assert_eq!(failures, 0);
            (poses, wheel)
        };
        assert!(!used_wheel, "sim scans carry no wheel odometry");
        let first_from_last = truth[0].inverse() * truth[29];
        let err = pose_difference(&first_from_last, &(poses[0].inverse() * poses[29]));
        assert!(err.xy().norm() < 0.02 && err.z.abs() < 0.005, "{err}");
    }
}
