//! Accuracy of a VO trajectory against ground truth: ATE RMSE after SE(3) alignment and RPE
//! over one frame (Sturm et al., IROS 2012, via `slamkit_eval`), and the end-point drift as a
//! percentage of the travelled path, the estimate moved to start at the ground truth's pose of
//! its first frame (a session starts wherever it is told, identity by default).

use nalgebra::Point3;
use serde::Serialize;
use slamkit_core::Trajectory;
use slamkit_eval::{associate, ate, rpe, Alignment, ErrorStats, EvalError, Pairing, RpeConfig};

/// Accuracy figures of one run.
#[derive(Debug, Clone, Serialize)]
pub struct VoMetrics {
    /// Absolute trajectory error after SE(3) alignment \[m\].
    pub ate: ErrorStats,
    /// Relative pose error over one frame \[m\].
    pub rpe: ErrorStats,
    /// Distance between the last estimated and true positions, the estimate's first pose put
    /// on the true one \[m\].
    pub end_point_error_m: f64,
    /// Length of the ground-truth path over the estimated frames \[m\].
    pub path_length_m: f64,
    /// `end_point_error_m` as a percentage of `path_length_m`.
    pub end_point_drift_percent: f64,
}

/// Scores `estimate` against `ground_truth`, pairing poses by time stamp.
///
/// # Errors
/// [`EvalError`] when the trajectories cannot be paired or aligned.
pub fn evaluate(estimate: &Trajectory, ground_truth: &Trajectory) -> Result<VoMetrics, EvalError> {
    let pairing = Pairing::default();
    let ate = ate(ground_truth, estimate, pairing, Alignment::Se3)?;
    let rpe = rpe(ground_truth, estimate, pairing, &RpeConfig::default())?;
    let no_pairs = || EvalError::NoPairs {
        estimate: estimate.len(),
        reference: ground_truth.len(),
    };
    let first = *associate(ground_truth, estimate, pairing)?
        .first()
        .ok_or_else(no_pairs)?;
    let (Some(gt_start), Some(est_start)) = (
        ground_truth.poses.get(first.reference),
        estimate.poses.get(first.estimate),
    ) else {
        return Err(no_pairs());
    };
    let anchored = gt_start.pose * est_start.pose.inverse();
    let (Some(est_end), Some(gt_end)) = (estimate.poses.last(), ate.reference_positions.last())
    else {
        return Err(no_pairs());
    };
    let path: f64 = ate
        .reference_positions
        .windows(2)
        .map(|w| (w[1] - w[0]).norm())
        .sum();
    let end = (anchored * Point3::from(est_end.pose.translation.vector) - gt_end).norm();
    Ok(VoMetrics {
        ate: ate.stats,
        rpe: rpe.stats,
        end_point_error_m: end,
        path_length_m: path,
        end_point_drift_percent: if path > 0.0 {
            100.0 * end / path
        } else {
            f64::NAN
        },
    })
}
