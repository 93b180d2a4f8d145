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

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use slamkit_vision::Descriptor;

use crate::error::VoError;

/// Local map settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LocalMapConfig {
    /// Features not seen in the last this many frames leave the map \[frames\].
    pub window_frames: usize,
    /// Every this many tracked frames is a key frame whose observations enter the map.
    pub keyframe_every: usize,
}

impl Default for LocalMapConfig {
    fn default() -> Self {
        Self {
            window_frames: 35,
            keyframe_every: 2,
        }
    }
}

impl LocalMapConfig {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`VoError::InvalidConfig`] for a zero window or key-frame spacing.
    pub fn validate(&self) -> Result<(), VoError> {
        if self.window_frames == 0 {
            return Err(VoError::config("local_map.window_frames", 0, "must be > 0"));
        }
        if self.keyframe_every == 0 {
            return Err(VoError::config(
                "local_map.keyframe_every",
                0,
                "must be > 0",
            ));
        }
        Ok(())
    }
}

/// One map feature.
#[derive(Debug, Clone, PartialEq)]
pub struct Landmark {
    sum_world: Vector3<f64>,
    count: u32,
    last_seen: usize,
    descriptor: Option<Descriptor>,
}

impl Landmark {
    /// Mean of the observed world positions \[m\].
    pub fn position(&self) -> Point3<f64> {
        Point3::from(self.sum_world / f64::from(self.count.max(1)))
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

    /// Adds a new landmark seen at `world` in `frame`; returns its id.
    pub fn insert(
        &mut self,
        world: Point3<f64>,
        descriptor: Option<Descriptor>,
        frame: usize,
    ) -> u64 {
        let id = self.next_id;
        self.next_id += 1;
        self.landmarks.insert(
            id,
            Landmark {
                sum_world: world.coords,
                count: 1,
                last_seen: frame,
                descriptor,
            },
        );
        id
    }

    /// Adds an observation of landmark `id` (merged into its mean); false when `id` left the
    /// map.
    pub fn observe(
        &mut self,
        id: u64,
        world: Point3<f64>,
        descriptor: Option<Descriptor>,
        frame: usize,
    ) -> bool {
        let Some(l) = self.landmarks.get_mut(&id) else {
            return false;
        };
        l.sum_world += world.coords;
        l.count += 1;
        l.last_seen = l.last_seen.max(frame);
        if descriptor.is_some() {
            l.descriptor = descriptor;
        }
        true
    }

    /// Marks landmark `id` as seen in `frame` without adding an observation.
    pub fn touch(&mut self, id: u64, frame: usize) {
        if let Some(l) = self.landmarks.get_mut(&id) {
            l.last_seen = l.last_seen.max(frame);
        }
    }

    /// Removes the landmarks not seen within `window_frames` of `frame`.
    pub fn prune(&mut self, frame: usize, window_frames: usize) {
        self.landmarks
            .retain(|_, l| frame.saturating_sub(l.last_seen) < window_frames);
    }

    /// Ids and descriptors of the landmarks that have one, in id order.
    pub fn descriptors(&self) -> (Vec<u64>, Vec<Descriptor>) {
        let mut v: Vec<(u64, Descriptor)> = self
            .landmarks
            .iter()
            .filter_map(|(&id, l)| l.descriptor.map(|d| (id, d)))
            .collect();
        v.sort_unstable_by_key(|(id, _)| *id);
        v.into_iter().unzip()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeated_observations_merge_into_their_mean() {
        let mut map = LocalMap::new();
        let id = map.insert(Point3::new(1.0, 2.0, 3.0), None, 0);
        assert!(map.observe(id, Point3::new(1.2, 2.0, 2.8), None, 2));
        assert!(map.observe(id, Point3::new(1.1, 2.3, 3.0), None, 4));
        assert_eq!(map.len(), 1);
        let l = map.get(id).unwrap();
        assert_eq!(l.observations(), 3);
        assert!((l.position() - Point3::new(1.1, 2.1, 2.933_333_333_333_333)).norm() < 1e-12);
    }

    #[test]
    fn landmarks_leave_after_the_window() {
        let mut map = LocalMap::new();
        let old = map.insert(Point3::origin(), Some([1; 4]), 0);
        let kept = map.insert(Point3::origin(), Some([2; 4]), 0);
        map.touch(kept, 30);
        map.prune(35, 35);
        assert!(map.get(old).is_none());
        assert!(map.get(kept).is_some());
        assert!(!map.observe(old, Point3::origin(), None, 36));
        assert_eq!(map.descriptors(), (vec![kept], vec![[2; 4]]));
    }
}
