//! The local map model: rather than only the previous frame, the current frame is matched
//! against the features of the recent key frames (default: the last 35 frames, every second
//! one a key frame), each feature's 3D position the mean of its repeated observations.
//!
//! Averaging `n` observations shrinks a feature's position noise by √n, so the motion of each
//! new frame is measured against steadier points and drift slows; a feature that was missed
//! in a bad frame is still in the map for the next one, so tracking recovers. This is the
//! local map of keyframe-based VO (PTAM, Klein & Murray, ISMAR 2007; ORB-SLAM's local map,
//! Mur-Artal et al., T-RO 2015) without its bundle adjustment: positions are plain means, as
//! the seed's MRPT-based VO kept them.

use std::collections::HashMap;

use nalgebra::{Point2, Point3, Vector3};
use serde::{Deserialize, Serialize};
use slamkit_core::camera::Intrinsics;
use slamkit_core::Pose3;
use slamkit_vision::matching::hamming;
use slamkit_vision::{Descriptor, MatchConfig};

use crate::error::VoError;

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
    /// ORB: a key-frame feature left unmatched is merged into the landmark projecting within
    /// this distance of it with a descriptor within the matching distance, instead of
    /// becoming a new landmark \[px\].
    pub merge_radius_px: f64,
}

impl Default for LocalMapConfig {
    fn default() -> Self {
        Self {
            window_frames: 35,
            keyframe_every: 2,
            max_landmarks: 6000,
            search_radius_px: 15.0,
            recovery_radius_px: 60.0,
            min_window_matches: 50,
            merge_radius_px: 3.0,
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
        Ok(())
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

/// A landmark projected into a camera: its id, pixel and descriptor.
pub type Projected = (u64, Point2<f64>, Descriptor);

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

    /// The landmarks with a descriptor that lie in front of the camera and project inside
    /// its image, in id order.
    pub fn project(&self, camera_from_world: &Pose3, k: &Intrinsics) -> Vec<Projected> {
        let mut out: Vec<Projected> = self
            .landmarks
            .iter()
            .filter_map(|(&id, l)| {
                let p = camera_from_world * l.position();
                if p.z <= 0.0 {
                    return None;
                }
                let px = Point2::new(k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy);
                k.contains(&px).then_some((id, px, l.descriptor?))
            })
            .collect();
        out.sort_unstable_by_key(|(id, _, _)| *id);
        out
    }

    /// Landmarks observed (not only seen) in `frame`.
    fn observed_in(&self, id: u64, frame: usize) -> bool {
        self.landmarks
            .get(&id)
            .is_some_and(|l| l.last_observed == frame)
    }

    /// Merges `o`, a key-frame feature seen at `pixel` that matched no landmark, into the
    /// landmark of `projected` (the map projected into the key frame, indexed by `grid`)
    /// nearest in descriptor within `radius_px` and `max_distance` bits and not yet observed
    /// in this frame; inserts it as a new landmark when there is none. Returns its id.
    pub fn merge_or_insert(
        &mut self,
        o: &Observation,
        pixel: Point2<f64>,
        projected: &[Projected],
        grid: &PixelGrid,
        radius_px: f64,
        max_distance: u32,
    ) -> u64 {
        let Some(d) = o.descriptor else {
            return self.insert(o);
        };
        let nearest = grid
            .near(pixel, radius_px)
            .filter_map(|i| projected.get(i))
            .filter(|(id, px, _)| {
                (px - pixel).norm_squared() <= radius_px * radius_px
                    && !self.observed_in(*id, o.frame)
            })
            .map(|(id, _, ld)| (hamming(&d, ld), *id))
            .filter(|&(dist, _)| dist <= max_distance)
            .min();
        match nearest {
            Some((_, id)) if self.observe(id, o) => id,
            _ => self.insert(o),
        }
    }
}

/// Indices of pixels bucketed in square cells, for radius queries.
#[derive(Debug, Clone)]
pub struct PixelGrid {
    cell_px: f64,
    cols: usize,
    rows: usize,
    cells: Vec<Vec<usize>>,
}

impl PixelGrid {
    /// Buckets the `pixels` of a `width` × `height` image (indices into the slice; pixels
    /// outside the image are left out) in cells of `cell_px` (> 0).
    pub fn new(
        pixels: impl IntoIterator<Item = (usize, Point2<f64>)>,
        width: usize,
        height: usize,
        cell_px: f64,
    ) -> Self {
        let cell_px = cell_px.max(1.0);
        let cols = (width as f64 / cell_px).ceil().max(1.0) as usize;
        let rows = (height as f64 / cell_px).ceil().max(1.0) as usize;
        let mut cells = vec![Vec::new(); cols * rows];
        for (i, p) in pixels {
            if let Some(c) = Self::cell_of(cell_px, cols, rows, p) {
                if let Some(v) = cells.get_mut(c.1 * cols + c.0) {
                    v.push(i);
                }
            }
        }
        Self {
            cell_px,
            cols,
            rows,
            cells,
        }
    }

    fn cell_of(cell_px: f64, cols: usize, rows: usize, p: Point2<f64>) -> Option<(usize, usize)> {
        let (cx, cy) = ((p.x / cell_px).floor(), (p.y / cell_px).floor());
        (cx >= 0.0 && cy >= 0.0 && (cx as usize) < cols && (cy as usize) < rows)
            .then_some((cx as usize, cy as usize))
    }

    /// Indices in the cells overlapping the square of half-side `radius_px` around `p` (a
    /// superset of those within the radius).
    pub fn near(&self, p: Point2<f64>, radius_px: f64) -> impl Iterator<Item = usize> + '_ {
        let span = |v: f64, n: usize| {
            let lo = ((v - radius_px) / self.cell_px).floor().max(0.0) as usize;
            let hi = ((v + radius_px) / self.cell_px).floor();
            let hi = if hi < 0.0 {
                None
            } else {
                Some((hi as usize).min(n - 1))
            };
            hi.filter(|&h| lo <= h).map(|h| lo..=h)
        };
        let xs = span(p.x, self.cols);
        let ys = span(p.y, self.rows);
        let ranges = xs.zip(ys);
        ranges.into_iter().flat_map(move |(xs, ys)| {
            ys.flat_map(move |y| xs.clone().map(move |x| y * self.cols + x))
                .filter_map(|c| self.cells.get(c))
                .flatten()
                .copied()
        })
    }
}

/// Matches landmarks projected into the predicted camera to the features (`pixels`,
/// `descriptors`, bucketed in `grid`) within `radius_px` of each projection: the nearest
/// descriptor, kept when within `config.max_distance`, passing Lowe's ratio test against the
/// second nearest in the window and (with `config.cross_check`) mutually nearest among the
/// windows that hold the feature. Returns (index into `projected`, feature index) pairs.
pub fn match_in_windows(
    projected: &[Projected],
    pixels: &[Point2<f64>],
    descriptors: &[Descriptor],
    grid: &PixelGrid,
    radius_px: f64,
    config: &MatchConfig,
) -> Vec<(usize, usize)> {
    let r2 = radius_px * radius_px;
    let mut feature_best = vec![(u32::MAX, usize::MAX); pixels.len()];
    let mut rows = Vec::with_capacity(projected.len());
    for (li, (_, lpx, ld)) in projected.iter().enumerate() {
        let (mut best, mut second, mut best_f) = (u32::MAX, u32::MAX, usize::MAX);
        for fi in grid.near(*lpx, radius_px) {
            let (Some(px), Some(fd), Some(fb)) = (
                pixels.get(fi),
                descriptors.get(fi),
                feature_best.get_mut(fi),
            ) else {
                continue;
            };
            if (px - lpx).norm_squared() > r2 {
                continue;
            }
            let d = hamming(ld, fd);
            if d < best {
                (second, best, best_f) = (best, d, fi);
            } else if d < second {
                second = d;
            }
            if d < fb.0 {
                *fb = (d, li);
            }
        }
        rows.push((best, second, best_f));
    }
    rows.into_iter()
        .enumerate()
        .filter(|&(li, (best, second, fi))| {
            let ratio_ok = config.ratio >= 1.0
                || second == u32::MAX
                || (best as f32) < config.ratio * second as f32;
            let cross_ok = !config.cross_check || feature_best.get(fi).is_some_and(|b| b.1 == li);
            best <= config.max_distance && ratio_ok && cross_ok
        })
        .map(|(li, (_, _, fi))| (li, fi))
        .collect()
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
