//! Weight bookkeeping shared by the particle filters: log-weight normalisation, the effective
//! sample size and low-variance resampling.
//!
//! Weights are kept as logarithms, since a scan's likelihood is a product over hundreds of
//! beams. The effective sample size `N_eff = 1 / Σ wᵢ²` (Liu 1996) measures how many particles
//! still carry weight; resampling only when it drops below `N/2` keeps diversity (Doucet et al.
//! 2000; Grisetti et al., IEEE T-RO 23(1), 2007, section IV). Resampling is systematic
//! ("low variance", Thrun et al., *Probabilistic Robotics*, table 4.4): one random offset, so a
//! particle of weight `w` is copied `⌊N·w⌋` or `⌈N·w⌉` times.

use crate::error::FieldCheck;
use rand::Rng;
use slamkit_core::pose::wrap_angle;
use slamkit_core::Pose2;

/// True when the odometry `increment` since the last filter update moved at least `linear_m`
/// or turned at least `angular_rad`: the filters update only then (GMapping `linearUpdate`,
/// `angularUpdate`).
pub fn moved_enough(increment: &Pose2, linear_m: f64, angular_rad: f64) -> bool {
    increment.translation.vector.norm() >= linear_m
        || wrap_angle(increment.rotation.angle()).abs() >= angular_rad
}

/// Range checks `(field, value, ok)` of the settings both filters share: the update thresholds
/// and the resampling threshold.
pub(crate) fn filter_checks(
    update_linear_m: f64,
    update_angular_rad: f64,
    resample_threshold: f64,
) -> [FieldCheck; 3] {
    [
        ("update_linear_m", update_linear_m, update_linear_m >= 0.0),
        (
            "update_angular_rad",
            update_angular_rad,
            update_angular_rad >= 0.0,
        ),
        (
            "resample_threshold",
            resample_threshold,
            (0.0..=1.0).contains(&resample_threshold),
        ),
    ]
}

/// Normalised weights `exp(lᵢ − max l) / Σ` of the log-weights `log_weights`; uniform when they
/// are all −∞ or NaN.
pub fn normalized_weights(log_weights: &[f64]) -> Vec<f64> {
    let max = log_weights
        .iter()
        .copied()
        .filter(|l| l.is_finite())
        .fold(f64::NEG_INFINITY, f64::max);
    if !max.is_finite() {
        return vec![1.0 / log_weights.len().max(1) as f64; log_weights.len()];
    }
    let w: Vec<f64> = log_weights
        .iter()
        .map(|l| if l.is_finite() { (l - max).exp() } else { 0.0 })
        .collect();
    let sum: f64 = w.iter().sum();
    w.into_iter().map(|x| x / sum).collect()
}

/// Effective sample size `1 / Σ wᵢ²` of normalised weights.
pub fn effective_sample_size(weights: &[f64]) -> f64 {
    let sum_sq: f64 = weights.iter().map(|w| w * w).sum();
    if sum_sq > 0.0 {
        1.0 / sum_sq
    } else {
        0.0
    }
}

/// Indices of `count` particles drawn by low-variance resampling from normalised `weights`.
pub fn low_variance_resample(weights: &[f64], count: usize, rng: &mut impl Rng) -> Vec<usize> {
    if weights.is_empty() || count == 0 {
        return Vec::new();
    }
    let step = 1.0 / count as f64;
    let mut u = rng.gen::<f64>() * step;
    let mut cumulative = weights[0];
    let mut i = 0;
    let mut picks = Vec::with_capacity(count);
    for _ in 0..count {
        while u > cumulative && i + 1 < weights.len() {
            i += 1;
            cumulative += weights[i];
        }
        picks.push(i);
        u += step;
    }
    picks
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn normalisation_survives_huge_log_weights() {
        // Log-weights 1 apart (exactly representable at 1e6): weights 1/(1+e) and e/(1+e).
        let w = normalized_weights(&[-1e6, -1e6 + 1.0, f64::NEG_INFINITY, f64::NAN]);
        let e = 1f64.exp();
        assert!((w[0] - 1.0 / (1.0 + e)).abs() < 1e-12 && (w[1] - e / (1.0 + e)).abs() < 1e-12);
        assert_eq!((w[2], w[3]), (0.0, 0.0));
        assert_eq!(normalized_weights(&[f64::NAN; 4]), vec![0.25; 4]);
    }

    #[test]
    fn effective_sample_size_bounds() {
        assert!((effective_sample_size(&[0.25; 4]) - 4.0).abs() < 1e-12);
        assert!((effective_sample_size(&[1.0, 0.0, 0.0]) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn resampling_copies_in_proportion_to_weight() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let picks = low_variance_resample(&[0.5, 0.25, 0.0, 0.25], 8, &mut rng);
        let count = |k| picks.iter().filter(|&&p| p == k).count();
        assert_eq!((count(0), count(1), count(2), count(3)), (4, 2, 0, 2));
        assert!(low_variance_resample(&[], 3, &mut rng).is_empty());
    }
}
