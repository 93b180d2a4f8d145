//! Tracking against the points of a saved map: where a frame is in the map, measured from the
//! map's own points rather than carried over by odometry (ORB-SLAM's "track local map",
//! Mur-Artal, Montiel and Tardós, T-RO 2015, §V-D: the map points near the predicted pose
//! projected into the frame, matched by descriptor near their projection, and the pose
//! refined on the matches).
//!
//! The map points are those of the keyframes nearest the predicted pose
//! ([`nearest_keyframes`]), each in the map frame with its ORB descriptor. Each is projected
//! into the predicted camera and matched to the frame's ORB features with depth within
//! `search_radius_px` of it; the matches give 3D–3D correspondences (the map point seen from
//! the predicted camera, the frame's point) that [`crate::motion::estimate_motion`] turns into
//! the camera's motion from its predicted pose (RANSAC on reprojection error, then
//! Gauss–Newton on the stereo reprojection error weighted by depth noise). Too few inliers
//! (the camera sees a part of the scene the map lacks) is no fix: the caller keeps its
//! odometry.
//!
//! Why points and not one keyframe: a single keyframe's 3D–3D match (what relocalisation
//! verifies) rests on one view's depth noise and left the frames it placed 0.19 m from the
//! map's trajectory on 7-Scenes; points of several keyframes refined on their reprojection
//! error are measured as precisely as odometry measures a step.

use nalgebra::{Point2, Point3};
use serde::{Deserialize, Serialize};
use slamkit_core::Pose3;
use slamkit_vision::matching::match_descriptors_within;
use slamkit_vision::{Descriptor, MatchConfig};

use crate::covisibility::PlaceFeatures;
use crate::local_map::project;
use crate::motion::{estimate_motion, Correspondence, MotionConfig, StereoCamera};
use crate::VoError;

/// Settings of tracking against a saved map's points.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MapTrackingConfig {
    /// Track against the map's points (off: odometry only between relocalisations).
    pub enabled: bool,
    /// Keyframes whose points are projected into a frame: the nearest ones.
    pub max_keyframes: usize,
    /// Keyframes farther than this from the predicted camera are left out \[m\].
    pub max_distance_m: f64,
    /// Keyframes looking more than this away from the predicted camera are left out \[deg\].
    pub max_angle_deg: f64,
    /// A map point matches a feature at most this far from its projection \[px\].
    pub search_radius_px: f64,
    /// Descriptor matching of map points to the frame's features.
    pub matching: MatchConfig,
    /// Fewest inliers of an accepted fix.
    pub min_inliers: usize,
    /// Smallest accepted inlier fraction of the matches, in \[0, 1\].
    pub min_inlier_ratio: f64,
}

impl Default for MapTrackingConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            max_keyframes: 5,
            max_distance_m: 1.0,
            max_angle_deg: 30.0,
            search_radius_px: 10.0,
            matching: MatchConfig::default(),
            min_inliers: 40,
            min_inlier_ratio: 0.5,
        }
    }
}

impl MapTrackingConfig {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`VoError::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<(), VoError> {
        for (field, v) in [
            ("map_tracking.max_distance_m", self.max_distance_m),
            ("map_tracking.max_angle_deg", self.max_angle_deg),
            ("map_tracking.search_radius_px", self.search_radius_px),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(VoError::config(field, v, "must be finite and > 0"));
            }
        }
        if self.max_keyframes == 0 {
            return Err(VoError::config(
                "map_tracking.max_keyframes",
                0,
                "must be > 0",
            ));
        }
        if self.min_inliers < 5 {
            return Err(VoError::config(
                "map_tracking.min_inliers",
                self.min_inliers,
                "must be >= 5",
            ));
        }
        if !(0.0..=1.0).contains(&self.min_inlier_ratio) {
            return Err(VoError::config(
                "map_tracking.min_inlier_ratio",
                self.min_inlier_ratio,
                "must be in [0, 1]",
            ));
        }
        Ok(())
    }
}

/// A point of the map: its position in the map frame and its ORB descriptor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapPoint {
    /// Position in the map frame \[m\].
    pub position: Point3<f64>,
    /// ORB descriptor of the feature it was seen as.
    pub descriptor: Descriptor,
}

/// Where the map's points put a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct MapFix {
    /// `map_from_camera` of the frame.
    pub map_from_camera: Pose3,
    /// Matches of map points to the frame's features.
    pub matches: usize,
    /// Matches consistent with the fix.
    pub inliers: usize,
}

/// Indices of the keyframes (their `map_from_camera` poses) to track a camera predicted at
/// `map_from_predicted` against: those within `max_distance_m` and `max_angle_deg` of it, the
/// nearest `max_keyframes` first.
///
/// ```
/// use nalgebra::Vector3;
/// use slamkit_core::Pose3;
/// use slamkit_vo::map_tracking::{nearest_keyframes, MapTrackingConfig};
///
/// let keyframes = [
///     Pose3::translation(0.0, 0.0, 0.0),
///     Pose3::translation(0.3, 0.0, 0.0),
///     Pose3::translation(3.0, 0.0, 0.0),                           // too far
///     Pose3::new(Vector3::new(0.1, 0.0, 0.0), Vector3::y() * 1.5), // looking away
/// ];
/// let near = nearest_keyframes(&keyframes, &Pose3::translation(0.25, 0.0, 0.0),
///     &MapTrackingConfig::default());
/// assert_eq!(near, vec![1, 0]);
/// ```
pub fn nearest_keyframes(
    keyframes: &[Pose3],
    map_from_predicted: &Pose3,
    config: &MapTrackingConfig,
) -> Vec<usize> {
    let max_angle = config.max_angle_deg.to_radians();
    let mut near: Vec<(f64, usize)> = keyframes
        .iter()
        .enumerate()
        .filter_map(|(i, k)| {
            let relative = k.inverse() * map_from_predicted;
            let distance = relative.translation.vector.norm();
            (distance <= config.max_distance_m && relative.rotation.angle() <= max_angle)
                .then_some((distance, i))
        })
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    near.into_iter()
        .take(config.max_keyframes)
        .map(|(_, i)| i)
        .collect()
}

/// Where `points` of the map put a frame with features `frame` (points in its camera frame,
/// each with its descriptor), seen by `camera` and predicted at `map_from_predicted`; `None`
/// when too few map points match it (`min_inliers`, `min_inlier_ratio`; the RANSAC and
/// refinement settings are `motion`'s).
///
/// ```
/// use nalgebra::Point3;
/// use slamkit_core::camera::Intrinsics;
/// use slamkit_core::Pose3;
/// use slamkit_vo::covisibility::PlaceFeatures;
/// use slamkit_vo::map_tracking::{track_in_map, MapPoint, MapTrackingConfig};
/// use slamkit_vo::motion::{MotionConfig, StereoCamera};
///
/// // 100 map points on a wall 2 m in front of the map's origin, each with its descriptor
/// let points: Vec<MapPoint> = (0..100u64)
///     .map(|i| MapPoint {
///         position: Point3::new((i % 10) as f64 * 0.2 - 0.9, (i / 10) as f64 * 0.15 - 0.7, 2.0),
///         descriptor: [i.wrapping_mul(0x9e37_79b9_7f4a_7c15), i << 9 | 3, !i, i * 7],
///     })
///     .collect();
/// // the camera is 5 cm right of the origin; odometry predicted it 2 cm off
/// let truth = Pose3::translation(0.05, 0.0, 0.0);
/// let frame = PlaceFeatures {
///     points: points.iter().map(|p| truth.inverse() * p.position).collect(),
///     descriptors: points.iter().map(|p| p.descriptor).collect(),
/// };
/// let camera = StereoCamera { k: Intrinsics::from_array([500.0, 500.0, 320.0, 240.0], 640, 480), bf: 40.0 };
/// let fix = track_in_map(&points, &frame, &camera, &Pose3::translation(0.03, 0.0, 0.0),
///     &MapTrackingConfig::default(), &MotionConfig::default()).expect("a fix");
/// assert!((fix.map_from_camera.translation.vector - truth.translation.vector).norm() < 1e-6);
/// assert_eq!(fix.inliers, 100);
/// ```
pub fn track_in_map(
    points: &[MapPoint],
    frame: &PlaceFeatures,
    camera: &StereoCamera,
    map_from_predicted: &Pose3,
    config: &MapTrackingConfig,
    motion: &MotionConfig,
) -> Option<MapFix> {
    let k = &camera.k;
    let predicted_from_map = map_from_predicted.inverse();
    // map points in front of the predicted camera and inside its image
    let mut seen: Vec<Point3<f64>> = Vec::new();
    let mut map_d: Vec<Descriptor> = Vec::new();
    let mut map_px: Vec<[f32; 2]> = Vec::new();
    for p in points {
        let q = predicted_from_map * p.position;
        if let Some(px) = project(k, &q) {
            seen.push(q);
            map_d.push(p.descriptor);
            map_px.push(px);
        }
    }
    // the frame's features at the pixels their points were lifted from
    let n = frame.len();
    let frame_px: Vec<[f32; 2]> = frame.points[..n]
        .iter()
        .map(|p| project(k, p).unwrap_or([f32::NAN; 2]))
        .collect();
    let matches = match_descriptors_within(
        (&map_d, &map_px),
        (&frame.descriptors[..n], &frame_px),
        config.search_radius_px as f32,
        &config.matching,
    )
    .ok()?;
    let data: Vec<Correspondence> = matches
        .iter()
        .filter_map(|m| {
            let [u, v] = *frame_px.get(m.train_idx)?;
            Some(Correspondence {
                reference: *seen.get(m.query_idx)?,
                current: *frame.points.get(m.train_idx)?,
                current_px: Point2::new(f64::from(u), f64::from(v)),
            })
        })
        .collect();
    let motion = MotionConfig {
        min_inliers: config.min_inliers,
        min_inlier_ratio: config.min_inlier_ratio,
        ..motion.clone()
    };
    let estimate = estimate_motion(&data, camera, &motion).ok()?;
    Some(MapFix {
        map_from_camera: map_from_predicted * estimate.current_from_reference.inverse(),
        matches: data.len(),
        inliers: estimate.inliers.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use slamkit_core::camera::Intrinsics;

    fn camera() -> StereoCamera {
        StereoCamera {
            k: Intrinsics::from_array([525.0, 525.0, 319.5, 239.5], 640, 480),
            bf: 0.08 * 525.0,
        }
    }

    /// `n` points of a room 1–5 m deep with random descriptors.
    fn room(rng: &mut ChaCha8Rng, n: usize) -> Vec<MapPoint> {
        (0..n)
            .map(|_| MapPoint {
                position: Point3::new(
                    rng.gen_range(-2.0..2.0),
                    rng.gen_range(-1.5..1.5),
                    rng.gen_range(1.0..5.0),
                ),
                descriptor: rng.gen(),
            })
            .collect()
    }

    /// The room as a camera at `map_from_camera` sees it: points with 2 mm of noise, a fifth
    /// of them missed, a few descriptor bits flipped, and `clutter` features of its own.
    fn view(
        rng: &mut ChaCha8Rng,
        room: &[MapPoint],
        map_from_camera: &Pose3,
        clutter: usize,
    ) -> PlaceFeatures {
        let camera_from_map = map_from_camera.inverse();
        let mut out = PlaceFeatures::default();
        for p in room {
            let c = camera_from_map * p.position;
            if project(&camera().k, &c).is_some() && rng.gen::<f64>() < 0.8 {
                let mut u = || rng.gen_range(-0.002..0.002);
                out.points.push(c + Vector3::new(u(), u(), u()));
                let mut d = p.descriptor;
                d[rng.gen_range(0..4)] ^= 1 << rng.gen_range(0..64);
                out.descriptors.push(d);
            }
        }
        for _ in 0..clutter {
            let z = rng.gen_range(1.0..4.0);
            out.points.push(Point3::new(
                rng.gen_range(-0.5..0.5) * z,
                rng.gen_range(-0.4..0.4) * z,
                z,
            ));
            out.descriptors.push(rng.gen());
        }
        out
    }

    #[test]
    fn a_camera_predicted_off_its_pose_is_put_back_by_the_map_points() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let points = room(&mut rng, 2000);
        let truth = Pose3::new(Vector3::new(0.3, -0.1, 0.2), Vector3::y() * 0.1);
        let frame = view(&mut rng, &points, &truth, 200);
        // odometry drifted 2.4 cm and 0.5° (a few pixels, within the search radius)
        let predicted = truth
            * Pose3::new(
                Vector3::new(0.015, -0.01, 0.015),
                Vector3::new(0.0, 1.0, 0.5).normalize() * 0.5f64.to_radians(),
            );
        let config = MapTrackingConfig::default();
        let fix = track_in_map(
            &points,
            &frame,
            &camera(),
            &predicted,
            &config,
            &MotionConfig::default(),
        )
        .unwrap();
        let err = truth.inverse() * fix.map_from_camera;
        assert!(err.translation.vector.norm() < 0.002, "{err}");
        assert!(err.rotation.angle() < 0.1f64.to_radians(), "{err}");
        assert!(fix.inliers > 500 && fix.inliers <= fix.matches, "{fix:?}");
    }

    #[test]
    fn a_part_of_the_scene_the_map_lacks_gives_no_fix() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let points = room(&mut rng, 2000);
        let elsewhere = room(&mut rng, 2000);
        let frame = view(&mut rng, &elsewhere, &Pose3::identity(), 0);
        let config = MapTrackingConfig::default();
        let motion = MotionConfig::default();
        let fix = track_in_map(
            &points,
            &frame,
            &camera(),
            &Pose3::identity(),
            &config,
            &motion,
        );
        assert!(fix.is_none(), "{fix:?}");
        // nor does an empty map or an empty frame
        let empty = PlaceFeatures::default();
        let id = Pose3::identity();
        assert!(track_in_map(&[], &frame, &camera(), &id, &config, &motion).is_none());
        assert!(track_in_map(&points, &empty, &camera(), &id, &config, &motion).is_none());
    }

    #[test]
    fn keyframes_are_taken_nearest_first_within_reach() {
        let config = MapTrackingConfig {
            max_keyframes: 2,
            ..MapTrackingConfig::default()
        };
        let keyframes: Vec<Pose3> = (0..6)
            .map(|i| Pose3::translation(f64::from(i) * 0.3, 0.0, 0.0))
            .collect();
        let near = nearest_keyframes(&keyframes, &Pose3::translation(0.95, 0.0, 0.0), &config);
        assert_eq!(near, vec![3, 4]);
        assert!(
            nearest_keyframes(&keyframes, &Pose3::translation(9.0, 0.0, 0.0), &config).is_empty()
        );
    }

    #[test]
    fn bad_settings_are_refused() {
        assert!(MapTrackingConfig::default().validate().is_ok());
        for bad in [
            MapTrackingConfig {
                max_keyframes: 0,
                ..MapTrackingConfig::default()
            },
            MapTrackingConfig {
                search_radius_px: f64::NAN,
                ..MapTrackingConfig::default()
            },
            MapTrackingConfig {
                min_inliers: 2,
                ..MapTrackingConfig::default()
            },
            MapTrackingConfig {
                min_inlier_ratio: 1.5,
                ..MapTrackingConfig::default()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
