//! The merged map: the maps' frames chained along the joined pairs, then one pose graph of
//! every keyframe of the joined maps, optimised together.
//!
//! Maps joined directly or through others form groups (union–find over the joined pairs). The
//! group with the most keyframes is the merged map, in the frame of its first input; every
//! other input is unmerged. Each map's frame is placed by a breadth-first walk from that input
//! along the joined pairs, each step the pair's best closure. The graph holds each map's own
//! edges as the map saved them and every accepted closure with a Cauchy kernel, so the closures
//! between maps correct each map's own drift as well as placing it, and one closure that
//! slipped through pulls with bounded force. The first keyframe of the first input is held
//! fixed.

use super::pcm::PairLink;
use super::{ClosureStatus, InterClosure, MergedInput};
use crate::lidar::{LidarMap, MapKeyframe, MapScan};
use crate::SlamError;
use serde::{Deserialize, Serialize};
use slamkit_core::pose::pose2_to_pose3;
use slamkit_core::{Pose2, Trajectory};
use slamkit_lidar::pose_graph::{Edge, OptimizeSummary, PoseGraph};

/// Joint optimisation settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct JointConfig {
    /// Standard deviation of the translation of a closure between maps \[m\].
    pub closure_sigma_m: f64,
    /// Standard deviation of its rotation \[rad\].
    pub closure_sigma_rad: f64,
    /// Cauchy kernel scale on a closure's Mahalanobis error (in standard deviations).
    pub robust_scale: f64,
    /// Gauss–Newton iterations at most.
    pub iterations: usize,
    /// Stop once a step moves no keyframe by more than this (metres and radians).
    pub tolerance: f64,
}

impl Default for JointConfig {
    fn default() -> Self {
        Self {
            closure_sigma_m: 0.05,
            closure_sigma_rad: 1f64.to_radians(),
            robust_scale: 3.0,
            iterations: 30,
            tolerance: 1e-6,
        }
    }
}

impl JointConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), SlamError> {
        let ok = self.closure_sigma_m > 0.0
            && self.closure_sigma_rad > 0.0
            && self.robust_scale > 0.0
            && self.tolerance > 0.0;
        if ok {
            Ok(())
        } else {
            Err(SlamError::Config(format!(
                "merge joint: a field is out of range in {self:?}"
            )))
        }
    }

    fn information(&self) -> nalgebra::Matrix3<f64> {
        let (t, r) = (
            self.closure_sigma_m.powi(-2),
            self.closure_sigma_rad.powi(-2),
        );
        nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(t, t, r))
    }
}

/// The merged map and where each input went.
#[derive(Debug, Clone)]
pub struct Joined {
    /// The merged map.
    pub map: LidarMap,
    /// One entry per input.
    pub inputs: Vec<MergedInput>,
    /// The joint optimisation, when two or more inputs merged.
    pub optimisation: Option<OptimizeSummary>,
}

/// Builds the merged map of `maps` from the joined pairs `links` and the `closures` (those
/// [`ClosureStatus::Accepted`] between merged maps become edges).
pub fn join(
    maps: &[LidarMap],
    closures: &[InterClosure],
    links: &[PairLink],
    config: &JointConfig,
) -> Joined {
    let frames = place_frames(maps, links);
    let mut offsets: Vec<Option<usize>> = vec![None; maps.len()];
    let mut graph = PoseGraph::new();
    for (m, map) in maps.iter().enumerate() {
        let Some(frame) = frames[m] else { continue };
        offsets[m] = Some(graph.nodes().len());
        for kf in &map.keyframes {
            graph.add_node(frame * kf.world_from_base);
        }
    }
    let mut edges = Vec::new();
    for (m, map) in maps.iter().enumerate() {
        let Some(o) = offsets[m] else { continue };
        edges.extend(map.edges.iter().map(|e| Edge {
            from: e.from + o,
            to: e.to + o,
            ..*e
        }));
    }
    for c in closures
        .iter()
        .filter(|c| c.status == ClosureStatus::Accepted)
    {
        let (Some(fo), Some(to)) = (offsets[c.from_map], offsets[c.to_map]) else {
            continue;
        };
        edges.push(Edge {
            from: fo + c.from_keyframe,
            to: to + c.to_keyframe,
            from_from_to: c.from_from_to,
            information: config.information(),
            robust_scale: Some(config.robust_scale),
        });
    }
    // A map's edges were checked when it was read; an edge the graph refuses (out of range,
    // not finite) is left out of the merged map too.
    edges.retain(|e| graph.add_edge(*e));
    let merged = frames.iter().filter(|f| f.is_some()).count();
    let optimisation = (merged >= 2).then(|| graph.optimize(config.iterations, config.tolerance));
    let poses = graph.nodes();
    let mut map = LidarMap {
        keyframes: Vec::with_capacity(poses.len()),
        edges,
        scans: Vec::new(),
    };
    let mut inputs = Vec::with_capacity(maps.len());
    for (m, input) in maps.iter().enumerate() {
        let (Some(o), Some(frame)) = (offsets[m], frames[m]) else {
            inputs.push(MergedInput {
                merged_from_input: None,
                keyframe_offset: None,
                trajectory: None,
            });
            continue;
        };
        map.keyframes
            .extend(input.keyframes.iter().enumerate().map(|(k, kf)| {
                MapKeyframe {
                    world_from_base: poses
                        .get(o + k)
                        .copied()
                        .unwrap_or(frame * kf.world_from_base),
                    scan: kf.scan.clone(),
                }
            }));
        let scans = rebased_scans(input, o);
        let mut trajectory = Trajectory::new();
        for s in &scans {
            let keyframe = s
                .keyframe
                .and_then(|k| map.keyframes.get(k))
                .map_or(frame, |kf| kf.world_from_base);
            trajectory.push(
                s.timestamp,
                pose2_to_pose3(&(keyframe * s.keyframe_from_base)),
            );
        }
        map.scans.extend(scans);
        inputs.push(MergedInput {
            merged_from_input: Some(frame),
            keyframe_offset: Some(o),
            trajectory: Some(trajectory),
        });
    }
    map.scans
        .sort_by(|a, b| a.timestamp.total_cmp(&b.timestamp));
    Joined {
        map,
        inputs,
        optimisation,
    }
}

/// `merged_from_input` of every input of the merged group (`None` for the rest).
fn place_frames(maps: &[LidarMap], links: &[PairLink]) -> Vec<Option<Pose2>> {
    let n = maps.len();
    let mut group: Vec<usize> = (0..n).collect();
    fn root(group: &mut [usize], mut i: usize) -> usize {
        while group[i] != i {
            group[i] = group[group[i]];
            i = group[i];
        }
        i
    }
    for l in links {
        let (a, b) = (root(&mut group, l.from_map), root(&mut group, l.to_map));
        group[a.max(b)] = a.min(b);
    }
    let roots: Vec<usize> = (0..n).map(|i| root(&mut group, i)).collect();
    let size = |r: usize| -> usize {
        (0..n)
            .filter(|&i| roots[i] == r)
            .map(|i| maps[i].keyframes.len())
            .sum()
    };
    // The largest group; among equal ones the one of the earliest input (roots are the
    // smallest index of their group, so the first input of the chosen group is its root).
    let Some(main) = (0..n)
        .filter(|&i| roots[i] == i)
        .max_by(|&a, &b| size(a).cmp(&size(b)).then(b.cmp(&a)))
    else {
        return vec![None; n];
    };
    let mut frames: Vec<Option<Pose2>> = vec![None; n];
    frames[main] = Some(Pose2::identity());
    let mut changed = true;
    while changed {
        changed = false;
        for l in links {
            match (frames[l.from_map], frames[l.to_map]) {
                (Some(f), None) => frames[l.to_map] = Some(f * l.from_from_to_frame),
                (None, Some(t)) => frames[l.from_map] = Some(t * l.from_from_to_frame.inverse()),
                _ => continue,
            }
            changed = true;
        }
    }
    frames
}

/// The scans of `map` following keyframes numbered from `offset`; a scan that followed the
/// map frame itself (before the first keyframe) follows the map's first keyframe instead, as
/// the map frame has no node of its own in the merged graph.
fn rebased_scans(map: &LidarMap, offset: usize) -> Vec<MapScan> {
    let first_from_world = map
        .keyframes
        .first()
        .map_or(Pose2::identity(), |kf| kf.world_from_base.inverse());
    map.scans
        .iter()
        .map(|s| match s.keyframe {
            Some(k) => MapScan {
                keyframe: Some(k + offset),
                ..*s
            },
            None => MapScan {
                keyframe: Some(offset),
                keyframe_from_base: first_from_world * s.keyframe_from_base,
                ..*s
            },
        })
        .collect()
}
