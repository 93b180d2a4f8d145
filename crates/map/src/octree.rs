//! 3D occupancy octree with OctoMap's semantics.
//!
//! A. Hornung, K. M. Wurm, M. Bennewitz, C. Stachniss, W. Burgard, "OctoMap: an efficient
//! probabilistic 3D mapping framework based on octrees", Autonomous Robots 34(3), 2013. Each
//! voxel holds the log-odds that it is occupied; a point cloud taken from a sensor origin adds
//! `l_hit` to the voxel of every end point and `l_miss` to every voxel a ray crosses, each voxel
//! once per cloud and a hit winning over a miss (OctoMap's `computeUpdate`), the sum clamped to
//! `[l_min, l_max]` (section 3.3). A voxel is occupied when its probability is at least the
//! occupancy threshold. Inner nodes hold the largest log-odds of their children, and a node
//! whose eight children are equal leaves is pruned into one leaf (section 3.4), so large free or
//! occupied regions cost one node.
//!
//! Insertion differs from OctoMap's in *how*, not *what*: the voxels of all rays are marked in
//! 8 × 8 × 8 chunks, visited in Morton order and applied in one depth-first pass, so each inner
//! node is updated and pruned once per cloud instead of once per voxel; the resulting tree is
//! the one OctoMap builds ([`bt`] writes it in OctoMap's `.bt` format, and
//! `scripts/bench_octree_vs_octomap.py` checks the agreement with the `pyoctomap` binding).
//!
//! Frames: the octree lives in the world frame of the clouds given to it; keys and the tree
//! layout are OctoMap's (depth 16, key = floor(x / resolution) + 2^15).

pub mod bt;
pub mod key;
mod marks;
mod nodes;
mod query;

use crate::error::MapError;
use crate::occupancy_grid::{log_odds_from_probability, Occupancy};
use key::{ray_keys, OctreeKey};
use marks::Marks;
use nalgebra::Point3;
use nodes::{NodePool, NO_CHILDREN, ROOT};
use serde::{Deserialize, Serialize};

pub use query::OctreeLeaf;

/// Parameters of the octree and its inverse sensor model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OctreeConfig {
    /// Edge of the smallest voxel \[m\].
    pub resolution_m: f64,
    /// Probability that the voxel of a ray's end point is occupied \[0..1\].
    pub p_hit: f64,
    /// Probability that a voxel a ray passed through is occupied \[0..1\].
    pub p_miss: f64,
    /// Lower clamp on a voxel's probability \[0..1\].
    pub p_min: f64,
    /// Upper clamp on a voxel's probability \[0..1\].
    pub p_max: f64,
    /// A voxel with at least this probability is occupied \[0..1\].
    pub occupancy_threshold: f64,
    /// Rays longer than this clear free space up to it and mark no hit; `None`: no limit \[m\].
    pub max_range_m: Option<f64>,
}

impl Default for OctreeConfig {
    fn default() -> Self {
        Self {
            resolution_m: 0.05,
            p_hit: 0.85,
            p_miss: 0.4,
            p_min: 0.12,
            p_max: 0.97,
            occupancy_threshold: 0.5,
            max_range_m: None,
        }
    }
}

impl OctreeConfig {
    /// Checks every value; the octree refuses a configuration that fails.
    pub fn validate(&self) -> Result<(), MapError> {
        let bad = |message: &str| {
            Err(MapError::InvalidConfig {
                message: message.to_string(),
            })
        };
        if !(self.resolution_m.is_finite() && self.resolution_m >= 1e-4 && self.resolution_m <= 1e3)
        {
            return bad("resolution_m must lie in [1e-4, 1e3]");
        }
        let ordered = 0.0 < self.p_min
            && self.p_min <= self.p_miss
            && self.p_miss < 0.5
            && 0.5 < self.p_hit
            && self.p_hit <= self.p_max
            && self.p_max < 1.0;
        if !ordered {
            return bad("need 0 < p_min <= p_miss < 0.5 < p_hit <= p_max < 1");
        }
        if !(self.occupancy_threshold > 0.0 && self.occupancy_threshold < 1.0) {
            return bad("occupancy_threshold must lie in (0, 1)");
        }
        if self
            .max_range_m
            .is_some_and(|r| !(r.is_finite() && r > 0.0))
        {
            return bad("max_range_m must be positive and finite");
        }
        Ok(())
    }
}

/// What happened to the points of one inserted cloud.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct OctreeInsertStats {
    /// Points whose voxel was marked occupied.
    pub hits: usize,
    /// Points beyond the maximum range, whose rays only cleared free space.
    pub cleared: usize,
    /// Points ignored: NaN or infinite, or outside the tree.
    pub ignored: usize,
    /// Distinct voxels updated.
    pub voxels_updated: usize,
}

/// Size of the tree.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct OctreeStats {
    /// Nodes that exist, inner and leaf.
    pub nodes: usize,
    /// Leaves (at any depth).
    pub leaves: usize,
    /// Leaves classified occupied.
    pub occupied_leaves: usize,
    /// Leaves classified free.
    pub free_leaves: usize,
    /// Bytes of node storage.
    pub bytes: usize,
}

/// OctoMap-style occupancy octree; see the module documentation.
#[derive(Debug, Clone)]
pub struct Octree {
    config: OctreeConfig,
    l_hit: f32,
    l_miss: f32,
    l_min: f32,
    l_max: f32,
    l_occupied: f32,
    pool: NodePool,
    marks: Marks,
    updates: Vec<u64>,
}

impl Octree {
    /// An empty octree.
    pub fn new(config: OctreeConfig) -> Result<Self, MapError> {
        config.validate()?;
        Ok(Self {
            l_hit: log_odds_from_probability(config.p_hit),
            l_miss: log_odds_from_probability(config.p_miss),
            l_min: log_odds_from_probability(config.p_min),
            l_max: log_odds_from_probability(config.p_max),
            l_occupied: log_odds_from_probability(config.occupancy_threshold),
            config,
            pool: NodePool::new(f32::NAN),
            marks: Marks::default(),
            updates: Vec::new(),
        })
    }

    /// The configuration the octree was built with.
    pub fn config(&self) -> &OctreeConfig {
        &self.config
    }

    /// Edge of the smallest voxel \[m\].
    pub fn resolution_m(&self) -> f64 {
        self.config.resolution_m
    }

    /// Clamp range of the log-odds, `(l_min, l_max)`.
    pub fn log_odds_limits(&self) -> (f32, f32) {
        (self.l_min, self.l_max)
    }

    /// Classifies a log-odds value with the occupancy threshold (at the threshold: occupied, as
    /// OctoMap's `isNodeOccupied`).
    pub fn classify(&self, log_odds: f32) -> Occupancy {
        if log_odds >= self.l_occupied {
            Occupancy::Occupied
        } else {
            Occupancy::Free
        }
    }

    /// Key of the finest voxel holding `point_m`; `None` for NaN or points outside the tree.
    pub fn key_at(&self, point_m: &Point3<f64>) -> Option<OctreeKey> {
        let inv = 1.0 / self.config.resolution_m;
        Some(OctreeKey([
            key::coord_to_key(point_m.x, inv)?,
            key::coord_to_key(point_m.y, inv)?,
            key::coord_to_key(point_m.z, inv)?,
        ]))
    }

    /// Centre of the finest voxel `key` \[m\].
    pub fn key_center_m(&self, key: OctreeKey) -> Point3<f64> {
        let r = self.config.resolution_m;
        let [x, y, z] = key.0.map(|k| key::key_to_coord(k, r));
        Point3::new(x, y, z)
    }

    /// Inserts a cloud of world points seen from `sensor_origin_m` (world frame). Points are
    /// taken in `f32`, as OctoMap stores them. NaN and out-of-tree points are skipped and
    /// counted; an empty cloud changes nothing.
    ///
    /// # Errors
    /// [`MapError::OutsideMap`] when the sensor origin is not finite or outside the tree.
    pub fn insert_cloud(
        &mut self,
        points_m: &[Point3<f64>],
        sensor_origin_m: &Point3<f64>,
    ) -> Result<OctreeInsertStats, MapError> {
        if self.key_at(sensor_origin_m).is_none() {
            return Err(MapError::OutsideMap {
                x_m: sensor_origin_m.x,
                y_m: sensor_origin_m.y,
            });
        }
        let origin = sensor_origin_m.coords.map(|c| c as f32);
        let mut stats = OctreeInsertStats::default();
        let mut marks = std::mem::take(&mut self.marks);
        for p in points_m {
            let end = p.coords.map(|c| c as f32);
            stats = self.mark_ray(&mut marks, origin.into(), end.into(), stats);
        }
        let mut updates = std::mem::take(&mut self.updates);
        marks.drain_sorted(&mut updates);
        stats.voxels_updated = updates.len();
        self.apply_updates(&updates);
        self.marks = marks;
        self.updates = updates;
        Ok(stats)
    }

    /// Marks the voxels of one ray (OctoMap `computeUpdate` for one point).
    fn mark_ray(
        &self,
        marks: &mut Marks,
        origin: [f32; 3],
        end: [f32; 3],
        mut stats: OctreeInsertStats,
    ) -> OctreeInsertStats {
        let resolution = self.config.resolution_m;
        if !end.iter().all(|c| c.is_finite()) {
            stats.ignored += 1;
            return stats;
        }
        let delta = [end[0] - origin[0], end[1] - origin[1], end[2] - origin[2]];
        let range =
            f64::from(delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2]).sqrt();
        match self.config.max_range_m {
            Some(max) if range > max => {
                let scale = (max / range) as f32;
                let clipped = [0, 1, 2].map(|i| origin[i] + delta[i] * scale);
                if ray_keys(origin, clipped, resolution, |k| marks.mark(k, false)) {
                    stats.cleared += 1;
                } else {
                    stats.ignored += 1;
                }
            }
            _ => {
                let traced = ray_keys(origin, end, resolution, |k| marks.mark(k, false));
                match self.key_at(&Point3::new(end[0], end[1], end[2]).cast::<f64>()) {
                    Some(key) if traced => {
                        marks.mark(key, true);
                        stats.hits += 1;
                    }
                    _ => stats.ignored += 1,
                }
            }
        }
        stats
    }

    /// Applies sorted updates (`morton << 1 | occupied`) in one depth-first pass.
    fn apply_updates(&mut self, updates: &[u64]) {
        if updates.is_empty() {
            return;
        }
        let created = !self.pool.exists(ROOT);
        if created {
            self.pool.set_value(ROOT, 0.0);
        }
        self.update_subtree(ROOT, created, key::TREE_DEPTH, updates);
    }

    /// Updates the subtree of `node`, `levels` above the finest level, with `updates` (all
    /// inside it, sorted, non-empty).
    fn update_subtree(&mut self, node: u32, just_created: bool, levels: u32, updates: &[u64]) {
        if levels == 0 {
            let step = if updates[0] & 1 == 1 {
                self.l_hit
            } else {
                self.l_miss
            };
            let value = (self.pool.value(node) + step).clamp(self.l_min, self.l_max);
            self.pool.set_value(node, value);
            return;
        }
        let mut first = self.pool.first_child(node);
        if first == NO_CHILDREN {
            let value = self.pool.value(node);
            if !just_created {
                // A pruned leaf: OctoMap leaves it alone when no update can change it.
                let saturated_hit = value >= self.l_max && updates.iter().all(|u| u & 1 == 1);
                let saturated_miss = value <= self.l_min && updates.iter().all(|u| u & 1 == 0);
                if saturated_hit || saturated_miss {
                    return;
                }
            }
            first = self.pool.add_children(node);
            if !just_created {
                (first..first + 8).for_each(|c| self.pool.set_value(c, value));
            }
        }
        let shift = 3 * (levels - 1) + 1;
        let child_of = |u: u64| ((u >> shift) & 7) as u32;
        let mut rest = updates;
        while let Some(&u) = rest.first() {
            let index = child_of(u);
            let n = rest.partition_point(|&x| child_of(x) == index);
            let (group, tail) = rest.split_at(n);
            let child = first + index;
            let created = !self.pool.exists(child);
            if created {
                self.pool.set_value(child, 0.0);
            }
            self.update_subtree(child, created, levels - 1, group);
            rest = tail;
        }
        self.pool.prune_or_update(node);
    }

    /// Size of the tree and the bytes it holds.
    pub fn stats(&self) -> OctreeStats {
        let mut stats = OctreeStats {
            nodes: self.pool.count_existing(),
            bytes: self.pool.bytes(),
            ..OctreeStats::default()
        };
        self.for_each_leaf(|leaf| {
            stats.leaves += 1;
            match self.classify(leaf.log_odds) {
                Occupancy::Occupied => stats.occupied_leaves += 1,
                _ => stats.free_leaves += 1,
            }
        });
        stats
    }

    /// The maximum-likelihood tree OctoMap writes to `.bt`: every node set to the clamp limit
    /// of its class, then pruned where that makes siblings equal.
    pub fn to_max_likelihood(&self) -> Octree {
        let mut tree = self.clone();
        let (l_min, l_max, l_occ) = (self.l_min, self.l_max, self.l_occupied);
        tree.pool
            .map_values(|v| if v >= l_occ { l_max } else { l_min });
        if tree.pool.exists(ROOT) {
            tree.prune_all(ROOT);
        }
        tree
    }

    /// Prunes every collapsible node below `node`, bottom up (OctoMap's `prune`).
    fn prune_all(&mut self, node: u32) {
        let first = self.pool.first_child(node);
        if first == NO_CHILDREN {
            return;
        }
        for child in first..first + 8 {
            if self.pool.exists(child) {
                self.prune_all(child);
            }
        }
        let value = self.pool.value(node);
        if !self.pool.prune_or_update(node) {
            // OctoMap's prune leaves inner values alone.
            self.pool.set_value(node, value);
        }
    }
}

#[cfg(test)]
#[path = "octree/tests.rs"]
mod tests;
