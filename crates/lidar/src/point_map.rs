//! The map ICP-SLAM matches against: the points of keyframe scans in the world frame, thinned
//! to one point per voxel and indexed in a uniform grid ([`GridIndex`]), each with the surface normal estimated in
//! its own scan.
//!
//! Two modes, as in the literature: a sliding window of the most recent keyframes (a local
//! submap, like KISS-ICP's local map or Cartographer's submaps, which keeps drift from an old
//! pass out of the current match), or every keyframe ever inserted (MRPT icp-slam's global point
//! map, which re-anchors the robot on its old map when it comes back with little drift).

use crate::cloud::{voxel_key, VoxelMap};
use crate::nn::GridIndex;
use nalgebra::{Point2, Vector2};
use slamkit_core::Pose2;
use std::collections::VecDeque;

/// Side of the nearest-neighbour grid's cells in map voxels: with one point per voxel a cell
/// holds a few points of a wall, and a query near a wall reads about nine cells.
const GRID_CELL_VOXELS: f64 = 2.0;

/// A scan inserted into the map.
#[derive(Debug, Clone, PartialEq)]
pub struct Keyframe {
    /// Pose of the robot base when the scan was taken.
    pub world_from_base: Pose2,
    /// Scan points in the base frame.
    pub points: Vec<Point2<f64>>,
    /// Unit normal of each point in the base frame, where the scan shows a clear surface.
    pub normals: Vec<Option<Vector2<f64>>>,
}

/// Keyframe points in the world frame, voxel-thinned and indexed.
pub struct KeyframeMap {
    voxel_m: f64,
    max_keyframes: usize,
    window: VecDeque<Keyframe>,
    /// The id of each keyframe in `window`: the order of insertion from 0, unless given
    /// ([`KeyframeMap::insert_with_id`]).
    ids: VecDeque<usize>,
    voxels: VoxelMap<usize>,
    points: Vec<Point2<f64>>,
    normals: Vec<Option<Vector2<f64>>>,
    index: GridIndex,
    keyframes_inserted: usize,
}

impl KeyframeMap {
    /// An empty map with voxels of side `voxel_m` holding the last `max_keyframes` keyframes
    /// (0: all of them).
    pub fn new(voxel_m: f64, max_keyframes: usize) -> Self {
        Self {
            voxel_m,
            max_keyframes,
            window: VecDeque::new(),
            ids: VecDeque::new(),
            voxels: VoxelMap::default(),
            points: Vec::new(),
            normals: Vec::new(),
            index: GridIndex::new(Vec::new(), None, voxel_m * GRID_CELL_VOXELS),
            keyframes_inserted: 0,
        }
    }

    /// Adds a keyframe and re-indexes the map.
    pub fn insert(&mut self, keyframe: Keyframe) {
        self.extend(std::iter::once(keyframe));
    }

    /// Adds keyframes in order and re-indexes the map once.
    pub fn extend(&mut self, keyframes: impl IntoIterator<Item = Keyframe>) {
        let first = self.keyframes_inserted;
        self.extend_with_ids(
            keyframes
                .into_iter()
                .enumerate()
                .map(|(i, kf)| (first + i, kf)),
        );
    }

    /// Adds `keyframe` known as `id` (what [`KeyframeMap::relocate`] asks new poses for), e.g.
    /// an old keyframe of a loaded map near where the robot resumes mapping.
    pub fn insert_with_id(&mut self, id: usize, keyframe: Keyframe) {
        self.extend_with_ids(std::iter::once((id, keyframe)));
    }

    /// Adds `(id, keyframe)` pairs in order and re-indexes the map once.
    pub fn extend_with_ids(&mut self, keyframes: impl IntoIterator<Item = (usize, Keyframe)>) {
        for (id, keyframe) in keyframes {
            self.keyframes_inserted += 1;
            if self.max_keyframes == 0 {
                self.add_points(&keyframe);
            }
            self.window.push_back(keyframe);
            self.ids.push_back(id);
        }
        if self.max_keyframes == 0 {
            self.reindex();
        } else {
            while self.window.len() > self.max_keyframes {
                self.window.pop_front();
                self.ids.pop_front();
            }
            self.rebuild();
        }
    }

    /// Moves the keyframes held in the map to new poses and rebuilds it: `pose_of(id)` is the
    /// new pose of the keyframe with that id (by default the order of insertion from 0), or
    /// `None` to keep its pose. Used after a pose-graph optimisation has corrected the
    /// keyframes.
    pub fn relocate(&mut self, pose_of: impl Fn(usize) -> Option<Pose2>) {
        for (id, kf) in self.ids.iter().zip(self.window.iter_mut()) {
            if let Some(pose) = pose_of(*id) {
                kf.world_from_base = pose;
            }
        }
        self.rebuild();
    }

    /// Re-thins and re-indexes the held keyframes, newest first: where keyframes overlap, the
    /// most recent view of a wall wins.
    fn rebuild(&mut self) {
        self.voxels.clear();
        self.points.clear();
        self.normals.clear();
        let window = std::mem::take(&mut self.window);
        if self.max_keyframes == 0 {
            // A global map keeps its voxels for the keyframes added later.
            for kf in window.iter().rev() {
                self.add_points(kf);
            }
        } else {
            thin_keyframes(
                window.iter().rev(),
                self.voxel_m,
                &mut self.points,
                &mut self.normals,
            );
        }
        self.window = window;
        self.reindex();
    }

    fn reindex(&mut self) {
        self.index = GridIndex::new(
            self.points.clone(),
            Some(self.normals.clone()),
            self.voxel_m * GRID_CELL_VOXELS,
        );
    }

    /// Adds the keyframe's points whose voxel is still empty.
    fn add_points(&mut self, kf: &Keyframe) {
        add_keyframe_points(
            kf,
            self.voxel_m,
            &mut self.voxels,
            &mut self.points,
            &mut self.normals,
        );
    }

    /// The indexed map points (world frame) with their normals.
    pub fn index(&self) -> &GridIndex {
        &self.index
    }

    /// The map points in the world frame.
    pub fn points(&self) -> &[Point2<f64>] {
        &self.points
    }

    /// Number of keyframes inserted since the start (including those out of the window).
    pub fn keyframes_inserted(&self) -> usize {
        self.keyframes_inserted
    }

    /// True when the keyframe known as `id` is in the map.
    pub fn holds(&self, id: usize) -> bool {
        self.ids.contains(&id)
    }

    /// True before the first keyframe.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// Adds the points of `kf` (world frame) whose voxel of side `voxel_m` is not in `voxels` yet,
/// with their normals turned into the world frame.
fn add_keyframe_points(
    kf: &Keyframe,
    voxel_m: f64,
    voxels: &mut VoxelMap<usize>,
    points: &mut Vec<Point2<f64>>,
    normals: &mut Vec<Option<Vector2<f64>>>,
) {
    for (p, n) in kf.points.iter().zip(&kf.normals) {
        let world = kf.world_from_base * p;
        let key = voxel_key(&world, voxel_m);
        if voxels.contains_key(&key) {
            continue;
        }
        voxels.insert(key, points.len());
        points.push(world);
        normals.push(n.map(|n| kf.world_from_base.rotation * n));
    }
}

/// Voxel sets spanning at most this many voxels are a bitmap (a few megabytes at most); wider
/// ones are hashed.
const MAX_BITMAP_VOXELS: i128 = 1 << 25;

/// The world points of `keyframes`, in order, whose voxel of side `voxel_m` is still empty,
/// appended with their normals turned into the world frame: the points
/// [`add_keyframe_points`] keeps, keyframe after keyframe from empty voxels, in the same order.
/// The voxels are marked in a bitmap over the rectangle the points span rather than hashed
/// (hashing was a twentieth of ICP-SLAM's time); a very wide rectangle falls back to hashing.
fn thin_keyframes<'a>(
    keyframes: impl Iterator<Item = &'a Keyframe>,
    voxel_m: f64,
    points: &mut Vec<Point2<f64>>,
    normals: &mut Vec<Option<Vector2<f64>>>,
) {
    let keyframes: Vec<&Keyframe> = keyframes.collect();
    let mut world = Vec::with_capacity(keyframes.iter().map(|kf| kf.points.len()).sum());
    for kf in keyframes {
        for (p, n) in kf.points.iter().zip(&kf.normals) {
            let point = kf.world_from_base * p;
            let normal = n.map(|n| kf.world_from_base.rotation * n);
            world.push((point, normal, voxel_key(&point, voxel_m)));
        }
    }
    let (lo, hi) = world.iter().fold(
        ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN)),
        |(lo, hi), &(_, _, (i, j))| ((lo.0.min(i), lo.1.min(j)), (hi.0.max(i), hi.1.max(j))),
    );
    let width = i128::from(hi.0) - i128::from(lo.0) + 1;
    let height = i128::from(hi.1) - i128::from(lo.1) + 1;
    let mut keep = |(p, n, _): (Point2<f64>, Option<Vector2<f64>>, (i64, i64))| {
        points.push(p);
        normals.push(n);
    };
    if world.is_empty() || width * height > MAX_BITMAP_VOXELS {
        let mut voxels = VoxelMap::default();
        for item in world {
            if voxels.insert(item.2, ()).is_none() {
                keep(item);
            }
        }
        return;
    }
    // The rectangle holds at most MAX_BITMAP_VOXELS voxels, so these fit in usize.
    let (width, cells) = (width as usize, (width * height) as usize);
    let mut marked = vec![0u64; cells.div_ceil(64)];
    for item in world {
        let (i, j) = item.2;
        let at = (j.abs_diff(lo.1) as usize) * width + i.abs_diff(lo.0) as usize;
        let Some(word) = marked.get_mut(at / 64) else {
            continue;
        };
        let bit = 1u64 << (at % 64);
        if *word & bit == 0 {
            *word |= bit;
            keep(item);
        }
    }
}

/// The points of `keyframes`, in order, thinned and indexed as a [`KeyframeMap`] holding all of
/// them would (same points, same order), without copying the keyframes: a fixed map to match
/// against, e.g. a loop-closure submap.
pub fn index_keyframes(keyframes: &[Keyframe], voxel_m: f64) -> GridIndex {
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    thin_keyframes(keyframes.iter(), voxel_m, &mut points, &mut normals);
    GridIndex::new(points, Some(normals), voxel_m * GRID_CELL_VOXELS)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::NearestNeighbours;
    use std::f64::consts::FRAC_PI_2;

    fn kf(x: f64, pts: &[(f64, f64)]) -> Keyframe {
        Keyframe {
            world_from_base: Pose2::new(Vector2::new(x, 0.0), FRAC_PI_2),
            points: pts.iter().map(|&(a, b)| Point2::new(a, b)).collect(),
            normals: vec![Some(Vector2::new(1.0, 0.0)); pts.len()],
        }
    }

    #[test]
    fn window_keeps_recent_keyframes_in_world_frame() {
        let mut map = KeyframeMap::new(0.05, 2);
        map.insert(kf(0.0, &[(1.0, 0.0)]));
        assert!((map.points()[0] - Point2::new(0.0, 1.0)).norm() < 1e-12);
        let n = map.index().normal(0).unwrap();
        assert!((n - Vector2::new(0.0, 1.0)).norm() < 1e-12);
        map.insert(kf(10.0, &[(1.0, 0.0)]));
        map.insert(kf(20.0, &[(1.0, 0.0), (1.01, 0.0)]));
        assert_eq!(map.keyframes_inserted(), 3);
        // keyframe 0 fell out of the window; the two points of the last share a voxel
        assert_eq!(map.points().len(), 2);
        assert!((map.points()[0] - Point2::new(20.0, 1.0)).norm() < 1e-12);
    }

    #[test]
    fn fixed_index_equals_a_global_map() {
        let kfs: Vec<Keyframe> = (0..4)
            .map(|i| kf(i as f64 * 0.02, &[(1.0, 0.0), (1.0, 0.5), (2.0, -1.0)]))
            .collect();
        let mut map = KeyframeMap::new(0.05, 0);
        map.extend(kfs.iter().cloned());
        let index = index_keyframes(&kfs, 0.05);
        assert_eq!(index.points(), map.points());
        assert!(index.points().len() < 12, "nearby keyframes share voxels");
        for i in 0..index.len() {
            assert_eq!(index.normal(i), map.index().normal(i));
        }
    }

    #[test]
    fn bitmap_thinning_equals_hashing() {
        // Scattered keyframes (bitmap), one far away (hash fallback), and NaN points.
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng % 10_000) as f64 / 1000.0 - 5.0
        };
        let mut kfs: Vec<Keyframe> = (0..6)
            .map(|i| {
                let pts: Vec<(f64, f64)> = (0..300).map(|_| (next(), next() * 0.3)).collect();
                kf(i as f64 * 0.37, &pts)
            })
            .collect();
        kfs[2].points[5] = Point2::new(f64::NAN, 1.0);
        for far in [false, true] {
            if far {
                kfs[4].world_from_base = Pose2::new(Vector2::new(1e6, -2e6), 0.3);
            }
            for voxel in [0.05, 0.1, 0.5] {
                let (mut points, mut normals) = (Vec::new(), Vec::new());
                thin_keyframes(kfs.iter(), voxel, &mut points, &mut normals);
                let (mut voxels, mut hp, mut hn) = (VoxelMap::default(), Vec::new(), Vec::new());
                for k in &kfs {
                    add_keyframe_points(k, voxel, &mut voxels, &mut hp, &mut hn);
                }
                assert!(points.len() < 1800, "thinned");
                assert_eq!(points.len(), hp.len());
                for (a, b) in points.iter().zip(&hp) {
                    assert!(a == b || (a.x.is_nan() && b.x.is_nan()));
                }
                assert_eq!(normals, hn);
            }
        }
        let (mut points, mut normals) = (Vec::new(), Vec::new());
        thin_keyframes([].iter(), 0.05, &mut points, &mut normals);
        assert!(points.is_empty());
    }

    #[test]
    fn global_map_keeps_everything() {
        let mut map = KeyframeMap::new(0.05, 0);
        assert!(map.is_empty());
        for i in 0..5 {
            map.insert(kf(i as f64, &[(1.0, 0.0)]));
        }
        assert_eq!(map.points().len(), 5);
        assert_eq!(map.index().len(), 5);
        // shift keyframe 3 by 1 m along y: its world point moves with it
        map.relocate(|i| (i == 3).then(|| Pose2::new(Vector2::new(3.0, 1.0), FRAC_PI_2)));
        assert_eq!(map.points().len(), 5);
        assert!(map
            .points()
            .iter()
            .any(|p| (p - Point2::new(3.0, 2.0)).norm() < 1e-12));
        assert!(!map
            .points()
            .iter()
            .any(|p| (p - Point2::new(3.0, 1.0)).norm() < 1e-12));
    }
}
