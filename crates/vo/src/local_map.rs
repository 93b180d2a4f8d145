//! The local map model: rather than only the previous frame, the current frame is matched
//! against the features of the recent key frames (default: the last 35 frames, every second
//! one a key frame), each feature's 3D position the mean of its repeated observations.
//!
//! Averaging `n` observations shrinks a feature's position noise by √n, so the motion of each
//! new frame is measured against steadier points and drift slows; a feature that was missed
//! in a bad frame is still in the map for the next one, so tracking recovers. This is the
//! local map of keyframe-based VO (PTAM, Klein & Murray, ISMAR 2007; ORB-SLAM's local map,
//! Mur-Artal et al., T-RO 2015) without its bundle adjustment: positions are means, weighted
//! by the inverse variance of each observation's depth (stereo and Kinect depth noise grow
//! with z², so a point first seen far away must not pull its later close-range observations).
//!
//! With ORB, landmarks are matched only near their projection into the predicted pose (as
//! ORB-SLAM's "search by projection"): matching against the whole map drowned each query in
//! thousands of unrelated descriptors, so Lowe's ratio test rejected nearly everything
//! (BENCHMARKS.md). A key frame's unmatched feature that projects next to a landmark with a
//! close descriptor merges into it ([`LocalMap::add_keyframe`]), so a point missed once does
//! not come back as a duplicate; the map is capped.

use std::collections::HashMap;

use nalgebra::{Point2, Point3, Vector3};
use serde::{Deserialize, Serialize};
use slamkit_core::camera::Intrinsics;
use slamkit_core::Pose3;
use slamkit_vision::matching::match_descriptors_within;
use slamkit_vision::{Descriptor, MatchConfig};

use crate::error::VoError;
use crate::local_ba::LocalBaConfig;

/// Local map settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LocalMapConfig {
    /// Features not seen in the last this many frames leave the map \[frames\].
    pub window_frames: usize,
    /// Every this many tracked frames is a key frame whose observations enter the map.
    pub keyframe_every: usize,
    /// Most landmarks kept; beyond it the least recently seen leave first.
    pub max_landmarks: usize,
    /// ORB: a landmark is matched only to features within this distance of its projection
    /// into the constant-velocity prediction of the pose \[px\].
    pub search_radius_px: f64,
    /// ORB: when the search around the prediction finds fewer than `min_window_matches`
    /// matches (a jerk, or a restart), it is repeated within this distance \[px\].
    pub recovery_radius_px: f64,
    /// ORB: see `recovery_radius_px` \[matches\].
    pub min_window_matches: usize,
    /// ORB frame to frame: coarser pyramid levels (`orb.scale_factor` apart) a feature may
    /// also be described on, so that a frame seeing it larger or smaller than the reference
    /// did (driving towards or away from it) still matches. Each reference feature's scale
    /// change is predicted from its depth and the predicted pose; it is compared on every
    /// level from 0 to the one that change calls for, on every level within this many in the
    /// recovery search. 0: the level-0 descriptors only.
    pub scale_levels: usize,
    /// ORB: a key-frame feature left unmatched is merged into the landmark projecting within
    /// this distance of it with a descriptor within the matching distance, instead of
    /// becoming a new landmark \[px\].
    pub merge_radius_px: f64,
    /// Local bundle adjustment of the recent key frames and their landmarks.
    pub bundle: LocalBaConfig,
}

impl Default for LocalMapConfig {
    fn default() -> Self {
        Self {
            window_frames: 35,
            keyframe_every: 2,
            max_landmarks: 6000,
            search_radius_px: 45.0,
            recovery_radius_px: 120.0,
            min_window_matches: 50,
            scale_levels: 0,
            merge_radius_px: 3.0,
            bundle: LocalBaConfig::default(),
        }
    }
}

impl LocalMapConfig {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`VoError::InvalidConfig`] for a zero window, key-frame spacing or capacity, or a
    /// radius that is not positive and finite.
    pub fn validate(&self) -> Result<(), VoError> {
        for (field, v) in [
            ("local_map.window_frames", self.window_frames),
            ("local_map.keyframe_every", self.keyframe_every),
            ("local_map.max_landmarks", self.max_landmarks),
        ] {
            if v == 0 {
                return Err(VoError::config(field, 0, "must be > 0"));
            }
        }
        for (field, r) in [
            ("local_map.search_radius_px", self.search_radius_px),
            ("local_map.recovery_radius_px", self.recovery_radius_px),
            ("local_map.merge_radius_px", self.merge_radius_px),
        ] {
            if !(r.is_finite() && r > 0.0) {
                return Err(VoError::config(field, r, "must be finite and > 0"));
            }
        }
        self.bundle.validate()
    }
}

/// One map feature.
#[derive(Debug, Clone, PartialEq)]
pub struct Landmark {
    weighted_sum: Vector3<f64>,
    weight: f64,
    count: u32,
    last_seen: usize,
    last_observed: usize,
    descriptor: Option<Descriptor>,
}

impl Landmark {
    /// Mean of the observed world positions, each weighted by its inverse depth variance
    /// \[m\].
    pub fn position(&self) -> Point3<f64> {
        Point3::from(self.weighted_sum / self.weight)
    }

    /// Number of observations averaged.
    pub fn observations(&self) -> u32 {
        self.count
    }

    /// The latest descriptor (ORB front end).
    pub fn descriptor(&self) -> Option<&Descriptor> {
        self.descriptor.as_ref()
    }
}

/// One observation of a landmark: its world position, the inverse variance it is weighted
/// by in the mean (> 0), its descriptor and frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// World position \[m\].
    pub world: Point3<f64>,
    /// Weight in the mean, the inverse of the depth variance \[1/m²\]; must be > 0.
    pub weight: f64,
    /// Descriptor (ORB front end).
    pub descriptor: Option<Descriptor>,
    /// Frame index.
    pub frame: usize,
}

/// A key-frame feature: its observation, its pixel and the landmark it was matched to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seen {
    /// The observation.
    pub observation: Observation,
    /// Pixel in the key frame.
    pub pixel: Point2<f64>,
    /// The landmark it was matched to while tracking, if any.
    pub landmark: Option<u64>,
}

/// How an unmatched key-frame feature finds the landmark it duplicates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MergeConfig {
    /// Farthest distance between its pixel and the landmark's projection \[px\].
    pub radius_px: f64,
    /// Farthest descriptor distance \[bits\].
    pub max_distance: u32,
}

/// Landmarks projected into a camera, index-aligned: ids, descriptors and pixels.
pub type Projected = (Vec<u64>, Vec<Descriptor>, Vec<[f32; 2]>);

/// Landmarks by id.
#[derive(Debug, Clone, Default)]
pub struct LocalMap {
    landmarks: HashMap<u64, Landmark>,
    next_id: u64,
}

impl LocalMap {
    /// An empty map.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of landmarks.
    pub fn len(&self) -> usize {
        self.landmarks.len()
    }

    /// True when the map holds no landmark.
    pub fn is_empty(&self) -> bool {
        self.landmarks.is_empty()
    }

    /// The landmark `id`, if it is still in the map.
    pub fn get(&self, id: u64) -> Option<&Landmark> {
        self.landmarks.get(&id)
    }

    /// Adds a new landmark from its first observation; returns its id.
    pub fn insert(&mut self, o: &Observation) -> u64 {
        let id = self.next_id;
        self.next_id += 1;
        let weight = o.weight.max(f64::MIN_POSITIVE);
        self.landmarks.insert(
            id,
            Landmark {
                weighted_sum: o.world.coords * weight,
                weight,
                count: 1,
                last_seen: o.frame,
                last_observed: o.frame,
                descriptor: o.descriptor,
            },
        );
        id
    }

    /// Merges an observation into landmark `id`'s mean (its descriptor becomes the latest);
    /// false when `id` left the map.
    pub fn observe(&mut self, id: u64, o: &Observation) -> bool {
        let Some(l) = self.landmarks.get_mut(&id) else {
            return false;
        };
        let weight = o.weight.max(f64::MIN_POSITIVE);
        l.weighted_sum += o.world.coords * weight;
        l.weight += weight;
        l.count += 1;
        l.last_seen = l.last_seen.max(o.frame);
        l.last_observed = l.last_observed.max(o.frame);
        if o.descriptor.is_some() {
            l.descriptor = o.descriptor;
        }
        true
    }

    /// Moves landmark `id` to `position` (a refinement), keeping the weight its observations
    /// gave it, so that later observations average with it as before; false when `id` left the
    /// map.
    pub fn set_position(&mut self, id: u64, position: &Point3<f64>) -> bool {
        let Some(l) = self.landmarks.get_mut(&id) else {
            return false;
        };
        l.weighted_sum = position.coords * l.weight;
        true
    }

    /// Moves every landmark by `new_from_old` (its observations' weighted sum with it).
    pub fn transform(&mut self, new_from_old: &Pose3) {
        let r = new_from_old.rotation;
        let t = new_from_old.translation.vector;
        for l in self.landmarks.values_mut() {
            l.weighted_sum = r * l.weighted_sum + t * l.weight;
        }
    }

    /// Marks landmark `id` as seen in `frame` without adding an observation to its mean; its
    /// descriptor, when given, becomes the latest.
    pub fn touch(&mut self, id: u64, descriptor: Option<Descriptor>, frame: usize) {
        if let Some(l) = self.landmarks.get_mut(&id) {
            l.last_seen = l.last_seen.max(frame);
            if descriptor.is_some() {
                l.descriptor = descriptor;
            }
        }
    }

    /// Removes the landmarks not seen within `window_frames` of `frame`, then the least
    /// recently seen (fewest observations first among equals) beyond `max_landmarks`.
    pub fn prune(&mut self, frame: usize, window_frames: usize, max_landmarks: usize) {
        self.landmarks
            .retain(|_, l| frame.saturating_sub(l.last_seen) < window_frames);
        let excess = self.landmarks.len().saturating_sub(max_landmarks);
        if excess == 0 {
            return;
        }
        let mut order: Vec<(usize, u32, u64)> = self
            .landmarks
            .iter()
            .map(|(&id, l)| (l.last_seen, l.count, id))
            .collect();
        order.sort_unstable();
        for (_, _, id) in order.into_iter().take(excess) {
            self.landmarks.remove(&id);
        }
    }

    /// Adds a key frame seen from `camera_from_world` through `k`: a feature matched to a
    /// landmark while tracking merges into it; an unmatched one merges into the landmark not
    /// yet observed in this frame that projects within `merge.radius_px` of it with the
    /// mutually nearest descriptor within `merge.max_distance` (a point missed by tracking
    /// does not come back as a duplicate); the others become new landmarks. Returns the
    /// landmark of each feature.
    pub fn add_keyframe(
        &mut self,
        seen: &[Seen],
        camera_from_world: &Pose3,
        k: &Intrinsics,
        merge: &MergeConfig,
    ) -> Vec<u64> {
        let mut ids: Vec<Option<u64>> = seen
            .iter()
            .map(|s| s.landmark.filter(|&id| self.observe(id, &s.observation)))
            .collect();
        let frame = seen.first().map(|s| s.observation.frame);
        let (lm_ids, lm_descriptors, lm_pixels) = self.project(camera_from_world, k, frame);
        let unmatched: Vec<(usize, Descriptor, [f32; 2])> = seen
            .iter()
            .zip(&ids)
            .enumerate()
            .filter(|(_, (_, id))| id.is_none())
            .filter_map(|(i, (s, _))| {
                let px = [s.pixel.x as f32, s.pixel.y as f32];
                Some((i, s.observation.descriptor?, px))
            })
            .collect();
        let query_d: Vec<Descriptor> = unmatched.iter().map(|u| u.1).collect();
        let query_px: Vec<[f32; 2]> = unmatched.iter().map(|u| u.2).collect();
        let nearest = MatchConfig {
            max_distance: merge.max_distance,
            ratio: 1.0,
            cross_check: true,
        };
        // the lists are index-aligned; a radius that is not positive merges nothing
        let merges = match_descriptors_within(
            (&query_d, &query_px),
            (&lm_descriptors, &lm_pixels),
            merge.radius_px as f32,
            &nearest,
        )
        .unwrap_or_default();
        for m in merges {
            let (Some(&(i, _, _)), Some(&id)) =
                (unmatched.get(m.query_idx), lm_ids.get(m.train_idx))
            else {
                continue;
            };
            if let (Some(s), Some(slot)) = (seen.get(i), ids.get_mut(i)) {
                *slot = self.observe(id, &s.observation).then_some(id);
            }
        }
        seen.iter()
            .zip(ids)
            .map(|(s, id)| id.unwrap_or_else(|| self.insert(&s.observation)))
            .collect()
    }

    /// The landmarks with a descriptor that lie in front of the camera and project inside
    /// its image, in id order, leaving out those already observed in frame `skip_observed_in`.
    pub fn project(
        &self,
        camera_from_world: &Pose3,
        k: &Intrinsics,
        skip_observed_in: Option<usize>,
    ) -> Projected {
        let mut v: Vec<(u64, Descriptor, [f32; 2])> = self
            .landmarks
            .iter()
            .filter(|(_, l)| skip_observed_in != Some(l.last_observed))
            .filter_map(|(&id, l)| {
                let px = project(k, &(camera_from_world * l.position()))?;
                Some((id, l.descriptor?, px))
            })
            .collect();
        v.sort_unstable_by_key(|(id, _, _)| *id);
        let mut out: Projected = (Vec::new(), Vec::new(), Vec::new());
        for (id, d, px) in v {
            out.0.push(id);
            out.1.push(d);
            out.2.push(px);
        }
        out
    }
}

/// The pixel of camera-frame point `p` when it lies in front of the camera and inside its
/// image.
pub fn project(k: &Intrinsics, p: &Point3<f64>) -> Option<[f32; 2]> {
    if p.z <= 0.0 || !p.z.is_finite() {
        return None;
    }
    let px = k.to_pixel(&Point2::new(p.x / p.z, p.y / p.z));
    k.contains(&px).then_some([px.x as f32, px.y as f32])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(x: f64, y: f64, z: f64, weight: f64, frame: usize) -> Observation {
        Observation {
            world: Point3::new(x, y, z),
            weight,
            descriptor: None,
            frame,
        }
    }

    #[test]
    fn repeated_observations_merge_into_their_weighted_mean() {
        let mut map = LocalMap::new();
        let id = map.insert(&obs(1.0, 2.0, 3.0, 1.0, 0));
        assert!(map.observe(id, &obs(1.2, 2.0, 2.8, 1.0, 2)));
        assert!(map.observe(id, &obs(1.1, 2.3, 3.0, 2.0, 4)));
        assert_eq!(map.len(), 1);
        let l = map.get(id).unwrap();
        assert_eq!(l.observations(), 3);
        let mean = Point3::new(1.1, 2.15, 2.95);
        assert!((l.position() - mean).norm() < 1e-12);
        // a loop closure moves the map: the mean moves with it
        let moved = Pose3::new(Vector3::new(0.5, -1.0, 2.0), Vector3::new(0.1, 0.7, -0.2));
        map.transform(&moved);
        let l = map.get(id).unwrap();
        assert!((l.position() - moved * mean).norm() < 1e-12);
    }

    #[test]
    fn landmarks_leave_after_the_window_and_beyond_the_cap() {
        let mut map = LocalMap::new();
        let with = |d: u64, frame| Observation {
            descriptor: Some([d; 4]),
            ..obs(0.0, 0.0, 1.0, 1.0, frame)
        };
        let old = map.insert(&with(1, 0));
        let kept = map.insert(&with(2, 0));
        let newer = map.insert(&with(3, 10));
        map.touch(kept, Some([5; 4]), 30);
        map.prune(35, 35, 10);
        assert!(map.get(old).is_none());
        assert!(!map.observe(old, &obs(0.0, 0.0, 1.0, 1.0, 36)));
        assert_eq!(map.get(kept).unwrap().descriptor(), Some(&[5; 4]));
        map.prune(35, 35, 1);
        assert!(
            map.get(newer).is_none(),
            "the least recently seen leaves first"
        );
        assert!(map.get(kept).is_some());
    }

    /// 300 points with random descriptors seen by a camera moving forward over 6 key frames;
    /// tracking matched the even points and missed the odd ones, whose observations must
    /// merge into their landmarks rather than duplicate them; one new point per frame.
    #[test]
    fn a_synthetic_scene_seen_repeatedly_has_no_duplicates_and_mean_positions() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let k = Intrinsics::from_array([500.0, 500.0, 320.0, 240.0], 640, 480);
        let points: Vec<(Point3<f64>, Descriptor)> = (0..300)
            .map(|_| {
                let p = Point3::new(
                    rng.gen_range(-1.5..1.5),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(5.0..10.0),
                );
                (p, [rng.gen(), rng.gen(), rng.gen(), rng.gen()])
            })
            .collect();
        let merge = MergeConfig {
            radius_px: 3.0,
            max_distance: 64,
        };
        let mut map = LocalMap::new();
        let mut ids: Vec<Option<u64>> = vec![None; points.len()];
        let mut observed: Vec<Vec<Observation>> = vec![Vec::new(); points.len()];
        for frame in 0..6 {
            let world_from_camera =
                Pose3::translation(0.05 * frame as f64, 0.0, 0.2 * frame as f64);
            let camera_from_world = world_from_camera.inverse();
            let seen: Vec<Seen> = points
                .iter()
                .enumerate()
                .map(|(i, (p, d))| {
                    let c = camera_from_world * p;
                    let pixel = k.to_pixel(&Point2::new(c.x / c.z, c.y / c.z));
                    let mut descriptor = *d;
                    descriptor[(i + frame) % 4] ^= 0b1011 << (frame * 3 % 60);
                    let o = Observation {
                        world: p + Vector3::new(rng.gen(), rng.gen(), rng.gen()) * 0.01,
                        weight: 1.0 / (1.0 + c.z * c.z),
                        descriptor: Some(descriptor),
                        frame,
                    };
                    observed[i].push(o);
                    let landmark = ids[i].filter(|_| i % 2 == 0);
                    Seen {
                        observation: o,
                        pixel,
                        landmark,
                    }
                })
                .collect();
            let new_point = Seen {
                observation: Observation {
                    world: Point3::new(0.0, 0.0, 3.0),
                    weight: 1.0,
                    descriptor: Some([rng.gen(), rng.gen(), rng.gen(), rng.gen()]),
                    frame,
                },
                pixel: Point2::new(320.0, 240.0),
                landmark: None,
            };
            let out = map.add_keyframe(
                &[seen, vec![new_point]].concat(),
                &camera_from_world,
                &k,
                &merge,
            );
            for (i, id) in out.iter().take(points.len()).enumerate() {
                assert!(
                    ids[i].is_none_or(|old| old == *id),
                    "point {i} frame {frame}"
                );
                ids[i] = Some(*id);
            }
        }
        assert_eq!(
            map.len(),
            points.len() + 6,
            "one landmark per point, plus the new ones"
        );
        for (id, obs) in ids.iter().zip(&observed) {
            let l = map.get(id.unwrap()).unwrap();
            assert_eq!(l.observations(), 6);
            let w: f64 = obs.iter().map(|o| o.weight).sum();
            let mean: Vector3<f64> = obs
                .iter()
                .map(|o| o.world.coords * o.weight)
                .sum::<Vector3<f64>>()
                / w;
            assert!((l.position().coords - mean).norm() < 1e-12);
        }
    }

    #[test]
    fn bad_ranges_are_rejected() {
        let bad = LocalMapConfig {
            search_radius_px: f64::NAN,
            ..LocalMapConfig::default()
        };
        assert!(bad.validate().is_err());
        let bad = LocalMapConfig {
            max_landmarks: 0,
            ..LocalMapConfig::default()
        };
        assert!(bad.validate().is_err());
        assert!(LocalMapConfig::default().validate().is_ok());
    }
}
