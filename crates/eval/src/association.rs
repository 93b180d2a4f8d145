//! Pairing the poses of a reference and an estimated trajectory, exactly as evo 1.38 does
//! (`evo.core.sync.associate_trajectories` with the default nearest-time method), so that the
//! pair sets — and therefore every metric — match evo's.
//!
//! evo walks the trajectory with *fewer* poses (the estimate when both have as many) and, for
//! each of its stamps, takes the nearest stamp of the other one if it is within `max_diff`.
//! When the other trajectory's stamps are sorted it uses a binary search with a fixed
//! tie-break (on equal distance the *earlier* stamp wins, and a match above is taken only when
//! strictly nearer); otherwise a linear scan keeping the first minimum. A pose of the longer
//! trajectory may be used by several pairs. Pairs keep the shorter trajectory's order.
//!
//! KITTI odometry files carry no timestamps; their poses pair by index (evo's `kitti` mode).

use crate::EvalError;
use slamkit_core::Trajectory;

/// evo's default maximum time difference for associating poses is 0.01 s; slamkit uses 0.02 s
/// (one frame at 50 Hz), the value the TUM RGB-D tools use.
pub const DEFAULT_MAX_DIFF_S: f64 = 0.02;

/// How poses of the reference and the estimate are paired.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pairing {
    /// Nearest timestamp within `max_diff_s` \[s\] (evo's `--t_max_diff`).
    NearestTime {
        /// Largest accepted time difference \[s\].
        max_diff_s: f64,
    },
    /// Pose `i` with pose `i` (KITTI: timestamps are line indices). Both trajectories must
    /// have the same length.
    Index,
}

impl Pairing {
    /// How two trajectory files pair, as evo does: by index when either is KITTI (its
    /// timestamps are line numbers), otherwise by nearest timestamp within `max_diff_s`.
    ///
    /// ```
    /// use slamkit_eval::Pairing;
    /// use slamkit_io::TrajectoryFormat;
    /// let p = Pairing::for_formats(TrajectoryFormat::Tum, TrajectoryFormat::Kitti, 0.01);
    /// assert_eq!(p, Pairing::Index);
    /// ```
    pub fn for_formats(
        reference: slamkit_io::TrajectoryFormat,
        estimate: slamkit_io::TrajectoryFormat,
        max_diff_s: f64,
    ) -> Self {
        use slamkit_io::TrajectoryFormat::Kitti;
        if reference == Kitti || estimate == Kitti {
            Self::Index
        } else {
            Self::NearestTime { max_diff_s }
        }
    }
}

impl Default for Pairing {
    fn default() -> Self {
        Self::NearestTime {
            max_diff_s: DEFAULT_MAX_DIFF_S,
        }
    }
}

/// One associated pair: indices into the reference and the estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PosePair {
    /// Index of the reference pose.
    pub reference: usize,
    /// Index of the estimated pose.
    pub estimate: usize,
}

/// Pairs the poses of `reference` and `estimate`; the result is never empty.
///
/// # Errors
/// [`EvalError::NonFiniteTimestamp`] for a NaN or infinite stamp, [`EvalError::NoPairs`] when
/// nothing pairs, [`EvalError::LengthMismatch`] for index pairing of unequal lengths.
pub fn associate(
    reference: &Trajectory,
    estimate: &Trajectory,
    pairing: Pairing,
) -> Result<Vec<PosePair>, EvalError> {
    check_finite(reference, "reference")?;
    check_finite(estimate, "estimate")?;
    let pairs = match pairing {
        Pairing::Index => {
            if reference.len() != estimate.len() {
                return Err(EvalError::LengthMismatch {
                    reference: reference.len(),
                    estimate: estimate.len(),
                });
            }
            (0..reference.len())
                .map(|i| PosePair {
                    reference: i,
                    estimate: i,
                })
                .collect()
        }
        Pairing::NearestTime { max_diff_s } => nearest_time(reference, estimate, max_diff_s),
    };
    if pairs.is_empty() {
        return Err(EvalError::NoPairs {
            reference: reference.len(),
            estimate: estimate.len(),
        });
    }
    Ok(pairs)
}

fn check_finite(traj: &Trajectory, which: &'static str) -> Result<(), EvalError> {
    match traj.poses.iter().position(|p| !p.timestamp.is_finite()) {
        Some(index) => Err(EvalError::NonFiniteTimestamp { which, index }),
        None => Ok(()),
    }
}

/// evo's `associate_trajectories`: iterate the shorter trajectory, search the longer.
fn nearest_time(reference: &Trajectory, estimate: &Trajectory, max_diff_s: f64) -> Vec<PosePair> {
    let stamps = |t: &Trajectory| t.poses.iter().map(|p| p.timestamp).collect::<Vec<_>>();
    let (ref_stamps, est_stamps) = (stamps(reference), stamps(estimate));
    let estimate_longer = est_stamps.len() > ref_stamps.len();
    if estimate_longer {
        matching_time_indices(&ref_stamps, &est_stamps, max_diff_s)
            .into_iter()
            .map(|(r, e)| PosePair {
                reference: r,
                estimate: e,
            })
            .collect()
    } else {
        matching_time_indices(&est_stamps, &ref_stamps, max_diff_s)
            .into_iter()
            .map(|(e, r)| PosePair {
                reference: r,
                estimate: e,
            })
            .collect()
    }
}

/// evo's `matching_time_indices`: for each stamp of `short`, the index of the best stamp of
/// `long` within `max_diff`, as `(short index, long index)`.
pub fn matching_time_indices(short: &[f64], long: &[f64], max_diff: f64) -> Vec<(usize, usize)> {
    let sorted = long.windows(2).all(|w| w[1] - w[0] >= 0.0);
    short
        .iter()
        .enumerate()
        .filter_map(|(i, &stamp)| {
            let j = if sorted {
                nearest_sorted(long, stamp, max_diff)
            } else {
                nearest_linear(long, stamp, max_diff)
            };
            j.map(|j| (i, j))
        })
        .collect()
}

/// Binary search with evo's tie-breaks (`np.searchsorted(side="right")`, then compare the
/// stamps just above and just below).
fn nearest_sorted(long: &[f64], stamp: f64, max_diff: f64) -> Option<usize> {
    let (first, last) = (*long.first()?, *long.last()?);
    if stamp < first - max_diff || stamp > last + max_diff {
        return None;
    }
    let upper = long.partition_point(|&s| s <= stamp).min(long.len() - 1);
    let diff_ub = long[upper] - stamp;
    let diff_lb = match upper.checked_sub(1) {
        Some(lower) => stamp - long[lower],
        None => f64::INFINITY,
    };
    if diff_ub <= max_diff && diff_ub < diff_lb {
        Some(upper)
    } else if diff_lb <= max_diff && diff_lb <= diff_ub {
        Some(upper - 1)
    } else {
        None
    }
}

/// Linear scan keeping the first minimum (`np.argmin`), for unsorted stamps.
fn nearest_linear(long: &[f64], stamp: f64, max_diff: f64) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (j, &s) in long.iter().enumerate() {
        let d = (s - stamp).abs();
        if best.map_or(true, |(_, bd)| d < bd) {
            best = Some((j, d));
        }
    }
    best.filter(|&(_, d)| d <= max_diff).map(|(j, _)| j)
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_core::Pose3;

    fn traj(stamps: &[f64]) -> Trajectory {
        let mut t = Trajectory::new();
        for &s in stamps {
            t.push(s, Pose3::identity());
        }
        t
    }

    fn pairs(r: &[f64], e: &[f64], max_diff_s: f64) -> Vec<(usize, usize)> {
        associate(&traj(r), &traj(e), Pairing::NearestTime { max_diff_s })
            .map(|p| p.iter().map(|p| (p.reference, p.estimate)).collect())
            .unwrap_or_default()
    }

    #[test]
    fn shorter_trajectory_drives_and_long_poses_may_repeat() {
        // estimate shorter: each estimate stamp takes its nearest reference stamp
        let r = [0.0, 0.1, 0.2, 0.3, 0.4];
        assert_eq!(pairs(&r, &[0.11, 0.29, 0.9], 0.02), vec![(1, 0), (3, 1)]);
        // reference shorter: both reference stamps pick estimate index 1
        assert_eq!(
            pairs(&[0.1, 0.105], &[0.0, 0.1, 0.3], 0.02),
            vec![(0, 1), (1, 1)]
        );
    }

    #[test]
    fn ties_go_to_the_earlier_stamp_like_evo() {
        // 0.25 is exactly between 0.0 + 0.25 steps: sorted search picks the lower one
        let long = [0.0, 0.5, 1.0];
        assert_eq!(
            matching_time_indices(&[0.25, 0.75], &long, 0.3),
            [(0, 0), (1, 1)]
        );
        // unsorted: first minimum in file order
        let unsorted = [1.0, 0.5, 0.0];
        assert_eq!(matching_time_indices(&[0.25], &unsorted, 0.3), [(0, 1)]);
        // beyond both ends but within max_diff
        assert_eq!(
            matching_time_indices(&[-0.1, 1.1], &long, 0.15),
            [(0, 0), (1, 2)]
        );
        assert!(matching_time_indices(&[-0.2, 1.2], &long, 0.15).is_empty());
    }

    #[test]
    fn sorted_and_linear_search_agree_off_ties() {
        let long: Vec<f64> = (0..50)
            .map(|i| i as f64 * 0.033 + 0.001 * (i % 3) as f64)
            .collect();
        let short: Vec<f64> = (0..70).map(|i| i as f64 * 0.0237 - 0.01).collect();
        for (i, &s) in short.iter().enumerate() {
            assert_eq!(
                nearest_sorted(&long, s, 0.01),
                nearest_linear(&long, s, 0.01),
                "stamp {i}"
            );
        }
    }

    #[test]
    fn errors() {
        let r = traj(&[0.0, 1.0]);
        assert!(matches!(
            associate(&r, &traj(&[5.0]), Pairing::default()),
            Err(EvalError::NoPairs { .. })
        ));
        assert!(matches!(
            associate(&r, &traj(&[0.0]), Pairing::Index),
            Err(EvalError::LengthMismatch {
                reference: 2,
                estimate: 1
            })
        ));
        assert!(matches!(
            associate(&r, &traj(&[f64::NAN]), Pairing::default()),
            Err(EvalError::NonFiniteTimestamp {
                which: "estimate",
                index: 0
            })
        ));
        assert_eq!(
            associate(&r, &traj(&[7.0, 9.0]), Pairing::Index)
                .unwrap()
                .len(),
            2
        );
    }
}
