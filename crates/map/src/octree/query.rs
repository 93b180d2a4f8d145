//! Queries on the octree: by point, by key, every leaf, and the leaves inside a box.

use super::key::{OctreeKey, TREE_DEPTH, TREE_MAX_VAL};
use super::nodes::{NO_CHILDREN, ROOT};
use super::Octree;
use crate::occupancy_grid::Occupancy;
use nalgebra::Point3;

/// A leaf of the octree: a cube of `2^(16 - depth)` finest voxels per edge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OctreeLeaf {
    /// Key of the cube's lowest finest voxel.
    pub min_key: OctreeKey,
    /// Depth below the root (16: a finest voxel).
    pub depth: u32,
    /// Edge length \[m\].
    pub size_m: f64,
    /// Centre of the cube \[m\].
    pub center_m: Point3<f64>,
    /// Log-odds of the cube.
    pub log_odds: f32,
}

impl Octree {
    /// Log-odds and depth of the deepest node holding `key`; `None` where nothing was observed.
    pub fn search_key(&self, key: OctreeKey) -> Option<(f32, u32)> {
        if !self.pool.exists(ROOT) {
            return None;
        }
        let mut node = ROOT;
        for depth in 0..TREE_DEPTH {
            let first = self.pool.first_child(node);
            if first == NO_CHILDREN {
                return Some((self.pool.value(node), depth));
            }
            let bit = TREE_DEPTH - 1 - depth;
            let index = (0..3).fold(0, |acc, axis| {
                acc | (((key.0[axis] >> bit) & 1) as u32) << axis
            });
            node = first + index;
            if !self.pool.exists(node) {
                return None;
            }
        }
        Some((self.pool.value(node), TREE_DEPTH))
    }

    /// Tri-state of the finest voxel `key`.
    pub fn occupancy_key(&self, key: OctreeKey) -> Occupancy {
        self.search_key(key)
            .map_or(Occupancy::Unknown, |(l, _)| self.classify(l))
    }

    /// Log-odds at `point_m`; `None` where unknown or outside the tree.
    pub fn log_odds_at(&self, point_m: &Point3<f64>) -> Option<f32> {
        self.search_key(self.key_at(point_m)?).map(|(l, _)| l)
    }

    /// Tri-state at `point_m` (unknown outside the tree and for NaN).
    pub fn occupancy_at(&self, point_m: &Point3<f64>) -> Occupancy {
        self.key_at(point_m)
            .map_or(Occupancy::Unknown, |k| self.occupancy_key(k))
    }

    /// Calls `visit` for every leaf, depth first, children in OctoMap's order.
    pub fn for_each_leaf(&self, mut visit: impl FnMut(&OctreeLeaf)) {
        self.leaves_in_keys([0; 3], [u16::MAX; 3], &mut visit);
    }

    /// Calls `visit` for every leaf overlapping the axis-aligned box `[min_m, max_m]`; a leaf
    /// larger than the box is reported whole. Nothing for a NaN or inverted box.
    pub fn for_each_leaf_in_box(
        &self,
        min_m: &Point3<f64>,
        max_m: &Point3<f64>,
        mut visit: impl FnMut(&OctreeLeaf),
    ) {
        let inv = 1.0 / self.config.resolution_m;
        let clamp_key = |c: f64| {
            let s = (c * inv).floor() + f64::from(TREE_MAX_VAL);
            // NaN becomes 0 through `as`; callers compare lo <= hi below.
            s.clamp(0.0, f64::from(u16::MAX)) as u16
        };
        if min_m.iter().chain(max_m.iter()).any(|c| c.is_nan()) {
            return;
        }
        let lo = [min_m.x, min_m.y, min_m.z].map(clamp_key);
        let hi = [max_m.x, max_m.y, max_m.z].map(clamp_key);
        if (0..3).any(|i| lo[i] > hi[i]) {
            return;
        }
        self.leaves_in_keys(lo, hi, &mut visit);
    }

    /// Occupied leaves overlapping the box `[min_m, max_m]`.
    pub fn occupied_in_box(&self, min_m: &Point3<f64>, max_m: &Point3<f64>) -> Vec<OctreeLeaf> {
        let mut out = Vec::new();
        self.for_each_leaf_in_box(min_m, max_m, |leaf| {
            if self.classify(leaf.log_odds) == Occupancy::Occupied {
                out.push(*leaf);
            }
        });
        out
    }

    /// Leaves whose key cube overlaps the key box `[lo, hi]` (inclusive).
    fn leaves_in_keys(&self, lo: [u16; 3], hi: [u16; 3], visit: &mut dyn FnMut(&OctreeLeaf)) {
        if self.pool.exists(ROOT) {
            self.leaves_rec(ROOT, 0, [0; 3], lo, hi, visit);
        }
    }

    fn leaves_rec(
        &self,
        node: u32,
        depth: u32,
        min_key: [u32; 3],
        lo: [u16; 3],
        hi: [u16; 3],
        visit: &mut dyn FnMut(&OctreeLeaf),
    ) {
        let span = 1u32 << (TREE_DEPTH - depth);
        let overlaps =
            (0..3).all(|i| min_key[i] <= u32::from(hi[i]) && min_key[i] + span > u32::from(lo[i]));
        if !overlaps {
            return;
        }
        let first = self.pool.first_child(node);
        if first == NO_CHILDREN {
            let res = self.config.resolution_m;
            let size_m = f64::from(span) * res;
            let corner =
                min_key.map(|k| (f64::from(k) - f64::from(TREE_MAX_VAL)) * res + size_m / 2.0);
            visit(&OctreeLeaf {
                min_key: OctreeKey(min_key.map(|k| k as u16)),
                depth,
                size_m,
                center_m: Point3::new(corner[0], corner[1], corner[2]),
                log_odds: self.pool.value(node),
            });
            return;
        }
        let half = span / 2;
        for index in 0..8u32 {
            let child = first + index;
            if self.pool.exists(child) {
                let key = [0, 1, 2].map(|axis| min_key[axis] + ((index >> axis) & 1) * half);
                self.leaves_rec(child, depth + 1, key, lo, hi, visit);
            }
        }
    }
}
