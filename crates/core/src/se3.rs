//! The Lie group SE(3) of rigid motions: exponential and logarithm maps, adjoint, and the
//! Jacobians an optimiser on poses needs (Barfoot, "State Estimation for Robotics", 2017,
//! §7.1.3–7.1.5, eqs. 7.37, 7.85–7.86 and 7.95; Solà et al., "A micro Lie theory for state
//! estimation in robotics", 2018).
//!
//! A tangent vector `ξ = (ρ, φ)` holds the translational part first and the rotation vector
//! second, the order of g2o's information matrices; `exp(ξ) = [exp(φ^), J_l(φ) ρ]`. The maps are
//! the exact ones (no first-order shortcut), with series expansions near zero rotation.
//!
//! ```
//! use nalgebra::Vector6;
//! use slamkit_core::se3;
//!
//! let xi = Vector6::new(0.5, -1.0, 2.0, 0.3, -0.2, 0.5);
//! assert!((se3::log(&se3::exp(&xi)) - xi).norm() < 1e-12);
//! ```

use crate::Pose3;
use nalgebra::{Matrix3, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6};

/// Below this rotation angle \[rad\] the Jacobians' coefficients use their Taylor series
/// (the closed forms lose digits to cancellation there; the series' first omitted term is
/// below 1e-17 of the result).
const SMALL_ANGLE_RAD: f64 = 1e-2;

/// The skew-symmetric matrix `v^` with `v^ w = v × w`.
pub fn hat(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The pose `exp(ξ)` of a tangent vector `ξ = (ρ, φ)`.
pub fn exp(xi: &Vector6<f64>) -> Pose3 {
    let rho = xi.fixed_rows::<3>(0).into_owned();
    let phi = xi.fixed_rows::<3>(3).into_owned();
    Pose3::from_parts(
        Translation3::from(so3_left_jacobian(&phi) * rho),
        UnitQuaternion::from_scaled_axis(phi),
    )
}

/// The tangent vector `log(T) = (ρ, φ)` of a pose, the rotation angle in \[0, π\].
pub fn log(pose: &Pose3) -> Vector6<f64> {
    let phi = pose.rotation.scaled_axis();
    let rho = so3_left_jacobian_inv(&phi) * pose.translation.vector;
    let mut xi = Vector6::zeros();
    xi.fixed_rows_mut::<3>(0).copy_from(&rho);
    xi.fixed_rows_mut::<3>(3).copy_from(&phi);
    xi
}

/// The adjoint `Ad(T)` with `T exp(ξ) = exp(Ad(T) ξ) T`: `[[R, t^R], [0, R]]`.
pub fn adjoint(pose: &Pose3) -> Matrix6<f64> {
    let r = *pose.rotation.to_rotation_matrix().matrix();
    let mut ad = Matrix6::zeros();
    ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    ad.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(hat(&pose.translation.vector) * r));
    ad.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
    ad
}

/// The inverse of the right Jacobian of SE(3): `log(exp(ξ) exp(δ)) ≈ ξ + J_r⁻¹(ξ) δ` for small
/// `δ`. Uses `J_r(ξ) = J_l(−ξ)` and the block form `J_l⁻¹ = [[J⁻¹, −J⁻¹ Q J⁻¹], [0, J⁻¹]]`.
pub fn right_jacobian_inv(xi: &Vector6<f64>) -> Matrix6<f64> {
    let rho = -xi.fixed_rows::<3>(0).into_owned();
    let phi = -xi.fixed_rows::<3>(3).into_owned();
    let j_inv = so3_left_jacobian_inv(&phi);
    let q = se3_q(&rho, &phi);
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&j_inv);
    m.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-j_inv * q * j_inv));
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&j_inv);
    m
}

/// The left Jacobian of SO(3), `J_l(φ) = I + (1 − cos θ)/θ² φ^ + (θ − sin θ)/θ³ φ^²`.
fn so3_left_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let (a, b) = if theta < SMALL_ANGLE_RAD {
        let t2 = theta * theta;
        (
            0.5 - t2 / 24.0 + t2 * t2 / 720.0,
            1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0,
        )
    } else {
        let t2 = theta * theta;
        (
            (1.0 - theta.cos()) / t2,
            (theta - theta.sin()) / (t2 * theta),
        )
    };
    let k = hat(phi);
    Matrix3::identity() + k * a + k * k * b
}

/// The inverse left Jacobian of SO(3), `I − ½φ^ + (1/θ² − cot(θ/2)/(2θ)) φ^²` (finite up to
/// θ = π).
fn so3_left_jacobian_inv(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let c = if theta < SMALL_ANGLE_RAD {
        let t2 = theta * theta;
        1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0
    } else {
        1.0 / (theta * theta) - 1.0 / (2.0 * theta * (0.5 * theta).tan())
    };
    let k = hat(phi);
    Matrix3::identity() - k * 0.5 + k * k * c
}

/// Barfoot's `Q(ρ, φ)`, the upper-right block of the left Jacobian of SE(3) (eq. 7.86).
fn se3_q(rho: &Vector3<f64>, phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let t2 = theta * theta;
    let (a, b, c) = if theta < SMALL_ANGLE_RAD {
        (
            1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0,
            1.0 / 24.0 - t2 / 720.0 + t2 * t2 / 40320.0,
            1.0 / 120.0 - t2 / 2520.0 + t2 * t2 / 120960.0,
        )
    } else {
        let (s, co) = theta.sin_cos();
        (
            (theta - s) / (t2 * theta),
            (t2 + 2.0 * co - 2.0) / (2.0 * t2 * t2),
            (2.0 * theta - 3.0 * s + theta * co) / (2.0 * t2 * t2 * theta),
        )
    };
    let (r, p) = (hat(rho), hat(phi));
    let (pr, rp, prp) = (p * r, r * p, p * r * p);
    r * 0.5 + (pr + rp + prp) * a + (p * pr + rp * p - prp * 3.0) * b + (prp * p + p * prp) * c
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples() -> Vec<Vector6<f64>> {
        vec![
            Vector6::new(0.5, -1.0, 2.0, 0.3, -0.2, 0.5),
            Vector6::new(1.0, 2.0, 3.0, 1e-3, -2e-3, 5e-4),
            Vector6::new(-0.3, 0.1, 0.7, 2.5, 0.8, -1.0),
            Vector6::new(0.2, 0.0, -0.1, 0.0, 0.0, 0.0),
            Vector6::new(0.2, 0.4, -0.1, 0.006, -0.004, 0.005),
        ]
    }

    #[test]
    fn log_inverts_exp() {
        for xi in samples() {
            assert!((log(&exp(&xi)) - xi).norm() < 1e-12, "{xi}");
        }
        // A rotation of π keeps a finite logarithm.
        let half_turn = Pose3::from_parts(
            Translation3::new(1.0, 0.0, 0.0),
            UnitQuaternion::from_scaled_axis(Vector3::z() * std::f64::consts::PI),
        );
        assert!(
            (exp(&log(&half_turn)).to_homogeneous() - half_turn.to_homogeneous()).norm() < 1e-12
        );
    }

    #[test]
    fn exp_of_a_pure_rotation_keeps_the_origin() {
        let p = exp(&Vector6::new(0.0, 0.0, 0.0, 0.1, 0.2, 0.3));
        assert!(p.translation.vector.norm() < 1e-15);
        assert!((p.rotation.scaled_axis() - Vector3::new(0.1, 0.2, 0.3)).norm() < 1e-15);
    }

    #[test]
    fn adjoint_moves_a_perturbation_across_the_pose() {
        let t = exp(&Vector6::new(0.5, -1.0, 2.0, 0.3, -0.2, 0.5));
        let d = Vector6::new(0.01, 0.02, -0.03, 0.02, -0.01, 0.03);
        let left = t * exp(&d);
        let right = exp(&(adjoint(&t) * d)) * t;
        assert!((left.to_homogeneous() - right.to_homogeneous()).norm() < 1e-12);
    }

    #[test]
    fn right_jacobian_inverse_matches_finite_differences() {
        let h = 1e-6;
        for xi in samples() {
            let analytic = right_jacobian_inv(&xi);
            let t = exp(&xi);
            for k in 0..6 {
                let mut d = Vector6::zeros();
                d[k] = h;
                let up = log(&(t * exp(&d)));
                let down = log(&(t * exp(&(-d))));
                let numeric = (up - down) / (2.0 * h);
                assert!(
                    (numeric - analytic.column(k)).norm() < 1e-7,
                    "ξ = {xi}, column {k}: {numeric} vs {}",
                    analytic.column(k)
                );
            }
        }
    }
}
