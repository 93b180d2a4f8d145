//! A* through the voxels of an octree, for flying robots.
//!
//! The graph joins each finest voxel to its 26 neighbours, a move costing the distance between
//! voxel centres (1, √2 or √3 voxels); the heuristic is the straight-line distance, which is
//! consistent, so the path is the shortest in this graph (Hart, Nilsson and Raphael 1968). A
//! voxel is passable when it and every voxel within `clearance_voxels` (a cube) is not
//! occupied. As on 2D grids, the first search uses known-free voxels only and a second one,
//! run only if the first fails, also unknown voxels. The search keeps its state in hash maps, so
//! its memory follows the explored volume, not the map's size, and stops after
//! `max_expansions`.

use crate::error::NavError;
use nalgebra::Point3;
use serde::{Deserialize, Serialize};
use slamkit_map::octree::key::OctreeKey;
use slamkit_map::{Occupancy, Octree};
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

/// Parameters of the octree planner.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OctreePlannerConfig {
    /// Voxels around each path voxel (a cube of half-side this) that must not be occupied.
    pub clearance_voxels: u16,
    /// The search gives up after this many expansions.
    pub max_expansions: usize,
}

impl Default for OctreePlannerConfig {
    fn default() -> Self {
        Self {
            clearance_voxels: 1,
            max_expansions: 2_000_000,
        }
    }
}

/// A path through the octree.
#[derive(Debug, Clone, PartialEq)]
pub struct OctreePath {
    /// Voxel centres \[m\], start first.
    pub waypoints_m: Vec<Point3<f64>>,
    /// Length of the polyline \[m\].
    pub length_m: f64,
    /// True when unknown voxels had to be crossed.
    pub through_unknown: bool,
    /// Voxels expanded by the search that found the path.
    pub expanded: usize,
}

/// Plans from `start_m` to `goal_m` through `tree`.
///
/// # Errors
/// [`NavError::OutsideMap`] for NaN or out-of-tree ends, [`NavError::Blocked`] when an end
/// lacks clearance, [`NavError::Unreachable`] or [`NavError::SearchLimit`] when no path is found.
pub fn plan_octree(
    tree: &Octree,
    start_m: &Point3<f64>,
    goal_m: &Point3<f64>,
    config: &OctreePlannerConfig,
) -> Result<OctreePath, NavError> {
    let start = end_key(tree, start_m, "start", config)?;
    let goal = end_key(tree, goal_m, "goal", config)?;
    let mut last = NavError::Unreachable { expanded: 0 };
    for allow_unknown in [false, true] {
        match search(tree, start, goal, allow_unknown, config) {
            Ok((keys, expanded)) => {
                let waypoints_m: Vec<Point3<f64>> =
                    keys.iter().map(|k| tree.key_center_m(*k)).collect();
                let length_m = waypoints_m.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
                return Ok(OctreePath {
                    waypoints_m,
                    length_m,
                    through_unknown: allow_unknown,
                    expanded,
                });
            }
            Err(e) => last = e,
        }
    }
    Err(last)
}

fn end_key(
    tree: &Octree,
    p: &Point3<f64>,
    what: &'static str,
    config: &OctreePlannerConfig,
) -> Result<OctreeKey, NavError> {
    let (x_m, y_m, z_m) = (p.x, p.y, p.z);
    let key = tree.key_at(p).ok_or(NavError::OutsideMap {
        what,
        x_m,
        y_m,
        z_m,
    })?;
    if !clear(tree, key, config.clearance_voxels) {
        return Err(NavError::Blocked {
            what,
            x_m,
            y_m,
            z_m,
        });
    }
    Ok(key)
}

/// No occupied voxel within the cube of half-side `r` around `key` (and all of it inside the tree).
fn clear(tree: &Octree, key: OctreeKey, r: u16) -> bool {
    let r = i32::from(r);
    for dz in -r..=r {
        for dy in -r..=r {
            for dx in -r..=r {
                let Some(k) = offset(key, [dx, dy, dz]) else {
                    return false;
                };
                if tree.occupancy_key(k) == Occupancy::Occupied {
                    return false;
                }
            }
        }
    }
    true
}

fn offset(key: OctreeKey, d: [i32; 3]) -> Option<OctreeKey> {
    let k = [0, 1, 2].map(|i| u16::try_from(i32::from(key.0[i]) + d[i]).ok());
    Some(OctreeKey([k[0]?, k[1]?, k[2]?]))
}

fn distance(a: OctreeKey, b: OctreeKey) -> f64 {
    let d = [0, 1, 2].map(|i| f64::from(i32::from(a.0[i]) - i32::from(b.0[i])));
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// A* in voxel units; returns the keys, start first, and the expansions.
fn search(
    tree: &Octree,
    start: OctreeKey,
    goal: OctreeKey,
    allow_unknown: bool,
    config: &OctreePlannerConfig,
) -> Result<(Vec<OctreeKey>, usize), NavError> {
    let passable = |k: OctreeKey| {
        let state = tree.occupancy_key(k);
        (state == Occupancy::Free || (allow_unknown && state == Occupancy::Unknown))
            && clear(tree, k, config.clearance_voxels)
    };
    let mut best: HashMap<OctreeKey, (f64, OctreeKey, bool)> = HashMap::new();
    best.insert(start, (0.0, start, false));
    let mut queue = BinaryHeap::from([Reverse((distance(start, goal).to_bits(), start))]);
    let mut expanded = 0;
    while let Some(Reverse((_, at))) = queue.pop() {
        let Some(entry) = best.get_mut(&at) else {
            continue;
        };
        if entry.2 {
            continue;
        }
        entry.2 = true;
        let g = entry.0;
        expanded += 1;
        if at == goal {
            return Ok((trace(&best, start, goal), expanded));
        }
        if expanded >= config.max_expansions {
            return Err(NavError::SearchLimit { expanded });
        }
        for d in neighbours() {
            let Some(n) = offset(at, d) else { continue };
            let cost = g + distance(at, n);
            let better = best
                .get(&n)
                .map_or(true, |(c, _, closed)| !closed && cost < *c);
            if better && passable(n) {
                best.insert(n, (cost, at, false));
                queue.push(Reverse(((cost + distance(n, goal)).to_bits(), n)));
            }
        }
    }
    Err(NavError::Unreachable { expanded })
}

fn neighbours() -> impl Iterator<Item = [i32; 3]> {
    (0..27)
        .map(|i| [i % 3 - 1, (i / 3) % 3 - 1, i / 9 - 1])
        .filter(|d| *d != [0, 0, 0])
}

fn trace(
    best: &HashMap<OctreeKey, (f64, OctreeKey, bool)>,
    start: OctreeKey,
    goal: OctreeKey,
) -> Vec<OctreeKey> {
    let mut keys = vec![goal];
    let mut at = goal;
    while at != start {
        match best.get(&at) {
            Some((_, parent, _)) => at = *parent,
            None => break,
        }
        keys.push(at);
    }
    keys.reverse();
    keys
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_map::OctreeConfig;

    /// A 2 m × 2 m × 1 m room at 0.1 m seen from its centre, with a wall across it at x = 1
    /// that leaves a gap above z = 0.5.
    pub(super) fn room() -> Octree {
        let mut tree = Octree::new(OctreeConfig {
            resolution_m: 0.1,
            ..OctreeConfig::default()
        })
        .unwrap();
        let mut cloud = Vec::new();
        let c = |i: i32| f64::from(i) * 0.1 + 0.05;
        for i in 0..20 {
            for j in 0..10 {
                for (x, y, z) in [
                    (c(i), 0.05, c(j)),
                    (c(i), 1.95, c(j)),
                    (0.05, c(i), c(j)),
                    (1.95, c(i), c(j)),
                ] {
                    cloud.push(Point3::new(x, y, z));
                }
                if j < 5 {
                    cloud.push(Point3::new(1.05, c(i), c(j)));
                }
            }
            for j in 0..20 {
                cloud.push(Point3::new(c(i), c(j), 0.05));
                cloud.push(Point3::new(c(i), c(j), 0.95));
            }
        }
        for origin in [Point3::new(0.45, 1.05, 0.85), Point3::new(1.55, 1.05, 0.85)] {
            tree.insert_cloud(&cloud, &origin).unwrap();
        }
        tree
    }

    #[test]
    fn flies_over_the_wall_through_free_voxels() {
        let tree = room();
        let config = OctreePlannerConfig::default();
        let (start, goal) = (Point3::new(0.45, 1.05, 0.35), Point3::new(1.55, 1.05, 0.35));
        let path = plan_octree(&tree, &start, &goal, &config).unwrap();
        // The wall's top is at z = 0.5 m; with one voxel of clearance the lowest crossing has
        // its centre at 0.65 m, the voxel above the first free layer.
        let crossing: Vec<f64> = path
            .waypoints_m
            .iter()
            .filter(|p| (p.x - 1.05).abs() < 1e-6)
            .map(|p| p.z)
            .collect();
        assert!(!crossing.is_empty(), "crosses the wall plane");
        assert!(
            crossing.iter().all(|z| *z > 0.6),
            "over the wall: {crossing:?}"
        );
        assert!(!path.through_unknown);
        for p in &path.waypoints_m {
            let key = tree.key_at(p).unwrap();
            assert!(
                clear(&tree, key, config.clearance_voxels),
                "clearance at {p}"
            );
        }
        assert!(path.length_m > (goal - start).norm());
    }

    #[test]
    fn errors_for_bad_ends() {
        let tree = room();
        let config = OctreePlannerConfig::default();
        let inside = Point3::new(0.45, 1.05, 0.35);
        let nan = Point3::new(f64::NAN, 0.0, 0.0);
        assert!(matches!(
            plan_octree(&tree, &nan, &inside, &config),
            Err(NavError::OutsideMap { what: "start", .. })
        ));
        let wall = Point3::new(1.05, 1.05, 0.35);
        assert!(matches!(
            plan_octree(&tree, &inside, &wall, &config),
            Err(NavError::Blocked { what: "goal", .. })
        ));
        let small = OctreePlannerConfig {
            max_expansions: 5,
            ..config
        };
        let far = Point3::new(1.55, 1.05, 0.35);
        assert!(matches!(
            plan_octree(&tree, &inside, &far, &small),
            Err(NavError::SearchLimit { .. })
        ));
    }
}
