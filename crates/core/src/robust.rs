//! Robust kernels for least squares: an error far outside its expected spread (a wrong loop
//! closure, an outlier match) should pull with bounded force. Used by iteratively reweighted
//! least squares (Holland & Welsch 1977; Zhang, "Parameter estimation techniques", 1997).

/// The Cauchy kernel on a squared Mahalanobis error `χ²` with scale `k`: the cost
/// `½ k² ln(1 + χ²/k²)` and the weight `1 / (1 + χ²/k²)` of the error in the next reweighted
/// step; without a (positive) scale, plain least squares: `(½χ², 1)`. GTSAM's
/// `noiseModel::mEstimator::Cauchy` has the same cost.
///
/// ```
/// use slamkit_core::robust::cauchy;
/// assert_eq!(cauchy(None, 4.0), (2.0, 1.0));
/// let (cost, weight) = cauchy(Some(1.0), 3.0);
/// assert!((cost - 0.5 * 4f64.ln()).abs() < 1e-15 && weight == 0.25);
/// ```
pub fn cauchy(scale: Option<f64>, chi2: f64) -> (f64, f64) {
    match scale {
        Some(k) if k > 0.0 => {
            let k2 = k * k;
            (0.5 * k2 * (1.0 + chi2 / k2).ln(), 1.0 / (1.0 + chi2 / k2))
        }
        _ => (0.5 * chi2, 1.0),
    }
}
