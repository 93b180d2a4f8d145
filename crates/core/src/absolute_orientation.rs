//! Absolute orientation: the similarity transform that best maps one point set onto another.
//!
//! Given pairs `(src_i, dst_i)`, find rotation `R`, translation `t` and scale `s` minimising
//! `Σ |dst_i − (s R src_i + t)|²`. Trajectory alignment (ATE with `--align se3|sim3`), RANSAC
//! motion estimation and map registration all reduce to this problem.
//!
//! Two closed forms are given; on the same input they agree to rounding:
//!
//! * [`horn`]: B. K. P. Horn, "Closed-form solution of absolute orientation using unit
//!   quaternions", JOSA A 4(4):629–642, 1987. The rotation is the unit eigenvector of the
//!   largest eigenvalue of the symmetric 4×4 matrix `N` built from the cross-covariance
//!   (Horn §4.A, eq. 27 ff.); it can never be a reflection. [`horn_with`] also offers Horn's
//!   symmetric scale (§2.E), which treats both sets alike.
//! * [`umeyama`]: S. Umeyama, "Least-squares estimation of transformation parameters between
//!   two point patterns", IEEE TPAMI 13(4):376–380, 1991. The rotation comes from the SVD of the
//!   cross-covariance, with the reflection fix of eqs. 39/43. This is the method `evo` uses for
//!   `-a` / `-as`, and it is followed here step by step so that alignments match evo.

use crate::{GeometryError, Pose3};
use nalgebra::{
    Matrix3, Matrix4, Point3, Quaternion, Rotation3, SymmetricEigen, Translation3, UnitQuaternion,
    Vector3, SVD,
};

/// A fitted similarity transform: `dst ≈ scale · R · src + t`.
///
/// The rigid part `dst_from_src` holds `R` and `t`; the scale multiplies the source point
/// *before* the rotation. Note that `dst_from_src * p` alone ignores the scale; use
/// [`SimilarityFit::transform_point`] to apply the whole transform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimilarityFit {
    /// Rotation `R` and translation `t`.
    pub dst_from_src: Pose3,
    /// Scale `s` (exactly 1 when the fit was asked for no scale).
    pub scale: f64,
}

impl SimilarityFit {
    /// Maps a source point into the destination frame: `s R p + t`.
    pub fn transform_point(&self, p: &Point3<f64>) -> Point3<f64> {
        let rotated = self.dst_from_src.rotation * (p.coords * self.scale);
        Point3::from(rotated + self.dst_from_src.translation.vector)
    }

    /// Maps a pose (e.g. `src_from_body`) into the destination frame, giving `dst_from_body`:
    /// its position goes through [`Self::transform_point`], its orientation is rotated by `R`.
    /// This is how evo applies a Sim(3) alignment to an estimated trajectory.
    pub fn transform_pose(&self, pose: &Pose3) -> Pose3 {
        let position = self.transform_point(&Point3::from(pose.translation.vector));
        Pose3::from_parts(
            Translation3::from(position.coords),
            self.dst_from_src.rotation * pose.rotation,
        )
    }
}

/// How [`horn_with`] estimates the scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HornScale {
    /// Rigid fit: scale fixed at 1.
    Fixed,
    /// Least squares with errors in the destination only: `s = Σ b_i·R a_i / Σ |a_i|²` over
    /// centred points (Horn §2.C). Equals Umeyama's eq. 42, so [`horn`] and [`umeyama`] agree.
    Asymmetric,
    /// Horn's symmetric form `s = sqrt(Σ |b_i|² / Σ |a_i|²)` (§2.E): fitting `dst → src`
    /// gives exactly the inverse scale, which the asymmetric form does not.
    Symmetric,
}

/// Horn's quaternion solution; `with_scale` uses the [`HornScale::Asymmetric`] scale so that the
/// result matches [`umeyama`].
///
/// # Errors
/// See [`GeometryError`]: mismatched lengths, fewer than 3 pairs, non-finite coordinates, or
/// coincident / collinear points (the rotation about their line is then undetermined).
pub fn horn(
    src: &[Point3<f64>],
    dst: &[Point3<f64>],
    with_scale: bool,
) -> Result<SimilarityFit, GeometryError> {
    let scale = if with_scale {
        HornScale::Asymmetric
    } else {
        HornScale::Fixed
    };
    horn_with(src, dst, scale)
}

/// Horn's quaternion solution with a choice of scale estimate.
///
/// # Errors
/// As [`horn`].
pub fn horn_with(
    src: &[Point3<f64>],
    dst: &[Point3<f64>],
    scale: HornScale,
) -> Result<SimilarityFit, GeometryError> {
    let m = Moments::new(src, dst)?;
    // Horn's M = Σ a_i b_iᵀ (source rows, destination columns); our covariance is its
    // transpose divided by n, and the positive factor does not move N's eigenvectors.
    let n = horn_matrix(&m.cov.transpose());
    let eig = SymmetricEigen::new(n);
    let q = eig.eigenvectors.column(eig.eigenvalues.imax());
    let rotation = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
    let s = match scale {
        HornScale::Fixed => 1.0,
        // (1/n) Σ b·R a = tr(R Σ_abᵀ) = Σ_ij cov_ij R_ij
        HornScale::Asymmetric => {
            m.cov
                .component_mul(rotation.to_rotation_matrix().matrix())
                .sum()
                / m.src_var
        }
        HornScale::Symmetric => (m.dst_var / m.src_var).sqrt(),
    };
    Ok(m.fit(rotation, s))
}

/// Umeyama's SVD solution, exactly as evo computes it.
///
/// Steps (Umeyama 1991): means (eqs. 34–35), source variance `σ²_src = (1/n) Σ |src_i − μ_src|²`
/// (36), covariance `Σ = (1/n) Σ (dst_i − μ_dst)(src_i − μ_src)ᵀ` (38), `Σ = U D Vᵀ`,
/// `S = diag(1, 1, −1)` when `det U · det V < 0` else `I` (39/43), `R = U S Vᵀ` (40),
/// `s = tr(D S) / σ²_src` (42), `t = μ_dst − s R μ_src` (41).
///
/// # Errors
/// As [`horn`].
pub fn umeyama(
    src: &[Point3<f64>],
    dst: &[Point3<f64>],
    with_scale: bool,
) -> Result<SimilarityFit, GeometryError> {
    let m = Moments::new(src, dst)?;
    let svd = SVD::new(m.cov, true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(GeometryError::NumericalFailure { what: "SVD" });
    };
    let mut s_diag = Vector3::new(1.0, 1.0, 1.0);
    if u.determinant() * v_t.determinant() < 0.0 {
        s_diag.z = -1.0;
    }
    let r = u * Matrix3::from_diagonal(&s_diag) * v_t;
    let scale = if with_scale {
        svd.singular_values.dot(&s_diag) / m.src_var
    } else {
        1.0
    };
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Ok(m.fit(rotation, scale))
}

/// Horn's symmetric matrix `N` (eq. 27 ff.) from `M = Σ a_i b_iᵀ`, where `M[(i, j)]` pairs
/// source coordinate `i` with destination coordinate `j`. Its eigenvector for the largest
/// eigenvalue is the quaternion `(w, x, y, z)` rotating source into destination.
fn horn_matrix(m: &Matrix3<f64>) -> Matrix4<f64> {
    let (sxx, sxy, sxz) = (m[(0, 0)], m[(0, 1)], m[(0, 2)]);
    let (syx, syy, syz) = (m[(1, 0)], m[(1, 1)], m[(1, 2)]);
    let (szx, szy, szz) = (m[(2, 0)], m[(2, 1)], m[(2, 2)]);
    #[rustfmt::skip]
    let n = Matrix4::new(
        sxx + syy + szz, syz - szy,       szx - sxz,        sxy - syx,
        syz - szy,       sxx - syy - szz, sxy + syx,        szx + sxz,
        szx - sxz,       sxy + syx,       -sxx + syy - szz, syz + szy,
        sxy - syx,       szx + sxz,       syz + szy,        -sxx - syy + szz,
    );
    n
}

/// Centroids and second moments of a validated pair of point sets, all divided by `n`.
struct Moments {
    src_mean: Vector3<f64>,
    dst_mean: Vector3<f64>,
    /// `(1/n) Σ (dst_i − μ_dst)(src_i − μ_src)ᵀ`
    cov: Matrix3<f64>,
    /// `(1/n) Σ |src_i − μ_src|²`
    src_var: f64,
    /// `(1/n) Σ |dst_i − μ_dst|²`
    dst_var: f64,
}

/// Fewest point pairs that fix a rotation.
const MIN_POINTS: usize = 3;

/// A point set whose second-largest scatter eigenvalue is below this fraction of the largest is
/// collinear to working precision (singular values 1e-6 apart: 1 mm of spread across 1 km).
const COLLINEAR_EIGEN_RATIO: f64 = 1e-12;

impl Moments {
    fn new(src: &[Point3<f64>], dst: &[Point3<f64>]) -> Result<Self, GeometryError> {
        if src.len() != dst.len() {
            return Err(GeometryError::LengthMismatch {
                src: src.len(),
                dst: dst.len(),
            });
        }
        if src.len() < MIN_POINTS {
            return Err(GeometryError::TooFewPoints {
                got: src.len(),
                min: MIN_POINTS,
            });
        }
        let src_mean = checked_mean(src, "source")?;
        let dst_mean = checked_mean(dst, "destination")?;
        let inv_n = 1.0 / src.len() as f64;
        let mut cov = Matrix3::zeros();
        let mut src_scatter = Matrix3::zeros();
        let mut dst_scatter = Matrix3::zeros();
        for (p, q) in src.iter().zip(dst) {
            let a = p.coords - src_mean;
            let b = q.coords - dst_mean;
            cov += b * a.transpose();
            src_scatter += a * a.transpose();
            dst_scatter += b * b.transpose();
        }
        check_spread(&src_scatter, "source")?;
        check_spread(&dst_scatter, "destination")?;
        Ok(Self {
            src_mean,
            dst_mean,
            cov: cov * inv_n,
            src_var: src_scatter.trace() * inv_n,
            dst_var: dst_scatter.trace() * inv_n,
        })
    }

    /// Completes a fit from its rotation and scale: `t = μ_dst − s R μ_src` (Umeyama eq. 41).
    fn fit(&self, rotation: UnitQuaternion<f64>, scale: f64) -> SimilarityFit {
        let t = self.dst_mean - rotation * (self.src_mean * scale);
        SimilarityFit {
            dst_from_src: Pose3::from_parts(Translation3::from(t), rotation),
            scale,
        }
    }
}

fn checked_mean(points: &[Point3<f64>], set: &'static str) -> Result<Vector3<f64>, GeometryError> {
    if let Some(index) = points
        .iter()
        .position(|p| !p.coords.iter().all(|c| c.is_finite()))
    {
        return Err(GeometryError::NonFinite { set, index });
    }
    let sum: Vector3<f64> = points.iter().map(|p| p.coords).sum();
    Ok(sum / points.len() as f64)
}

/// Rejects coincident or collinear sets from their scatter matrix `Σ a aᵀ`.
fn check_spread(scatter: &Matrix3<f64>, set: &'static str) -> Result<(), GeometryError> {
    let mut eig = scatter.symmetric_eigenvalues();
    eig.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    if eig[0] <= f64::MIN_POSITIVE || eig[1] <= COLLINEAR_EIGEN_RATIO * eig[0] {
        return Err(GeometryError::Degenerate { set });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{random_points, random_pose, random_vector};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    type Solver = fn(&[Point3<f64>], &[Point3<f64>], bool) -> Result<SimilarityFit, GeometryError>;
    const SOLVERS: [(&str, Solver); 2] = [("horn", horn), ("umeyama", umeyama)];

    /// Maps `src` through `scale · pose` and adds uniform noise of ±`noise` per coordinate.
    fn observe(
        rng: &mut ChaCha8Rng,
        src: &[Point3<f64>],
        pose: &Pose3,
        scale: f64,
        noise: f64,
    ) -> Vec<Point3<f64>> {
        src.iter()
            .map(|p| pose * Point3::from(p.coords * scale) + random_vector(rng, noise))
            .collect()
    }

    fn assert_close(a: &SimilarityFit, b: &SimilarityFit, tol: f64, what: &str) {
        let rot = a.dst_from_src.rotation.angle_to(&b.dst_from_src.rotation);
        let trans = (a.dst_from_src.translation.vector - b.dst_from_src.translation.vector).norm();
        let scale = (a.scale - b.scale).abs();
        assert!(
            rot < tol && trans < tol && scale < tol,
            "{what}: rot {rot:e} trans {trans:e} scale {scale:e}"
        );
    }

    #[test]
    fn noisy_rigid_transforms_are_recovered() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for trial in 0..20 {
            let truth = random_pose(&mut rng);
            let src = random_points(&mut rng, 50, 5.0);
            let dst = observe(&mut rng, &src, &truth, 1.0, 0.01);
            for (name, solve) in SOLVERS {
                let fit = solve(&src, &dst, false).unwrap();
                let expected = SimilarityFit {
                    dst_from_src: truth,
                    scale: 1.0,
                };
                assert_close(&fit, &expected, 5e-3, &format!("{name} trial {trial}"));
            }
        }
    }

    #[test]
    fn exact_data_is_fitted_to_rounding() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        for trial in 0..20 {
            let truth = random_pose(&mut rng);
            let scale = rng.gen_range(0.1..10.0);
            // three points: the minimal case
            let src = random_points(&mut rng, 3, 5.0);
            let dst = observe(&mut rng, &src, &truth, scale, 0.0);
            let expected = SimilarityFit {
                dst_from_src: truth,
                scale,
            };
            for (name, solve) in SOLVERS {
                let fit = solve(&src, &dst, true).unwrap();
                assert_close(&fit, &expected, 1e-9, &format!("{name} trial {trial}"));
                for (p, q) in src.iter().zip(&dst) {
                    assert!((fit.transform_point(p) - q).norm() < 1e-9);
                }
            }
            let sym = horn_with(&src, &dst, HornScale::Symmetric).unwrap();
            assert_close(&sym, &expected, 1e-9, &format!("symmetric trial {trial}"));
        }
    }

    #[test]
    fn horn_and_umeyama_agree_on_noisy_data() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for trial in 0..50 {
            let truth = random_pose(&mut rng);
            let scale = rng.gen_range(0.2..5.0);
            let src = random_points(&mut rng, 30, 3.0);
            let dst = observe(&mut rng, &src, &truth, scale, 0.3);
            for with_scale in [false, true] {
                let h = horn(&src, &dst, with_scale).unwrap();
                let u = umeyama(&src, &dst, with_scale).unwrap();
                assert_close(&h, &u, 1e-9, &format!("trial {trial} scale {with_scale}"));
            }
        }
    }

    /// Reference values from evo 1.38.1 `evo.core.geometry.umeyama_alignment` (numpy 2.4.6)
    /// on the points below, with and without scale.
    #[test]
    fn umeyama_matches_evo() {
        let pts = |v: &[[f64; 3]]| v.iter().map(|p| Point3::from(*p)).collect::<Vec<_>>();
        let src = pts(&[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 3.0],
            [1.5, -0.5, 2.0],
            [-1.0, 1.0, 0.5],
            [2.0, 2.0, -1.0],
        ]);
        let dst = pts(&[
            [1.0, 2.0, 3.0],
            [1.3, 3.9, 2.8],
            [-2.9, 2.4, 3.1],
            [1.2, 1.7, 8.9],
            [0.4, 4.1, 6.7],
            [1.8, 0.2, 4.0],
            [-1.5, 6.1, 0.9],
        ]);
        let r = Matrix3::new(
            -0.1653740625012108,
            -0.9724966718479533,
            -0.16401720244077853,
            0.9823425576011384,
            -0.14767476693207887,
            -0.11487063479066426,
            0.08749010788368947,
            -0.18011770167368307,
            0.979746444018191,
        );
        let cases = [
            (
                false,
                Vector3::new(0.9990173790076473, 2.5918936223069085, 3.6422078974081145),
                1.0,
            ),
            (
                true,
                Vector3::new(1.6223216900324964, 2.344816754620354, 3.2147236973993856),
                1.7663862539866435,
            ),
        ];
        for (with_scale, t, scale) in cases {
            let fit = umeyama(&src, &dst, with_scale).unwrap();
            let r_fit = fit.dst_from_src.rotation.to_rotation_matrix();
            assert!((r_fit.matrix() - r).abs().max() < 1e-12, "{with_scale}");
            assert!(
                (fit.dst_from_src.translation.vector - t).abs().max() < 1e-12,
                "{with_scale}"
            );
            assert!((fit.scale - scale).abs() < 1e-12, "{with_scale}");
        }
    }

    #[test]
    fn reflected_data_still_gives_a_rotation() {
        // dst is a mirror image of src: the best proper rotation needs Umeyama's S fix.
        let mut rng = ChaCha8Rng::seed_from_u64(10);
        for trial in 0..20 {
            let src = random_points(&mut rng, 20, 2.0);
            let dst: Vec<_> = src.iter().map(|p| Point3::new(p.x, p.y, -p.z)).collect();
            let h = horn(&src, &dst, true).unwrap();
            let u = umeyama(&src, &dst, true).unwrap();
            let det = u
                .dst_from_src
                .rotation
                .to_rotation_matrix()
                .matrix()
                .determinant();
            assert!((det - 1.0).abs() < 1e-12);
            assert_close(&h, &u, 1e-9, &format!("trial {trial}"));
        }
    }

    #[test]
    fn symmetric_scale_inverts_exactly() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let src = random_points(&mut rng, 40, 2.0);
        let truth = random_pose(&mut rng);
        let dst = observe(&mut rng, &src, &truth, 3.0, 0.5);
        let fwd = horn_with(&src, &dst, HornScale::Symmetric).unwrap();
        let back = horn_with(&dst, &src, HornScale::Symmetric).unwrap();
        assert!((fwd.scale * back.scale - 1.0).abs() < 1e-12);
        let fwd = horn_with(&src, &dst, HornScale::Asymmetric).unwrap();
        let back = horn_with(&dst, &src, HornScale::Asymmetric).unwrap();
        assert!(
            (fwd.scale * back.scale - 1.0).abs() > 1e-3,
            "noise should break the inverse"
        );
    }

    #[test]
    fn transform_pose_moves_position_and_orientation() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let fit = SimilarityFit {
            dst_from_src: random_pose(&mut rng),
            scale: 2.0,
        };
        let src_from_body = random_pose(&mut rng);
        let dst_from_body = fit.transform_pose(&src_from_body);
        let origin = Point3::from(src_from_body.translation.vector);
        assert!(
            (Point3::from(dst_from_body.translation.vector) - fit.transform_point(&origin)).norm()
                < 1e-12
        );
        let expected = fit.dst_from_src.rotation * src_from_body.rotation;
        assert!(dst_from_body.rotation.angle_to(&expected) < 1e-12);
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = |x: f64, y: f64, z: f64| Point3::new(x, y, z);
        let good = vec![p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(0.0, 1.0, 0.0)];
        let line = vec![
            p(0.0, 0.0, 0.0),
            p(1.0, 1.0, 1.0),
            p(2.0, 2.0, 2.0),
            p(3.0, 3.0, 3.0),
        ];
        let same = [p(1.0, 2.0, 3.0); 4];
        let mut nan = good.clone();
        nan[1].y = f64::NAN;
        for (name, solve) in SOLVERS {
            assert_eq!(
                solve(&good, &good[..2], false),
                Err(GeometryError::LengthMismatch { src: 3, dst: 2 }),
                "{name}"
            );
            assert_eq!(
                solve(&good[..2], &good[..2], false),
                Err(GeometryError::TooFewPoints { got: 2, min: 3 }),
                "{name}"
            );
            assert_eq!(
                solve(&line, &line, false),
                Err(GeometryError::Degenerate { set: "source" }),
                "{name}"
            );
            assert_eq!(
                solve(&good, &same[..3], true),
                Err(GeometryError::Degenerate { set: "destination" }),
                "{name}"
            );
            assert_eq!(
                solve(&good, &nan, false),
                Err(GeometryError::NonFinite {
                    set: "destination",
                    index: 1
                }),
                "{name}"
            );
        }
    }
}
