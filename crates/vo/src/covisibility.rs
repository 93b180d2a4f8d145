//! Map points and the covisibility graph of the keyframes (Mur-Artal, Montiel and Tardós,
//! "ORB-SLAM", T-RO 2015, §III: keyframes are connected by the map points they observe in
//! common, weighted by their number).
//!
//! A keyframe's features are its [`PlaceFeatures`] (binary descriptors with 3D points in its
//! camera frame). A feature found again in a later keyframe ([`associate`]: mutual nearest
//! descriptors whose points agree under the odometry's relative pose) observes the same map
//! point; two map points found to be one (a verified loop) are merged, their observations
//! pooled. The covisibility weight of two keyframes is the number of map points both observe.

use std::collections::HashMap;

use nalgebra::Point3;
use slamkit_core::Pose3;
use slamkit_vision::{match_descriptors, Descriptor, MatchConfig};

/// Binary descriptors with the 3D points of their features, index-aligned: what place
/// recognition indexes and loop verification matches.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlaceFeatures {
    /// Feature points in the camera frame \[m\].
    pub points: Vec<Point3<f64>>,
    /// ORB descriptors, `descriptors[i]` for `points[i]`.
    pub descriptors: Vec<Descriptor>,
}

impl PlaceFeatures {
    /// Number of features.
    pub fn len(&self) -> usize {
        self.points.len().min(self.descriptors.len())
    }

    /// True without features.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Feature pairs `(a index, b index)` of the same scene point in two views: mutually nearest
/// descriptors (`matching`) whose points, moved from `b` into `a` by `a_from_b`, land within
/// `tolerance_m + relative_tolerance × depth` of each other.
pub fn associate(
    a: &PlaceFeatures,
    b: &PlaceFeatures,
    a_from_b: &Pose3,
    matching: &MatchConfig,
    (tolerance_m, relative_tolerance): (f64, f64),
) -> Vec<(usize, usize)> {
    match_descriptors(&a.descriptors, &b.descriptors, matching)
        .into_iter()
        .filter_map(|m| {
            let pa = a.points.get(m.query_idx)?;
            let pb = a_from_b * b.points.get(m.train_idx)?;
            let limit = tolerance_m + relative_tolerance * pa.coords.norm();
            ((pa - pb).norm() <= limit).then_some((m.query_idx, m.train_idx))
        })
        .collect()
}

/// Map points, each with the `(keyframe, feature)` observations of it, and the keyframes'
/// features' points.
///
/// ```
/// use slamkit_vo::covisibility::Covisibility;
///
/// let mut graph = Covisibility::default();
/// let a = graph.add_keyframe(3, &[]);
/// // keyframe 1 sees a's features 0 and 2 again as its features 1 and 0
/// let b = graph.add_keyframe(2, &[(a, vec![(0, 1), (2, 0)])]);
/// let c = graph.add_keyframe(2, &[(b, vec![(1, 0)])]);
/// assert_eq!(graph.weight(a, b), 2);
/// assert_eq!(graph.weight(a, c), 1); // a's feature 0 is b's 1 is c's 0
/// assert_eq!(graph.points(), 3 + 0 + 1);
/// ```
#[derive(Debug, Clone, Default)]
pub struct Covisibility {
    /// Per keyframe, per feature: its map point.
    point_of: Vec<Vec<usize>>,
    /// Per map point: its observations; empty once merged into another.
    observations: Vec<Vec<(usize, usize)>>,
    live_points: usize,
}

impl Covisibility {
    /// Keyframes so far.
    pub fn keyframes(&self) -> usize {
        self.point_of.len()
    }

    /// Map points (merged ones counted once).
    pub fn points(&self) -> usize {
        self.live_points
    }

    /// Adds a keyframe of `features` features; `links` pairs `(earlier keyframe feature, this
    /// keyframe's feature)` per earlier keyframe: those features observe the earlier one's map
    /// points (the first link wins for a feature), the others start new map points. Returns
    /// the keyframe's id (0, 1, ...).
    pub fn add_keyframe(
        &mut self,
        features: usize,
        links: &[(usize, Vec<(usize, usize)>)],
    ) -> usize {
        let id = self.point_of.len();
        let mut points: Vec<Option<usize>> = vec![None; features];
        for (other, pairs) in links {
            for &(theirs, mine) in pairs {
                let point = self
                    .point_of
                    .get(*other)
                    .and_then(|p| p.get(theirs))
                    .copied();
                if let (Some(slot @ None), Some(point)) = (points.get_mut(mine), point) {
                    *slot = Some(point);
                }
            }
        }
        let points = points
            .into_iter()
            .enumerate()
            .map(|(feature, p)| {
                let point = p.unwrap_or_else(|| {
                    self.observations.push(Vec::new());
                    self.live_points += 1;
                    self.observations.len() - 1
                });
                if let Some(obs) = self.observations.get_mut(point) {
                    obs.push((id, feature));
                }
                point
            })
            .collect();
        self.point_of.push(points);
        id
    }

    /// Merges the map points of `pairs` `(feature of a, feature of b)`: each of b's points is
    /// folded into a's (a verified loop saw one scene point twice).
    pub fn merge(&mut self, a: usize, b: usize, pairs: &[(usize, usize)]) {
        for &(fa, fb) in pairs {
            let pa = self.point_of.get(a).and_then(|p| p.get(fa)).copied();
            let pb = self.point_of.get(b).and_then(|p| p.get(fb)).copied();
            let (Some(keep), Some(gone)) = (pa, pb) else {
                continue;
            };
            if keep == gone {
                continue;
            }
            let moved = self
                .observations
                .get_mut(gone)
                .map(std::mem::take)
                .unwrap_or_default();
            for &(k, f) in &moved {
                if let Some(slot) = self.point_of.get_mut(k).and_then(|p| p.get_mut(f)) {
                    *slot = keep;
                }
            }
            if let Some(obs) = self.observations.get_mut(keep) {
                obs.extend(moved);
            }
            self.live_points -= 1;
        }
    }

    /// The keyframes sharing map points with `keyframe`, and how many (itself left out).
    pub fn neighbours(&self, keyframe: usize) -> HashMap<usize, usize> {
        let mut weights: HashMap<usize, usize> = HashMap::new();
        let Some(points) = self.point_of.get(keyframe) else {
            return weights;
        };
        let mut seen: Vec<usize> = Vec::new();
        for &p in points {
            seen.clear();
            for &(k, _) in self.observations.get(p).into_iter().flatten() {
                if k != keyframe && !seen.contains(&k) {
                    seen.push(k);
                    *weights.entry(k).or_default() += 1;
                }
            }
        }
        weights
    }

    /// Map points `a` and `b` both observe.
    pub fn weight(&self, a: usize, b: usize) -> usize {
        self.neighbours(a).get(&b).copied().unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn associate_keeps_matches_that_agree_with_the_motion() {
        let a = PlaceFeatures {
            points: vec![Point3::new(0.0, 0.0, 2.0), Point3::new(1.0, 0.0, 3.0)],
            descriptors: vec![[1, 0, 0, 0], [u64::MAX, 7, 7, 7]],
        };
        // b moved 0.5 m forward: its points are 0.5 m nearer; the second is misplaced by 1 m
        let b = PlaceFeatures {
            points: vec![Point3::new(0.0, 0.0, 1.5), Point3::new(1.0, 1.0, 2.5)],
            descriptors: a.descriptors.clone(),
        };
        let a_from_b = Pose3::translation(0.0, 0.0, 0.5);
        let pairs = associate(&a, &b, &a_from_b, &MatchConfig::default(), (0.05, 0.02));
        assert_eq!(pairs, vec![(0, 0)]);
        // without the motion, the first pair is 0.5 m off too
        assert!(associate(
            &a,
            &b,
            &Pose3::identity(),
            &MatchConfig::default(),
            (0.05, 0.02)
        )
        .is_empty());
    }

    #[test]
    fn merging_points_joins_their_keyframes() {
        let mut g = Covisibility::default();
        let a = g.add_keyframe(2, &[]);
        let b = g.add_keyframe(2, &[(a, vec![(0, 0)])]);
        let far = g.add_keyframe(3, &[]);
        assert_eq!((g.weight(a, b), g.weight(a, far)), (1, 0));
        assert_eq!(g.points(), 2 + 1 + 3);
        // a loop: far's features 0 and 1 are a's 1 and b's 0 (= a's 0)
        g.merge(a, far, &[(1, 0)]);
        g.merge(b, far, &[(0, 1)]);
        assert_eq!(g.weight(a, far), 2);
        assert_eq!(g.weight(far, b), 1);
        assert_eq!(g.points(), 4);
        assert_eq!(g.neighbours(far).len(), 2);
        // merging a point with itself or out-of-range features changes nothing
        g.merge(a, b, &[(0, 0), (9, 9)]);
        assert_eq!(g.points(), 4);
    }
}
