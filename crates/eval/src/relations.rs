//! The relations metric of Kümmerle et al., "On measuring the accuracy of SLAM algorithms",
//! Autonomous Robots 27(4), 2009 — the error measure of the standard 2D lidar benchmark logs
//! (Intel, ACES, MIT CSAIL, MIT Killian), whose `*.relations` files give ground-truth relative
//! motions between pairs of scan times.
//!
//! For each relation `(t1, t2, δ*)` (the motion from the pose at t1 to the pose at t2, in the
//! frame of t1): the estimated motion is `δ = P(t1)⁻¹ P(t2)`, the error `ε = δ*⁻¹ δ`; the
//! translational error is `|trans(ε)|` \[m\] and the rotational error `|angle(ε)|` wrapped into
//! [0°, 180°]. Reported are mean ± population std of both (Kümmerle eq. 2 with absolute rather
//! than squared errors; the squared means are given too). Estimated poses are found by
//! timestamp within [`RELATION_STAMP_TOLERANCE_S`]; a relation with an end that has no pose is
//! counted as missing, not scored.

use crate::stats::mean_std;
use crate::EvalError;
use serde::{Deserialize, Serialize};
use slamkit_core::{Pose3, Trajectory};

/// Largest time difference between a relation's timestamp and the estimated pose used for it
/// \[s\]. Relation stamps equal scan stamps (to 6 decimals) in the benchmark logs.
pub const RELATION_STAMP_TOLERANCE_S: f64 = 1e-3;

/// One ground-truth relative motion: the type [`slamkit_io::relations::read_relations`] reads, so
/// a `.relations` file is scored as read.
pub use slamkit_io::relations::Relation as GroundTruthRelation;

/// Result of the relations metric; the field names are the `--json` keys of
/// `slamkit eval relations` (DESIGN.md), plus the squared means and `missing`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RelationsStats {
    /// Mean translational error \[m\].
    pub trans_mean: f64,
    /// Population std of the translational error \[m\].
    pub trans_std: f64,
    /// Mean rotational error \[deg\].
    pub rot_mean_deg: f64,
    /// Population std of the rotational error \[deg\].
    pub rot_std_deg: f64,
    /// Mean squared translational error \[m²\].
    pub trans_sq_mean: f64,
    /// Mean squared rotational error \[deg²\].
    pub rot_sq_mean_deg2: f64,
    /// Relations scored.
    pub count: usize,
    /// Relations skipped because an end had no estimated pose within the tolerance.
    pub missing: usize,
}

/// The metric as `slamkit eval relations` prints it: counts, then translation and rotation
/// error (mean ± std, and mean squared), one line each.
impl std::fmt::Display for RelationsStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = self;
        writeln!(
            f,
            "relations metric: {} relations scored, {} without estimated poses",
            s.count, s.missing
        )?;
        writeln!(
            f,
            "  translation  {:>10.7} ± {:.7} m    (mean squared {:.7} m²)",
            s.trans_mean, s.trans_std, s.trans_sq_mean
        )?;
        writeln!(
            f,
            "  rotation     {:>10.7} ± {:.7} deg  (mean squared {:.7} deg²)",
            s.rot_mean_deg, s.rot_std_deg, s.rot_sq_mean_deg2
        )
    }
}

/// The error of one scored relation: what [`relations_error`] averages, and what a report
/// draws over time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RelationError {
    /// The relation's first timestamp \[s\].
    pub t1: f64,
    /// Its second timestamp \[s\].
    pub t2: f64,
    /// Translational error \[m\].
    pub trans_m: f64,
    /// Rotational error \[deg\].
    pub rot_deg: f64,
}

/// The error of every relation of `relations` whose two ends have an estimated pose, in the
/// file's order.
///
/// # Errors
/// [`EvalError::NonFiniteTimestamp`] for a NaN stamp in the estimate, [`EvalError::NonFiniteError`]
/// (relation index) for a broken pose.
pub fn relation_errors(
    relations: &[GroundTruthRelation],
    estimate: &Trajectory,
) -> Result<Vec<RelationError>, EvalError> {
    let index = StampIndex::new(estimate)?;
    let mut errors = Vec::with_capacity(relations.len());
    for (i, rel) in relations.iter().enumerate() {
        let (Some(p1), Some(p2)) = (index.pose_at(rel.t1), index.pose_at(rel.t2)) else {
            continue;
        };
        let error = rel.t1_from_t2.inverse() * (p1.inverse() * p2);
        let (trans_m, rot_deg) = (
            error.translation.vector.norm(),
            error.rotation.angle().to_degrees(),
        );
        if !(trans_m.is_finite() && rot_deg.is_finite()) {
            return Err(EvalError::NonFiniteError { index: i });
        }
        errors.push(RelationError {
            t1: rel.t1,
            t2: rel.t2,
            trans_m,
            rot_deg,
        });
    }
    Ok(errors)
}

/// Scores `estimate` on `relations`: the statistics of [`relation_errors`].
///
/// # Errors
/// As [`relation_errors`], and [`EvalError::NoRelations`] when no relation can be scored.
pub fn relations_error(
    relations: &[GroundTruthRelation],
    estimate: &Trajectory,
) -> Result<RelationsStats, EvalError> {
    let errors = relation_errors(relations, estimate)?;
    let trans: Vec<f64> = errors.iter().map(|e| e.trans_m).collect();
    let rot_deg: Vec<f64> = errors.iter().map(|e| e.rot_deg).collect();
    let (Some((trans_mean, trans_std)), Some((rot_mean_deg, rot_std_deg))) =
        (mean_std(&trans), mean_std(&rot_deg))
    else {
        return Err(EvalError::NoRelations {
            relations: relations.len(),
        });
    };
    let sq_mean = |v: &[f64]| v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64;
    Ok(RelationsStats {
        trans_mean,
        trans_std,
        rot_mean_deg,
        rot_std_deg,
        trans_sq_mean: sq_mean(&trans),
        rot_sq_mean_deg2: sq_mean(&rot_deg),
        count: trans.len(),
        missing: relations.len() - trans.len(),
    })
}

/// Estimated poses sorted by time, for nearest-stamp look-up (logs may step back in time).
struct StampIndex<'a> {
    sorted: Vec<(f64, &'a Pose3)>,
}

impl<'a> StampIndex<'a> {
    fn new(traj: &'a Trajectory) -> Result<Self, EvalError> {
        if let Some(index) = traj.poses.iter().position(|p| !p.timestamp.is_finite()) {
            return Err(EvalError::NonFiniteTimestamp {
                which: "estimate",
                index,
            });
        }
        let mut sorted: Vec<_> = traj.poses.iter().map(|p| (p.timestamp, &p.pose)).collect();
        sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(Self { sorted })
    }

    /// The pose nearest in time to `t`, if within the tolerance (the earlier one on a tie).
    fn pose_at(&self, t: f64) -> Option<&'a Pose3> {
        let upper = self.sorted.partition_point(|(s, _)| *s < t);
        let candidates = [upper.checked_sub(1), Some(upper)];
        candidates
            .into_iter()
            .flatten()
            .filter_map(|i| self.sorted.get(i))
            .map(|&(s, pose)| ((s - t).abs(), pose))
            .filter(|(d, _)| *d <= RELATION_STAMP_TOLERANCE_S)
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, pose)| pose)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    #[test]
    fn prints_counts_then_translation_and_rotation() {
        let stats = RelationsStats {
            trans_mean: 0.5,
            trans_std: 0.25,
            rot_mean_deg: 1.0,
            rot_std_deg: 0.5,
            trans_sq_mean: 0.3125,
            rot_sq_mean_deg2: 1.25,
            count: 4,
            missing: 1,
        };
        let text = stats.to_string();
        assert_eq!(
            text,
            "relations metric: 4 relations scored, 1 without estimated poses\n  translation   \
             0.5000000 ± 0.2500000 m    (mean squared 0.3125000 m²)\n  rotation      \
             1.0000000 ± 0.5000000 deg  (mean squared 1.2500000 deg²)\n"
        );
    }

    fn planar(x: f64, y: f64, yaw: f64) -> Pose3 {
        Pose3::from_parts(
            Translation3::new(x, y, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
        )
    }

    fn square_path() -> Trajectory {
        let mut t = Trajectory::new();
        for (i, (x, y, yaw)) in [
            (0.0, 0.0, 0.0),
            (1.0, 0.0, 1.0),
            (1.0, 2.0, 3.0),
            (0.0, 2.0, -2.5),
        ]
        .into_iter()
        .enumerate()
        {
            t.push(10.0 + i as f64, planar(x, y, yaw));
        }
        t
    }

    fn exact_relations(traj: &Trajectory) -> Vec<GroundTruthRelation> {
        traj.poses
            .windows(2)
            .map(|w| GroundTruthRelation {
                t1: w[0].timestamp,
                t2: w[1].timestamp,
                t1_from_t2: w[0].pose.inverse() * w[1].pose,
            })
            .collect()
    }

    #[test]
    fn exact_estimate_scores_zero() {
        let est = square_path();
        let s = relations_error(&exact_relations(&est), &est).unwrap();
        assert!(s.trans_mean < 1e-12 && s.rot_mean_deg < 1e-9);
        assert_eq!((s.count, s.missing), (3, 0));
    }

    #[test]
    fn known_errors_and_wrapping() {
        let est = square_path();
        let mut rels = exact_relations(&est);
        // claim the first motion was 0.5 m shorter along its own x and 179° further round:
        // the error is then 0.5 m and |wrap(-179°)| = 179°
        rels[0].t1_from_t2 *= planar(0.0, 0.0, 179f64.to_radians());
        rels[1].t1_from_t2 = planar(0.5, 0.0, 0.0) * rels[1].t1_from_t2;
        let s = relations_error(&rels, &est).unwrap();
        // errors: trans [0, 0.5, 0], rot [179, 0, 0]
        assert!((s.trans_mean - 0.5 / 3.0).abs() < 1e-12, "{s:?}");
        assert!((s.rot_mean_deg - 179.0 / 3.0).abs() < 1e-9, "{s:?}");
        let std = (2.0f64 / 9.0).sqrt() * 0.5; // population std of [0, 0.5, 0]
        assert!((s.trans_std - std).abs() < 1e-12);
    }

    #[test]
    fn stamps_match_within_a_millisecond_in_any_order() {
        let mut est = square_path();
        let rels = exact_relations(&est);
        est.poses.reverse();
        est.poses[0].timestamp += 0.0009; // still matches
        est.poses[3].timestamp += 0.002; // the first pose (t = 10) no longer matches
        let s = relations_error(&rels, &est).unwrap();
        assert_eq!((s.count, s.missing), (2, 1));
        assert!(s.trans_mean < 1e-12);
        let mut none = square_path();
        none.poses.iter_mut().for_each(|p| p.timestamp += 5.0);
        assert!(matches!(
            relations_error(&rels, &none),
            Err(EvalError::NoRelations { relations: 3 })
        ));
    }
}
