//! Loop detection: which earlier keyframe the current one sees again, and how it lies from it.
//!
//! Candidates come from the [`crate::place_index`] votes; a candidate must be consistent over
//! consecutive keyframes (ORB-SLAM's test, Mur-Artal and Tardós, "Fast relocalisation and loop
//! closing in keyframe-based SLAM", ICRA 2014: the previous keyframe's candidates held one
//! within a few keyframes of it), then pass geometric verification ([`verify`]): descriptor
//! matches between the two keyframes' 3D features, RANSAC over 3-point Horn samples, enough
//! inliers and a small residual. A loop that passes is a relative pose between the keyframes.

use serde::{Deserialize, Serialize};
use slamkit_core::ransac::{ransac, PointMatch, RansacConfig, RigidTransformEstimator};
use slamkit_core::Pose3;
use slamkit_vision::{match_descriptors, MatchConfig, OrbConfig};

use crate::covisibility::PlaceFeatures;
use crate::map_tracking::MapTrackingConfig;
use crate::place_index::PlaceIndexConfig;
use crate::relocalisation::RelocalisationConfig;
use crate::VoError;

/// Settings of keyframe selection, place recognition and loop closure (`slamkit vo --slam`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LoopClosureConfig {
    /// Detect and close loops (off: plain visual odometry).
    pub enabled: bool,
    /// A tracked frame this far from the last keyframe becomes one \[m\].
    pub keyframe_distance_m: f64,
    /// A tracked frame turned this much from the last keyframe becomes one \[deg\].
    pub keyframe_angle_deg: f64,
    /// ORB features of the KLT front end's keyframes (the ORB front end's own are used as
    /// they are).
    pub orb: OrbConfig,
    /// The place index.
    pub place_index: PlaceIndexConfig,
    /// Candidates are keyframes at least this many keyframes older than the query...
    pub min_keyframes_apart: usize,
    /// ... sharing at most this many map points with it (more: the two are already
    /// connected, by odometry or an earlier closure).
    pub max_shared_points: usize,
    /// Best-voted keyframes kept as candidates of one query.
    pub candidates: usize,
    /// A candidate needs votes from at least this fraction of the query's features.
    pub min_vote_fraction: f64,
    /// Consecutive keyframes whose candidates must agree before a candidate is verified
    /// (1: no temporal check).
    pub temporal_consistency: usize,
    /// Candidates of consecutive queries agree when this many keyframes apart or fewer.
    pub consistency_window: usize,
    /// Geometric verification.
    pub verification: VerifyConfig,
    /// Feature association between consecutive keyframes (map points): an absolute and a
    /// depth-relative distance within which two matched points are one \[m, 1\].
    pub association_tolerance: (f64, f64),
    /// Standard deviations of the odometry between keyframes in the pose graph, translation
    /// \[m\] and rotation \[rad\]; a loop edge has the same, under a Cauchy kernel.
    pub odometry_sigma: (f64, f64),
    /// Scale of the Cauchy kernel of loop edges (Mahalanobis units).
    pub loop_robust_scale: f64,
    /// Keep the map bounded on revisits: a frame due to become a keyframe (by the distance
    /// and angle rules) that lies within those of an existing keyframe and is verified against
    /// it (as a loop is), with a pose within `max_localisation_correction` of odometry's, is
    /// localised in the map instead of added: it re-observes that keyframe's points.
    pub cull_redundant_keyframes: bool,
    /// Largest disagreement between odometry and a localisation in the map, translation \[m\]
    /// and rotation \[deg\]; a larger one is drift for loop closure to correct.
    pub max_localisation_correction: (f64, f64),
    /// Finding the camera in the map again when tracking is lost (verified as loops are).
    pub relocalisation: RelocalisationConfig,
    /// Tracking against a saved map's points (`slamkit vo --localize`).
    pub map_tracking: MapTrackingConfig,
}

impl Default for LoopClosureConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            keyframe_distance_m: 0.1,
            keyframe_angle_deg: 10.0,
            orb: OrbConfig::default(),
            place_index: PlaceIndexConfig::default(),
            min_keyframes_apart: 10,
            max_shared_points: 0,
            candidates: 3,
            min_vote_fraction: 0.05,
            temporal_consistency: 3,
            consistency_window: 2,
            verification: VerifyConfig::default(),
            association_tolerance: (0.03, 0.03),
            odometry_sigma: (0.01, 0.01),
            loop_robust_scale: 3.0,
            cull_redundant_keyframes: true,
            max_localisation_correction: (0.05, 3.0),
            relocalisation: RelocalisationConfig::default(),
            map_tracking: MapTrackingConfig::default(),
        }
    }
}

impl LoopClosureConfig {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`VoError::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<(), VoError> {
        self.place_index.validate()?;
        self.relocalisation.validate()?;
        self.map_tracking.validate()?;
        for (field, v) in [
            ("loop_closure.keyframe_distance_m", self.keyframe_distance_m),
            ("loop_closure.keyframe_angle_deg", self.keyframe_angle_deg),
            ("loop_closure.odometry_sigma", self.odometry_sigma.0),
            ("loop_closure.odometry_sigma", self.odometry_sigma.1),
            ("loop_closure.loop_robust_scale", self.loop_robust_scale),
            (
                "loop_closure.max_localisation_correction",
                self.max_localisation_correction.0,
            ),
            (
                "loop_closure.max_localisation_correction",
                self.max_localisation_correction.1,
            ),
            (
                "loop_closure.verification.max_rms_m",
                self.verification.max_rms_m,
            ),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(VoError::config(field, v, "must be finite and > 0"));
            }
        }
        for (field, v) in [
            ("loop_closure.candidates", self.candidates),
            (
                "loop_closure.temporal_consistency",
                self.temporal_consistency,
            ),
            (
                "loop_closure.verification.min_inliers",
                self.verification.min_inliers,
            ),
        ] {
            if v == 0 {
                return Err(VoError::config(field, 0, "must be > 0"));
            }
        }
        if !(0.0..=1.0).contains(&self.min_vote_fraction) {
            return Err(VoError::config(
                "loop_closure.min_vote_fraction",
                self.min_vote_fraction,
                "must be in [0, 1]",
            ));
        }
        Ok(())
    }
}

/// Settings of geometric verification.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VerifyConfig {
    /// Descriptor matching between the two keyframes.
    pub matching: MatchConfig,
    /// RANSAC over 3D–3D matches (threshold in metres of point distance).
    pub ransac: RansacConfig,
    /// Fewest inliers of an accepted loop.
    pub min_inliers: usize,
    /// Fewest inliers as a fraction of the descriptor matches.
    pub min_inlier_ratio: f64,
    /// Largest RMS point distance of the inliers under the fitted pose \[m\].
    pub max_rms_m: f64,
}

impl Default for VerifyConfig {
    fn default() -> Self {
        Self {
            matching: MatchConfig {
                max_distance: 50,
                ratio: 0.8,
                cross_check: true,
            },
            ransac: RansacConfig {
                threshold: 0.05,
                max_iterations: 500,
                ..RansacConfig::default()
            },
            min_inliers: 40,
            min_inlier_ratio: 0.3,
            max_rms_m: 0.03,
        }
    }
}

/// A verified loop.
#[derive(Debug, Clone, PartialEq)]
pub struct VerifiedLoop {
    /// Pose of the query keyframe's camera in the candidate's.
    pub candidate_from_query: Pose3,
    /// Inlier feature pairs `(candidate feature, query feature)`.
    pub inliers: Vec<(usize, usize)>,
    /// Descriptor matches tried.
    pub matches: usize,
    /// RMS point distance of the inliers \[m\].
    pub rms_m: f64,
}

/// Why a candidate failed verification.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum LoopRejection {
    /// Too few descriptor matches for RANSAC to find the minimum of inliers.
    TooFewMatches {
        /// Matches found.
        matches: usize,
    },
    /// No pose explains enough matches.
    TooFewInliers {
        /// Best inlier count.
        inliers: usize,
        /// Matches tried.
        matches: usize,
    },
    /// The inliers fit too loosely.
    ResidualTooLarge {
        /// RMS point distance \[m\].
        rms_m: f64,
    },
}

/// Geometric verification of `query` against `candidate`: their descriptors matched, then
/// RANSAC + Horn on the matched points (`candidate ≈ candidate_from_query · query`).
///
/// # Errors
/// A [`LoopRejection`] saying why the two views are not shown to be one place.
pub fn verify(
    query: &PlaceFeatures,
    candidate: &PlaceFeatures,
    config: &VerifyConfig,
) -> Result<VerifiedLoop, LoopRejection> {
    let matches = match_descriptors(&candidate.descriptors, &query.descriptors, &config.matching);
    let pairs: Vec<(usize, usize, PointMatch)> = matches
        .iter()
        .filter_map(|m| {
            Some((
                m.query_idx,
                m.train_idx,
                PointMatch {
                    src: *query.points.get(m.train_idx)?,
                    dst: *candidate.points.get(m.query_idx)?,
                },
            ))
        })
        .collect();
    if pairs.len() < config.min_inliers.max(3) {
        return Err(LoopRejection::TooFewMatches {
            matches: pairs.len(),
        });
    }
    let data: Vec<PointMatch> = pairs.iter().map(|p| p.2).collect();
    let ransac_config = RansacConfig {
        min_inliers: config.min_inliers,
        ..config.ransac.clone()
    };
    let too_few = |inliers| LoopRejection::TooFewInliers {
        inliers,
        matches: data.len(),
    };
    let fit = ransac(&RigidTransformEstimator, &data, &ransac_config).map_err(|_| too_few(0))?;
    let n = fit.inliers.len();
    if n < config.min_inliers || (n as f64) < config.min_inlier_ratio * data.len() as f64 {
        return Err(too_few(n));
    }
    let sum_sq: f64 = fit
        .inliers
        .iter()
        .filter_map(|&i| data.get(i))
        .map(|m| (m.dst - fit.model * m.src).norm_squared())
        .sum();
    let rms_m = (sum_sq / n as f64).sqrt();
    if rms_m > config.max_rms_m {
        return Err(LoopRejection::ResidualTooLarge { rms_m });
    }
    Ok(VerifiedLoop {
        candidate_from_query: fit.model,
        inliers: fit
            .inliers
            .iter()
            .filter_map(|&i| pairs.get(i).map(|p| (p.0, p.1)))
            .collect(),
        matches: data.len(),
        rms_m,
    })
}

/// The temporal-consistency test: a candidate is consistent when the previous query's
/// candidates held one within `window` keyframes of it, and counts how many queries in a row
/// it has been.
#[derive(Debug, Clone, Default)]
pub struct Consistency {
    /// The previous query's candidates with their run lengths.
    previous: Vec<(usize, usize)>,
}

impl Consistency {
    /// Records the candidates of the next query; returns each with the number of consecutive
    /// queries (this one included) that had a candidate within `window` keyframes of it.
    pub fn update(&mut self, candidates: &[usize], window: usize) -> Vec<(usize, usize)> {
        let current: Vec<(usize, usize)> = candidates
            .iter()
            .map(|&c| {
                let run = self
                    .previous
                    .iter()
                    .filter(|(p, _)| p.abs_diff(c) <= window)
                    .map(|&(_, run)| run)
                    .max()
                    .unwrap_or(0);
                (c, run + 1)
            })
            .collect();
        self.previous.clone_from(&current);
        current
    }

    /// Forgets the runs (after a closure, or when tracking restarts).
    pub fn reset(&mut self) {
        self.previous.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A room of `n` points with random descriptors, seen from the origin.
    fn scene(rng: &mut ChaCha8Rng, n: usize) -> PlaceFeatures {
        PlaceFeatures {
            points: (0..n)
                .map(|_| {
                    Point3::new(
                        rng.gen_range(-2.0..2.0),
                        rng.gen_range(-1.5..1.5),
                        rng.gen_range(1.0..5.0),
                    )
                })
                .collect(),
            descriptors: (0..n).map(|_| rng.gen()).collect(),
        }
    }

    /// `scene` seen from `camera_from_scene`, a fraction `keep` of its features, points with
    /// `noise_m` noise, descriptors with a few flipped bits.
    fn view(
        rng: &mut ChaCha8Rng,
        scene: &PlaceFeatures,
        camera_from_scene: &Pose3,
        keep: f64,
        noise_m: f64,
    ) -> PlaceFeatures {
        let mut out = PlaceFeatures::default();
        for (p, d) in scene.points.iter().zip(&scene.descriptors) {
            if rng.gen::<f64>() < keep {
                let mut u = || rng.gen_range(-1.0..1.0);
                let jitter = Vector3::new(u(), u(), u()) * noise_m;
                out.points.push(camera_from_scene * p + jitter);
                let mut d = *d;
                d[rng.gen_range(0..4)] ^= 1 << rng.gen_range(0..64);
                out.descriptors.push(d);
            }
        }
        out
    }

    #[test]
    fn a_revisit_is_verified_with_its_true_relative_pose() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let room = scene(&mut rng, 400);
        let first = view(&mut rng, &room, &Pose3::identity(), 0.7, 0.005);
        // back in the room 0.3 m to the side, turned 15°
        let truth = Pose3::new(
            Vector3::new(0.3, 0.0, -0.1),
            Vector3::y() * 15f64.to_radians(),
        );
        let again = view(&mut rng, &room, &truth, 0.7, 0.005);
        let verified = verify(&again, &first, &VerifyConfig::default()).unwrap();
        // first ≈ candidate_from_query · again: candidate_from_query = truth⁻¹
        let err = truth * verified.candidate_from_query;
        assert!(err.translation.vector.norm() < 0.005, "{err}");
        assert!(err.rotation.angle() < 0.2f64.to_radians());
        // about 0.7 × 0.7 of the 400 points are in both views
        assert!(
            verified.inliers.len() > 150 && verified.rms_m < 0.01,
            "{verified:?}"
        );
    }

    #[test]
    fn a_different_place_is_rejected() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let room = scene(&mut rng, 400);
        let other = scene(&mut rng, 400);
        let a = view(&mut rng, &room, &Pose3::identity(), 0.8, 0.005);
        let b = view(&mut rng, &other, &Pose3::identity(), 0.8, 0.005);
        assert!(matches!(
            verify(&b, &a, &VerifyConfig::default()),
            Err(LoopRejection::TooFewMatches { .. })
        ));
        // the same descriptors on a scene whose geometry differs (a repeated texture in
        // another room): matches, but no rigid motion explains them
        let mut lookalike = scene(&mut rng, 400);
        lookalike.descriptors.clone_from(&room.descriptors);
        let c = view(&mut rng, &lookalike, &Pose3::identity(), 0.8, 0.005);
        assert!(matches!(
            verify(&c, &a, &VerifyConfig::default()),
            Err(LoopRejection::TooFewInliers { .. })
        ));
    }

    #[test]
    fn loose_geometry_is_rejected_by_the_residual() {
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        let room = scene(&mut rng, 400);
        let a = view(&mut rng, &room, &Pose3::identity(), 0.8, 0.0);
        // points scattered by up to 4 cm a side: RMS ~ 4 cm, most within RANSAC's 5 cm
        let b = view(&mut rng, &room, &Pose3::identity(), 0.8, 0.04);
        let config = VerifyConfig {
            max_rms_m: 0.02,
            ..VerifyConfig::default()
        };
        assert!(matches!(
            verify(&b, &a, &config),
            Err(LoopRejection::ResidualTooLarge { .. })
        ));
    }

    #[test]
    fn consistency_counts_runs_of_nearby_candidates() {
        let mut c = Consistency::default();
        assert_eq!(c.update(&[40, 90], 2), vec![(40, 1), (90, 1)]);
        assert_eq!(c.update(&[41, 7], 2), vec![(41, 2), (7, 1)]);
        assert_eq!(c.update(&[43], 2), vec![(43, 3)]);
        // a gap breaks the run
        assert_eq!(c.update(&[], 2), vec![]);
        assert_eq!(c.update(&[43], 2), vec![(43, 1)]);
        c.reset();
        assert_eq!(c.update(&[44], 2), vec![(44, 1)]);
    }

    #[test]
    fn default_settings_are_valid_and_bad_ones_are_not() {
        assert!(LoopClosureConfig::default().validate().is_ok());
        let bad = LoopClosureConfig {
            temporal_consistency: 0,
            ..LoopClosureConfig::default()
        };
        assert!(bad.validate().is_err());
    }
}
