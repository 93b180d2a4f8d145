//! Absolute trajectory error (ATE; evo's APE w.r.t. the translation part).
//!
//! Sturm et al., "A Benchmark for the Evaluation of RGB-D SLAM Systems", IROS 2012, §V-A: after
//! associating poses by time, the estimate is aligned onto the reference and the error of pair
//! `i` is `|p_ref,i − S p_est,i|`. The alignment `S` is the least-squares rigid (SE(3)) or
//! similarity (Sim(3)) transform of Umeyama 1991 over *all* associated positions, estimate onto
//! reference — exactly what `evo_ape -a` / `-as` do — or the identity.

use crate::association::{associate, Pairing};
use crate::{ErrorStats, EvalError};
use nalgebra::Point3;
use slamkit_core::{umeyama, SimilarityFit, Trajectory};
use std::fmt;
use std::str::FromStr;

/// How the estimate is aligned onto the reference before the errors are taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Alignment {
    /// Rotation and translation (evo `-a`).
    #[default]
    Se3,
    /// Rotation, translation and scale (evo `-as`), for monocular estimates.
    Sim3,
    /// No alignment: both trajectories are taken to be in the same frame.
    None,
}

impl fmt::Display for Alignment {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Se3 => "se3",
            Self::Sim3 => "sim3",
            Self::None => "none",
        })
    }
}

impl FromStr for Alignment {
    type Err = EvalError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "se3" => Ok(Self::Se3),
            "sim3" => Ok(Self::Sim3),
            "none" => Ok(Self::None),
            other => Err(EvalError::UnknownAlignment {
                name: other.to_owned(),
            }),
        }
    }
}

/// ATE of one estimate, with what a plot or report needs.
#[derive(Debug, Clone)]
pub struct AteResult {
    /// Statistics of the position errors \[m\].
    pub stats: ErrorStats,
    /// Error of each associated pair \[m\], in pair order.
    pub errors_m: Vec<f64>,
    /// Timestamp of the estimated pose of each pair \[s\].
    pub timestamps: Vec<f64>,
    /// Reference position of each pair.
    pub reference_positions: Vec<Point3<f64>>,
    /// Aligned estimated position of each pair.
    pub aligned_estimate_positions: Vec<Point3<f64>>,
    /// The alignment applied (`reference_from_estimate` with scale), if any.
    pub alignment: Option<SimilarityFit>,
}

/// Computes the ATE of `estimate` against `reference`.
///
/// # Errors
/// Association errors (see [`associate`]), [`EvalError::Alignment`] when the associated
/// positions cannot be aligned (fewer than 3, collinear, NaN), [`EvalError::NonFiniteError`].
pub fn ate(
    reference: &Trajectory,
    estimate: &Trajectory,
    pairing: Pairing,
    alignment: Alignment,
) -> Result<AteResult, EvalError> {
    let pairs = associate(reference, estimate, pairing)?;
    let mut ref_pos = Vec::with_capacity(pairs.len());
    let mut est_pos = Vec::with_capacity(pairs.len());
    let mut timestamps = Vec::with_capacity(pairs.len());
    for pair in &pairs {
        let (Some(r), Some(e)) = (
            reference.poses.get(pair.reference),
            estimate.poses.get(pair.estimate),
        ) else {
            continue;
        };
        ref_pos.push(Point3::from(r.pose.translation.vector));
        est_pos.push(Point3::from(e.pose.translation.vector));
        timestamps.push(e.timestamp);
    }
    let fit = match alignment {
        Alignment::Se3 => Some(umeyama(&est_pos, &ref_pos, false)?),
        Alignment::Sim3 => Some(umeyama(&est_pos, &ref_pos, true)?),
        Alignment::None => None,
    };
    let aligned: Vec<Point3<f64>> = match &fit {
        Some(fit) => est_pos.iter().map(|p| fit.transform_point(p)).collect(),
        None => est_pos,
    };
    let errors_m: Vec<f64> = aligned
        .iter()
        .zip(&ref_pos)
        .map(|(e, r)| (e - r).norm())
        .collect();
    Ok(AteResult {
        stats: ErrorStats::from_errors(&errors_m)?,
        errors_m,
        timestamps,
        reference_positions: ref_pos,
        aligned_estimate_positions: aligned,
        alignment: fit,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};
    use slamkit_core::Pose3;

    /// A helix with changing orientation: 3D enough for any alignment.
    fn helix(n: usize) -> Trajectory {
        let mut t = Trajectory::new();
        for i in 0..n {
            let a = i as f64 * 0.1;
            let pose = Pose3::from_parts(
                Translation3::new(a.cos() * 2.0, a.sin() * 2.0, 0.05 * i as f64),
                UnitQuaternion::from_euler_angles(0.1 * a, 0.0, a),
            );
            t.push(i as f64 * 0.05, pose);
        }
        t
    }

    fn mapped(t: &Trajectory, f: impl Fn(&Pose3) -> Pose3) -> Trajectory {
        let mut out = Trajectory::new();
        for p in &t.poses {
            out.push(p.timestamp, f(&p.pose));
        }
        out
    }

    #[test]
    fn constant_offset() {
        let gt = helix(100);
        let offset = Vector3::new(0.3, -0.4, 1.2);
        let est = mapped(&gt, |p| Translation3::from(offset) * p);
        let none = ate(&gt, &est, Pairing::default(), Alignment::None).unwrap();
        assert!((none.stats.rmse - offset.norm()).abs() < 1e-12);
        assert!((none.stats.min - offset.norm()).abs() < 1e-12);
        assert!(none.stats.std < 1e-12);
        assert_eq!(none.stats.pairs, 100);
        let se3 = ate(&gt, &est, Pairing::default(), Alignment::Se3).unwrap();
        assert!(se3.stats.max < 1e-9, "{:?}", se3.stats);
    }

    #[test]
    fn rigid_motion_and_scale() {
        let gt = helix(80);
        let world = Pose3::from_parts(
            Translation3::new(5.0, -2.0, 1.0),
            UnitQuaternion::from_euler_angles(0.3, -0.2, 1.4),
        );
        let scale = 0.37;
        let est = mapped(&gt, |p| {
            let q = world * p;
            Pose3::from_parts(Translation3::from(q.translation.vector * scale), q.rotation)
        });
        let sim3 = ate(&gt, &est, Pairing::default(), Alignment::Sim3).unwrap();
        assert!(sim3.stats.max < 1e-9);
        let fit = sim3.alignment.unwrap();
        assert!((fit.scale - 1.0 / scale).abs() < 1e-9);
        // a rigid alignment cannot undo the scale
        let se3 = ate(&gt, &est, Pairing::default(), Alignment::Se3).unwrap();
        assert!(se3.stats.rmse > 0.1);
    }

    #[test]
    fn known_per_pose_errors() {
        // estimate = reference moved along x by 0, 1, 2, 3 (no alignment): errors 0..3
        let gt = helix(4);
        let mut est = gt.clone();
        for (i, p) in est.poses.iter_mut().enumerate() {
            p.pose.translation.vector.x += i as f64;
        }
        let r = ate(&gt, &est, Pairing::Index, Alignment::None).unwrap();
        assert_eq!(r.errors_m.len(), 4);
        assert!((r.stats.mean - 1.5).abs() < 1e-12);
        assert!((r.stats.rmse - 3.5f64.sqrt()).abs() < 1e-12);
        assert!((r.stats.std - 1.25f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn degenerate_alignment_is_an_error() {
        let mut line = Trajectory::new();
        for i in 0..10 {
            line.push(i as f64, Pose3::translation(i as f64, 0.0, 0.0));
        }
        assert!(matches!(
            ate(&line, &line, Pairing::default(), Alignment::Se3),
            Err(EvalError::Alignment(_))
        ));
        assert!(ate(&line, &line, Pairing::default(), Alignment::None).is_ok());
        assert!("sim4".parse::<Alignment>().is_err());
        assert_eq!("sim3".parse::<Alignment>().unwrap(), Alignment::Sim3);
    }
}
