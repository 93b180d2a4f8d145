//! Relocalisation: which keyframe of a map a frame sees, and where the frame is from it, when
//! there is no pose to start from (tracking was lost, or a session starts in a saved map).
//!
//! As in ORB-SLAM's relocalisation (Mur-Artal and Tardós, "Fast relocalisation and loop
//! closing in keyframe-based SLAM", ICRA 2014), the frame's descriptors query the place index
//! ([`crate::place_index`]), and the best-voted keyframes (however few their votes: views
//! 30 cm apart share few near-identical descriptors) are verified one by one with the
//! geometric test of loop closure ([`crate::loop_closure::verify`]: RANSAC + Horn on 3D–3D
//! matches, enough inliers, a small residual); the keyframe with the most inliers wins. There
//! is no temporal-consistency test: a lost camera has no previous frame to agree with, and the
//! verification's bar is what keeps wrong places out. Its matching is looser than a loop's
//! (Lowe's ratio 0.9, not 0.8: after a loss the camera has moved, and the ratio test at 0.8
//! keeps few of the matches between views 30 cm apart), its bar on the inliers a fraction of
//! the matches instead: on 7-Scenes, views of the same place gave 50–75 % inliers, views of
//! other places 30–36 %.

use serde::{Deserialize, Serialize};

use crate::covisibility::PlaceFeatures;
use slamkit_core::ransac::RansacConfig;
use slamkit_vision::MatchConfig;

use crate::loop_closure::{verify, VerifiedLoop, VerifyConfig};
use crate::place_index::PlaceIndex;
use crate::VoError;

/// Settings of relocalisation (a lost [`crate::Odometry`] in a session with loop closure, or
/// localisation in a saved map).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RelocalisationConfig {
    /// Best-voted keyframes verified per frame.
    pub candidates: usize,
    /// Geometric verification of a candidate.
    pub verification: VerifyConfig,
    /// Lost this long without being found in the map, tracking starts again at the last pose
    /// (a new stretch of odometry, which the pose graph joins to the map by a weak edge until
    /// a loop closes) \[s\]; 0: never, the camera stays lost until it is found.
    pub restart_after_s: f64,
}

impl Default for RelocalisationConfig {
    fn default() -> Self {
        Self {
            candidates: 5,
            verification: VerifyConfig {
                matching: MatchConfig {
                    max_distance: 64,
                    ratio: 0.9,
                    cross_check: true,
                },
                ransac: RansacConfig {
                    threshold: 0.05,
                    max_iterations: 500,
                    ..RansacConfig::default()
                },
                min_inliers: 30,
                min_inlier_ratio: 0.5,
                max_rms_m: 0.03,
            },
            restart_after_s: 3.0,
        }
    }
}

impl RelocalisationConfig {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`VoError::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<(), VoError> {
        if self.verification.min_inliers == 0 {
            return Err(VoError::config(
                "relocalisation.verification.min_inliers",
                0,
                "must be > 0",
            ));
        }
        if !(self.verification.max_rms_m.is_finite() && self.verification.max_rms_m > 0.0) {
            return Err(VoError::config(
                "relocalisation.verification.max_rms_m",
                self.verification.max_rms_m,
                "must be finite and > 0",
            ));
        }
        if self.candidates == 0 {
            return Err(VoError::config(
                "relocalisation.candidates",
                0,
                "must be > 0",
            ));
        }
        if !(self.restart_after_s.is_finite() && self.restart_after_s >= 0.0) {
            return Err(VoError::config(
                "relocalisation.restart_after_s",
                self.restart_after_s,
                "must be finite and >= 0",
            ));
        }
        Ok(())
    }
}

/// A frame found in the map.
#[derive(Debug, Clone, PartialEq)]
pub struct Relocalisation {
    /// The keyframe the frame sees.
    pub keyframe: usize,
    /// The verified match: `candidate_from_query` is the frame's camera in the keyframe's.
    pub verified: VerifiedLoop,
}

/// Finds the frame with features `query` among the keyframes of `index`, whose features
/// `keyframe` gives by id: the `candidates` best-voted keyframes are verified
/// (`config.verification`), the one with the most inliers is returned (`None`: no keyframe
/// passed).
///
/// ```
/// use nalgebra::Point3;
/// use slamkit_core::Pose3;
/// use slamkit_vo::covisibility::PlaceFeatures;
/// use slamkit_vo::place_index::{PlaceIndex, PlaceIndexConfig};
/// use slamkit_vo::relocalisation::{relocalise, RelocalisationConfig};
///
/// // one keyframe seeing 60 points with distinct descriptors
/// let mut seen = PlaceFeatures::default();
/// for i in 0..60u64 {
///     let f = i as f64;
///     seen.points.push(Point3::new((f * 0.37).sin(), (f * 0.71).cos(), 2.0 + (f * 0.13).sin()));
///     seen.descriptors.push([i.wrapping_mul(0x9e37_79b9_7f4a_7c15), i << 7 | 1, !i, i * 3]);
/// }
/// let mut index = PlaceIndex::new(PlaceIndexConfig::default())?;
/// index.insert(0, &seen.descriptors);
/// // the same view 10 cm to the left: found, with the frame 10 cm left of the keyframe
/// let shift = Pose3::translation(0.1, 0.0, 0.0);
/// let query = PlaceFeatures {
///     points: seen.points.iter().map(|p| shift * p).collect(),
///     descriptors: seen.descriptors.clone(),
/// };
/// let found = relocalise(&query, &index, |_| Some(&seen), &RelocalisationConfig::default())
///     .expect("found");
/// assert_eq!(found.keyframe, 0);
/// let x = found.verified.candidate_from_query.translation.vector.x;
/// assert!((x + 0.1).abs() < 1e-6);
/// # Ok::<(), slamkit_vo::VoError>(())
/// ```
pub fn relocalise<'a>(
    query: &PlaceFeatures,
    index: &PlaceIndex,
    keyframe: impl Fn(usize) -> Option<&'a PlaceFeatures>,
    config: &RelocalisationConfig,
) -> Option<Relocalisation> {
    if query.is_empty() {
        return None;
    }
    index
        .query(&query.descriptors)
        .into_iter()
        .take(config.candidates)
        .filter_map(|m| {
            let verified = verify(query, keyframe(m.keyframe)?, &config.verification).ok()?;
            Some(Relocalisation {
                keyframe: m.keyframe,
                verified,
            })
        })
        .max_by(|a, b| {
            a.verified
                .inliers
                .len()
                .cmp(&b.verified.inliers.len())
                // ties: the earlier keyframe (the first seen, as the index ranks them)
                .then(b.keyframe.cmp(&a.keyframe))
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::place_index::PlaceIndexConfig;
    use nalgebra::{Point3, Vector3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use slamkit_core::Pose3;

    /// `n` points of a room with random descriptors, in the room's frame.
    fn room(rng: &mut ChaCha8Rng, n: usize) -> PlaceFeatures {
        PlaceFeatures {
            points: (0..n)
                .map(|_| {
                    Point3::new(
                        rng.gen_range(-3.0..3.0),
                        rng.gen_range(-1.5..1.5),
                        rng.gen_range(1.0..6.0),
                    )
                })
                .collect(),
            descriptors: (0..n).map(|_| rng.gen()).collect(),
        }
    }

    /// The room's points in front of the camera at `room_from_camera` (3 mm noise, a bit
    /// of each descriptor flipped), in the camera's frame.
    fn view(rng: &mut ChaCha8Rng, room: &PlaceFeatures, room_from_camera: &Pose3) -> PlaceFeatures {
        let camera_from_room = room_from_camera.inverse();
        let mut out = PlaceFeatures::default();
        for (p, d) in room.points.iter().zip(&room.descriptors) {
            let c = camera_from_room * p;
            if c.z > 0.5 && c.x.abs() < c.z && rng.gen::<f64>() < 0.8 {
                let mut u = || rng.gen_range(-0.003..0.003);
                out.points.push(c + Vector3::new(u(), u(), u()));
                let mut d = *d;
                d[rng.gen_range(0..4)] ^= 1 << rng.gen_range(0..64);
                out.descriptors.push(d);
            }
        }
        out
    }

    /// Keyframes looking along x = −2, 0, 2 m at the room (turned 25° in turn).
    fn keyframe_pose(i: usize) -> Pose3 {
        let x = i as f64 * 2.0 - 2.0;
        Pose3::new(
            Vector3::new(x, 0.0, -1.0),
            Vector3::y() * (x * 12.5).to_radians(),
        )
    }

    #[test]
    fn a_view_is_found_at_its_keyframe_with_its_pose_and_another_room_is_not() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let scene = room(&mut rng, 1500);
        let mut index = PlaceIndex::new(PlaceIndexConfig::default()).unwrap();
        let keyframes: Vec<PlaceFeatures> = (0..3)
            .map(|i| view(&mut rng, &scene, &keyframe_pose(i)))
            .collect();
        for (i, k) in keyframes.iter().enumerate() {
            index.insert(i, &k.descriptors);
        }
        let config = RelocalisationConfig::default();
        // near the third keyframe, 20 cm aside and turned 5°
        let truth = keyframe_pose(2)
            * Pose3::new(
                Vector3::new(0.2, 0.05, 0.1),
                Vector3::y() * 5f64.to_radians(),
            );
        let query = view(&mut rng, &scene, &truth);
        let found = relocalise(&query, &index, |i| keyframes.get(i), &config).unwrap();
        assert_eq!(found.keyframe, 2);
        let estimate = keyframe_pose(2) * found.verified.candidate_from_query;
        let err = truth.inverse() * estimate;
        assert!(err.translation.vector.norm() < 0.01, "{err}");
        assert!(err.rotation.angle() < 0.5f64.to_radians(), "{err}");
        // a room never seen: not found
        let other = room(&mut rng, 1500);
        let lost = view(&mut rng, &other, &Pose3::identity());
        let found = relocalise(&lost, &index, |i| keyframes.get(i), &config);
        assert!(found.is_none(), "{found:?}");
        // nothing to match with: not found
        let empty = PlaceFeatures::default();
        assert!(relocalise(&empty, &index, |i| keyframes.get(i), &config).is_none());
    }

    #[test]
    fn bad_settings_are_refused() {
        assert!(RelocalisationConfig::default().validate().is_ok());
        for bad in [
            RelocalisationConfig {
                candidates: 0,
                ..RelocalisationConfig::default()
            },
            RelocalisationConfig {
                verification: VerifyConfig {
                    min_inliers: 0,
                    ..VerifyConfig::default()
                },
                ..RelocalisationConfig::default()
            },
            RelocalisationConfig {
                restart_after_s: f64::NAN,
                ..RelocalisationConfig::default()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
