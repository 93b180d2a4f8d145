//! Relative pose error (RPE; evo's `evo_rpe` with its default `--pose_relation trans_part`).
//!
//! Sturm et al., IROS 2012, §V-B: for a pair of associated poses `(i, j)`,
//! `E = (Q_i⁻¹ Q_j)⁻¹ (P_i⁻¹ P_j)` with `Q` the reference and `P` the estimate; the error is the
//! norm of the translation of `E` \[m\]. It measures local drift and needs no alignment (a rigid
//! change of the estimate's world frame cancels out).
//!
//! Which pairs `(i, j)` are used follows `evo.core.filters` (indices into the *associated*
//! sequence, chosen on the estimate's positions as evo does by default):
//! * frames (`--delta_unit f`): `(0, Δ), (Δ, 2Δ), …`; with `all_pairs`, `(i, i+Δ)` for every i.
//! * metres (`--delta_unit m`): walk the path, summing the distances between consecutive
//!   positions, and cut a pair whenever the sum reaches Δ (then restart from 0); with
//!   `all_pairs`, for every `i` the later pose whose travelled distance from `i` is nearest to
//!   Δ, kept if within `rel_delta_tol · Δ`.

use crate::association::{associate, Pairing, PosePair};
use crate::{ErrorStats, EvalError};
use serde::{Deserialize, Serialize};
use slamkit_core::{Pose3, Trajectory};
use std::fmt;

/// Unit of the RPE pair distance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DeltaUnit {
    /// Poses `delta` associated frames apart.
    #[default]
    Frames,
    /// Poses `delta` metres of travelled path apart.
    #[serde(rename = "m")]
    Metres,
}

impl fmt::Display for DeltaUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Frames => "frames",
            Self::Metres => "m",
        })
    }
}

/// RPE settings; the defaults are evo_rpe's.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RpeConfig {
    /// Distance between the poses of a pair, in `unit` (frames: a positive integer).
    pub delta: f64,
    /// Unit of `delta`.
    pub unit: DeltaUnit,
    /// Pair every pose with the one `delta` later, rather than only consecutive blocks.
    pub all_pairs: bool,
    /// In metres with `all_pairs`: accepted distance error, as a fraction of `delta` \[-\].
    pub rel_delta_tol: f64,
}

impl Default for RpeConfig {
    fn default() -> Self {
        Self {
            delta: 1.0,
            unit: DeltaUnit::Frames,
            all_pairs: false,
            rel_delta_tol: 0.1,
        }
    }
}

/// RPE of one estimate.
#[derive(Debug, Clone)]
pub struct RpeResult {
    /// Statistics of the relative translation errors \[m\].
    pub stats: ErrorStats,
    /// Error of each pair \[m\].
    pub errors_m: Vec<f64>,
    /// Timestamp of the later estimated pose of each pair \[s\].
    pub timestamps: Vec<f64>,
}

/// Computes the RPE of `estimate` against `reference`.
///
/// # Errors
/// Association errors (see [`associate`]), [`EvalError::InvalidDelta`] for a delta that is not
/// positive (or not an integer in frames), [`EvalError::NoDeltaPairs`] when no pair is `delta`
/// apart, [`EvalError::NonFiniteError`] for broken poses.
pub fn rpe(
    reference: &Trajectory,
    estimate: &Trajectory,
    pairing: Pairing,
    config: &RpeConfig,
) -> Result<RpeResult, EvalError> {
    let pairs = associate(reference, estimate, pairing)?;
    let lookup = |p: &PosePair| {
        Some((
            reference.poses.get(p.reference)?.pose,
            estimate.poses.get(p.estimate)?,
        ))
    };
    let synced: Vec<(Pose3, &slamkit_core::StampedPose)> =
        pairs.iter().filter_map(lookup).collect();
    let ids = match config.unit {
        DeltaUnit::Frames => {
            let delta = frame_delta(config.delta)?;
            pairs_by_index(synced.len(), delta, config.all_pairs)
        }
        DeltaUnit::Metres => {
            if !(config.delta > 0.0 && config.delta.is_finite()) {
                return Err(EvalError::InvalidDelta {
                    delta: config.delta,
                    unit: config.unit,
                });
            }
            let positions: Vec<_> = synced
                .iter()
                .map(|(_, e)| e.pose.translation.vector)
                .collect();
            let tol = config.delta * config.rel_delta_tol;
            pairs_by_path(&positions, config.delta, tol, config.all_pairs)
        }
    };
    if ids.is_empty() {
        return Err(EvalError::NoDeltaPairs {
            delta: config.delta,
            unit: config.unit,
            poses: synced.len(),
        });
    }
    let mut errors_m = Vec::with_capacity(ids.len());
    let mut timestamps = Vec::with_capacity(ids.len());
    for &(i, j) in &ids {
        let (Some((q_i, p_i)), Some((q_j, p_j))) = (synced.get(i), synced.get(j)) else {
            continue;
        };
        let ref_rel = q_i.inverse() * q_j;
        let est_rel = p_i.pose.inverse() * p_j.pose;
        errors_m.push((ref_rel.inverse() * est_rel).translation.vector.norm());
        timestamps.push(p_j.timestamp);
    }
    Ok(RpeResult {
        stats: ErrorStats::from_errors(&errors_m)?,
        errors_m,
        timestamps,
    })
}

fn frame_delta(delta: f64) -> Result<usize, EvalError> {
    if delta >= 1.0 && delta.fract() == 0.0 && delta < usize::MAX as f64 {
        Ok(delta as usize)
    } else {
        Err(EvalError::InvalidDelta {
            delta,
            unit: DeltaUnit::Frames,
        })
    }
}

/// evo's `filter_pairs_by_index` over `n` poses.
pub fn pairs_by_index(n: usize, delta: usize, all_pairs: bool) -> Vec<(usize, usize)> {
    if delta == 0 {
        return Vec::new();
    }
    if all_pairs {
        (0..n.saturating_sub(delta))
            .map(|i| (i, i + delta))
            .collect()
    } else {
        let ids: Vec<usize> = (0..n).step_by(delta).collect();
        ids.windows(2).map(|w| (w[0], w[1])).collect()
    }
}

/// evo's `filter_pairs_by_path` on positions, `delta` and `tol` in metres.
pub fn pairs_by_path(
    positions: &[nalgebra::Vector3<f64>],
    delta: f64,
    tol: f64,
    all_pairs: bool,
) -> Vec<(usize, usize)> {
    if positions.is_empty() {
        return Vec::new();
    }
    if all_pairs {
        return all_pairs_by_path(positions, delta, tol);
    }
    let mut ids = vec![0];
    let mut path = 0.0;
    for (i, w) in positions.windows(2).enumerate() {
        path += (w[1] - w[0]).norm();
        if path >= delta {
            ids.push(i + 1);
            path = 0.0;
        }
    }
    ids.windows(2).map(|w| (w[0], w[1])).collect()
}

/// evo's all-pairs search by path: for every `i`, the first later pose whose travelled
/// distance from `i` is nearest to `delta`, kept when it misses by at most `tol`. evo scans every
/// later pose (O(n²): days for two million poses); the distance from `i` only grows along the
/// path, so the miss falls to its minimum where `d − dᵢ − Δ` turns non-negative and rises after,
/// and two binary searches per pose give the same pairs (checked against the scan in the tests)
/// in O(n log n). A path whose length overflows has no pairs.
fn all_pairs_by_path(
    positions: &[nalgebra::Vector3<f64>],
    delta: f64,
    tol: f64,
) -> Vec<(usize, usize)> {
    let travelled = accumulated_distances(positions);
    if travelled.last().is_some_and(|d| !d.is_finite()) {
        return Vec::new();
    }
    let mut pairs = Vec::new();
    for (i, &from) in travelled.iter().enumerate() {
        // computed exactly as evo does, so that ties and rounding pick the same pose
        let offset = |d: f64| d - from - delta;
        let later = travelled.get(i + 1..).unwrap_or_default();
        let k = later.partition_point(|&d| offset(d) < 0.0);
        // below Δ: the earliest pose with the largest offset under 0 (the first of equal ones)
        let below = k.checked_sub(1).and_then(|last| {
            let worst = offset(*later.get(last)?);
            let first = later.get(..last)?.partition_point(|&d| offset(d) < worst);
            Some((first, -worst))
        });
        let above = later.get(k).map(|&d| (k, offset(d)));
        let best = match (below, above) {
            (Some(b), Some(a)) => Some(if a.1 < b.1 { a } else { b }),
            (b, a) => b.or(a),
        };
        if let Some((j, miss)) = best {
            if miss <= tol {
                pairs.push((i, i + 1 + j));
            }
        }
    }
    pairs
}

/// Distance travelled from the first position to each, as evo's
/// `geometry.accumulated_distances`.
fn accumulated_distances(positions: &[nalgebra::Vector3<f64>]) -> Vec<f64> {
    let mut travelled = Vec::with_capacity(positions.len());
    travelled.push(0.0);
    let mut sum = 0.0;
    for w in positions.windows(2) {
        sum += (w[0] - w[1]).norm();
        travelled.push(sum);
    }
    travelled
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    fn straight(n: usize, step: f64) -> Trajectory {
        let mut t = Trajectory::new();
        for i in 0..n {
            t.push(
                i as f64 * 0.1,
                Pose3::translation(i as f64 * step, 0.0, 0.0),
            );
        }
        t
    }

    #[test]
    fn index_pairs_like_evo() {
        assert_eq!(pairs_by_index(5, 2, false), [(0, 2), (2, 4)]);
        assert_eq!(pairs_by_index(6, 2, false), [(0, 2), (2, 4)]);
        assert_eq!(pairs_by_index(5, 2, true), [(0, 2), (1, 3), (2, 4)]);
        assert_eq!(pairs_by_index(1, 1, false), []);
    }

    #[test]
    fn path_pairs_like_evo() {
        // expected pairs computed with evo 1.38's filters.filter_pairs_by_path
        let p: Vec<_> = [0.0, 0.4, 0.8, 1.2, 1.6, 2.5, 2.6, 3.55]
            .iter()
            .map(|&x| Vector3::new(x, 0.0, 0.0))
            .collect();
        assert_eq!(pairs_by_path(&p, 1.0, 0.1, false), [(0, 3), (3, 5), (5, 7)]);
        assert_eq!(pairs_by_path(&p, 1.0, 0.1, true), [(4, 6), (5, 7), (6, 7)]);
    }

    #[test]
    fn constant_velocity_drift() {
        // estimate moves 1.1 m per frame where the reference moves 1.0: RPE(Δ=k) = 0.1 k
        let gt = straight(11, 1.0);
        let est = straight(11, 1.1);
        let cfg = RpeConfig::default();
        let r = rpe(&gt, &est, Pairing::default(), &cfg).unwrap();
        assert_eq!(r.stats.pairs, 10);
        assert!((r.stats.rmse - 0.1).abs() < 1e-12 && r.stats.std < 1e-12);
        let cfg5 = RpeConfig { delta: 5.0, ..cfg };
        let r = rpe(&gt, &est, Pairing::default(), &cfg5).unwrap();
        assert_eq!(r.stats.pairs, 2);
        assert!((r.stats.mean - 0.5).abs() < 1e-12);
    }

    #[test]
    fn rigid_change_of_world_frame_cancels() {
        let mut gt = Trajectory::new();
        for i in 0..30 {
            let a = i as f64 * 0.2;
            gt.push(
                i as f64,
                Pose3::from_parts(
                    Translation3::new(a.cos(), a.sin(), 0.1 * a),
                    UnitQuaternion::from_euler_angles(0.0, 0.1 * a, a),
                ),
            );
        }
        let world = Pose3::from_parts(
            Translation3::new(3.0, 1.0, -2.0),
            UnitQuaternion::from_euler_angles(0.4, 0.2, -1.0),
        );
        let mut est = gt.clone();
        for p in &mut est.poses {
            p.pose = world * p.pose;
        }
        for unit in [DeltaUnit::Frames, DeltaUnit::Metres] {
            let cfg = RpeConfig {
                delta: 2.0,
                unit,
                ..RpeConfig::default()
            };
            let r = rpe(&gt, &est, Pairing::Index, &cfg).unwrap();
            assert!(r.stats.max < 1e-12, "{unit}: {:?}", r.stats);
        }
    }

    /// evo's all-pairs search as it is written (every later pose scanned): the reference
    /// the binary search must match.
    fn all_pairs_by_path_scan(
        positions: &[nalgebra::Vector3<f64>],
        delta: f64,
        tol: f64,
    ) -> Vec<(usize, usize)> {
        let travelled = accumulated_distances(positions);
        let mut pairs = Vec::new();
        for i in 0..travelled.len().saturating_sub(1) {
            let mut best: Option<(usize, f64)> = None;
            for (j, d) in travelled.iter().enumerate().skip(i + 1) {
                let miss = (d - travelled[i] - delta).abs();
                if best.map_or(true, |(_, b)| miss < b) {
                    best = Some((j, miss));
                }
            }
            if let Some((j, miss)) = best {
                if miss <= tol {
                    pairs.push((i, j));
                }
            }
        }
        pairs
    }

    /// Seeded random walks with stops (repeated positions), steps on a coarse grid (exact
    /// ties) and fine ones, against the scan.
    #[test]
    fn all_pairs_by_path_matches_evos_scan() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(25);
        for case in 0..300 {
            let n = rng.gen_range(0..120);
            let mut p = Vector3::zeros();
            let mut positions = Vec::with_capacity(n);
            for _ in 0..n {
                match rng.gen_range(0..4) {
                    0 => {}
                    1 => p.x += f64::from(rng.gen_range(1..4)) * 0.25,
                    _ => p += Vector3::new(rng.gen(), rng.gen(), 0.0) * 0.3,
                }
                positions.push(p);
            }
            let delta = [0.25, 0.5, 1.0, 2.7][case % 4];
            let tol = delta * [0.0, 0.1, 1.0][case % 3];
            assert_eq!(
                all_pairs_by_path(&positions, delta, tol),
                all_pairs_by_path_scan(&positions, delta, tol),
                "case {case}"
            );
        }
    }

    #[test]
    fn bad_delta_is_an_error() {
        let gt = straight(5, 1.0);
        for (delta, unit) in [
            (0.0, DeltaUnit::Frames),
            (1.5, DeltaUnit::Frames),
            (-1.0, DeltaUnit::Metres),
        ] {
            let cfg = RpeConfig {
                delta,
                unit,
                ..RpeConfig::default()
            };
            assert!(matches!(
                rpe(&gt, &gt, Pairing::Index, &cfg),
                Err(EvalError::InvalidDelta { .. })
            ));
        }
        let far = RpeConfig {
            delta: 100.0,
            ..RpeConfig::default()
        };
        assert!(matches!(
            rpe(&gt, &gt, Pairing::Index, &far),
            Err(EvalError::NoDeltaPairs { .. })
        ));
    }
}
