//! Accuracy of a VO trajectory against ground truth: ATE RMSE after SE(3) alignment and RPE
//! over one frame (Sturm et al., IROS 2012, via `slamkit_eval`), and the end-point drift as a
//! percentage of the travelled path, the estimate moved to start at the ground truth's pose of
//! its first frame (a session starts wherever it is told, identity by default).
//!
//! Only estimated poses with ground truth are scored; how many had none is reported
//! ([`VoMetrics::frames_without_ground_truth`]), and the end point is the last *scored* pose, so
//! ground truth shorter than the sequence cannot turn into a meaningless drift figure.

use nalgebra::Point3;
use serde::Serialize;
use slamkit_core::{Pose3, Trajectory};
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
    /// Estimated poses paired with a ground-truth pose, and so scored.
    pub scored_frames: usize,
    /// Estimated poses without a ground-truth pose within the pairing tolerance, not scored.
    pub frames_without_ground_truth: usize,
}

/// Below this path length \[m\] the end-point error is not given as a percentage of the path:
/// a centimetre over a few centimetres of path would read as tens of percent.
const MIN_PATH_FOR_DRIFT_M: f64 = 1.0;

impl std::fmt::Display for VoMetrics {
    /// One line of ATE, RPE and end-point drift (as an error in metres on paths under a metre),
    /// and a second naming the frames left unscored, when there were some.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let path_m = self.path_length_m;
        let end_point = if path_m >= MIN_PATH_FOR_DRIFT_M {
            let drift = self.end_point_drift_percent;
            format!("end-point drift {drift:.2} % of {path_m:.1} m")
        } else {
            let error = self.end_point_error_m;
            format!(
                "end-point error {error:.3} m (the path, {path_m:.2} m, is too short for a \
                 percentage)"
            )
        };
        let (ate, rpe) = (self.ate.rmse, self.rpe.rmse);
        write!(f, "ATE RMSE {ate:.4} m, RPE RMSE {rpe:.4} m, {end_point}")?;
        if self.frames_without_ground_truth > 0 {
            write!(
                f,
                "\nscored {} posed frames; {} without ground truth were not scored",
                self.scored_frames, self.frames_without_ground_truth
            )?;
        }
        Ok(())
    }
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
    let pairs = associate(ground_truth, estimate, pairing)?;
    let (Some(first), Some(last)) = (pairs.first(), pairs.last()) else {
        return Err(no_pairs());
    };
    let (Some(gt_start), Some(est_start), Some(gt_end), Some(est_end)) = (
        ground_truth.poses.get(first.reference),
        estimate.poses.get(first.estimate),
        ground_truth.poses.get(last.reference),
        estimate.poses.get(last.estimate),
    ) else {
        return Err(no_pairs());
    };
    let anchored = gt_start.pose * est_start.pose.inverse();
    let gt_end = Point3::from(gt_end.pose.translation.vector);
    let mut scored: Vec<usize> = pairs.iter().map(|p| p.estimate).collect();
    scored.sort_unstable();
    scored.dedup();
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
        scored_frames: scored.len(),
        frames_without_ground_truth: estimate.len().saturating_sub(scored.len()),
    })
}

/// A loop closure is wrong when the ground truth's relative pose differs from it by more than
/// this \[m\] (issue 20's bar)...
pub const WRONG_CLOSURE_M: f64 = 0.3;
/// ... or by more than this \[deg\].
pub const WRONG_CLOSURE_DEG: f64 = 10.0;

/// Loop closures scored against ground truth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ClosureCheck {
    /// Closures both of whose times the ground truth covers.
    pub checked: usize,
    /// Closures off by more than [`WRONG_CLOSURE_M`] or [`WRONG_CLOSURE_DEG`].
    pub wrong: usize,
    /// Largest translation error \[m\] (0 without checked closures).
    pub max_error_m: f64,
    /// Largest rotation error \[deg\].
    pub max_error_deg: f64,
}

/// Scores loop closures `(query time, candidate time, candidate_from_query)` against the
/// relative pose of the ground truth (interpolated at the two times).
pub fn check_closures(closures: &[(f64, f64, Pose3)], ground_truth: &Trajectory) -> ClosureCheck {
    let mut check = ClosureCheck {
        checked: 0,
        wrong: 0,
        max_error_m: 0.0,
        max_error_deg: 0.0,
    };
    for (query, candidate, candidate_from_query) in closures {
        let (Some(q), Some(c)) = (
            ground_truth.interpolate(*query),
            ground_truth.interpolate(*candidate),
        ) else {
            continue;
        };
        let error = (c.inverse() * q).inverse() * candidate_from_query;
        let (m, deg) = (
            error.translation.vector.norm(),
            error.rotation.angle().to_degrees(),
        );
        check.checked += 1;
        check.wrong += usize::from(m > WRONG_CLOSURE_M || deg > WRONG_CLOSURE_DEG);
        check.max_error_m = check.max_error_m.max(m);
        check.max_error_deg = check.max_error_deg.max(deg);
    }
    check
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn a_closure_is_wrong_beyond_30_cm_or_10_degrees() {
        let mut gt = Trajectory::new();
        for i in 0..11 {
            let a = f64::from(i) * 0.6;
            gt.push(
                f64::from(i),
                Pose3::new(Vector3::new(a.cos(), a.sin(), 0.0), Vector3::z() * a),
            );
        }
        let truth =
            |q: f64, c: f64| gt.interpolate(c).unwrap().inverse() * gt.interpolate(q).unwrap();
        let right = (
            9.0,
            1.0,
            truth(9.0, 1.0) * Pose3::translation(0.1, 0.0, 0.0),
        );
        let far = (
            8.0,
            2.0,
            truth(8.0, 2.0) * Pose3::translation(0.0, 0.35, 0.0),
        );
        let turned = (
            7.0,
            2.0,
            truth(7.0, 2.0) * Pose3::new(Vector3::zeros(), Vector3::x() * 12f64.to_radians()),
        );
        let outside = (50.0, 1.0, Pose3::identity());
        let check = check_closures(&[right, far, turned, outside], &gt);
        assert_eq!((check.checked, check.wrong), (3, 2));
        assert!((check.max_error_m - 0.35).abs() < 1e-9);
        assert!((check.max_error_deg - 12.0).abs() < 1e-9);
    }

    /// Issue 25 (9): ground truth for the first 20 of 40 frames; the estimate is exact there
    /// and wanders off after. Only the 20 are scored, and the end point is the 20th.
    #[test]
    fn ground_truth_shorter_than_the_estimate_scores_only_its_frames() {
        let (mut gt, mut est) = (Trajectory::new(), Trajectory::new());
        for i in 0..40 {
            let t = f64::from(i) * 0.1;
            let truth = Pose3::translation(f64::from(i) * 0.1, 0.02 * f64::from(i % 3), 0.0);
            if i < 20 {
                gt.push(t, truth);
                est.push(t, truth);
            } else {
                est.push(t, Pose3::translation(5.0, f64::from(i), 0.0));
            }
        }
        let m = evaluate(&est, &gt).unwrap();
        assert_eq!((m.scored_frames, m.frames_without_ground_truth), (20, 20));
        assert!(m.end_point_error_m < 1e-9, "{}", m.end_point_error_m);
        assert!(m.ate.rmse < 1e-9 && m.end_point_drift_percent < 1e-6);
        // every frame with ground truth: nothing left out
        let m = evaluate(&gt, &gt).unwrap();
        assert_eq!((m.scored_frames, m.frames_without_ground_truth), (20, 0));
    }
}
