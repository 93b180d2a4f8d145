//! One scalar measurement in an error-state Kalman filter, the step that the heading filter
//! ([`super::heading`]) and the velocity filter ([`super::velocity`]) both take for every
//! match, with the same innovation gate.

use nalgebra::{SMatrix, SVector};

/// The update of an error state (zero before the measurement) with covariance `p` by one
/// scalar measurement `hᵀ δx`, read as `innovation` with variance `r`: the state's correction
/// and its covariance after. `None` when the innovation is further than `max_sigmas` standard
/// deviations of the prediction and the measurement together allow (a false measurement).
pub fn scalar_update<const N: usize>(
    p: &SMatrix<f64, N, N>,
    h: &SVector<f64, N>,
    innovation: f64,
    r: f64,
    max_sigmas: f64,
) -> Option<(SVector<f64, N>, SMatrix<f64, N, N>)> {
    let variance = (h.transpose() * p * h).x + r;
    if innovation.powi(2) > max_sigmas.powi(2) * variance {
        return None;
    }
    let gain = p * h / variance;
    Some((
        gain * innovation,
        (SMatrix::identity() - gain * h.transpose()) * p,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2};

    #[test]
    fn equal_variances_meet_halfway_and_a_far_reading_is_dropped() {
        // state (a, b) with a known to 1 (variance 1), b correlated with a
        let p = Matrix2::new(1.0, 0.5, 0.5, 1.0);
        let h = Vector2::new(1.0, 0.0);
        let (dx, after) = scalar_update(&p, &h, 2.0, 1.0, 3.0).unwrap();
        assert!((dx - Vector2::new(1.0, 0.5)).norm() < 1e-12, "{dx}");
        assert!((after[(0, 0)] - 0.5).abs() < 1e-12 && (after[(1, 1)] - 0.875).abs() < 1e-12);
        // 2 standard deviations of the two together (variance 2) pass, 5 do not
        assert!(scalar_update(&p, &h, 2.0 * 2f64.sqrt(), 1.0, 3.0).is_some());
        assert!(scalar_update(&p, &h, 5.0 * 2f64.sqrt(), 1.0, 3.0).is_none());
    }
}
