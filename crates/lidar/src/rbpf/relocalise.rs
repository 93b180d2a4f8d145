//! Relocalisation of a particle when it re-enters ground its own map covers.
//!
//! The improved proposal climbs from the motion-model draw and so captures only errors of a
//! cell or two; over a loop of a few hundred metres each particle's scan matcher drifts metres
//! (BENCHMARKS.md), and since the filter resamples at most updates the particles are one
//! lineage, centimetres apart, when the loop closes. Without help no particle lies within the
//! climb's reach of the old map, and the closure is lost.
//!
//! Each particle therefore searches, every few updates, for a place in its own past: an old pose
//! of its trajectory (more than `min_separation_updates` updates back) near its predicted pose.
//! The scans of that pose and its neighbours in time, placed at the particle's poses, form a
//! submap, and the new scan is matched against it over a window that grows with the path the
//! particle travelled since that old pose — the constraint search of ICP-SLAM's loop
//! closure ([`crate::icp_slam::loop_closure`]: correlative search, Olson, ICRA 2009, then
//! point-to-line ICP, Censi, ICRA 2008; the growing window of Hess et al., ICRA 2016). An
//! accepted match moves the particle's pose before the proposal, so the climb starts within
//! its reach of the old map; the weight is then computed as usual, so a wrong jump is paid for
//! by the scan likelihood like any other bad pose. (With `confirmations` set, one particle
//! searches per lineage and the lineage moves once that many matches in a row ask for the same
//! correction, [`RelocalisationConfig::confirmations`]; a match counts only when the old pass
//! does not explain the scan at the prediction too, see `ambiguous`.) This is the scan-matching
//! "relocalisation" used when a Rao-Blackwellised filter meets old ground with a drifted
//! lineage; it does not correct the particle's past poses, only its present one, which is
//! what the relations metric compares between two visits of the same place (Kümmerle et al.,
//! Autonomous Robots 27(4), 2009).

use super::{agree, Node};
use crate::cloud::{estimate_normals, voxel_downsample};
use crate::error::check_fields;
use crate::icp::align;
use crate::icp_slam::loop_closure::{
    candidate_reach, match_submap, search_window, LoopClosureConfig, SearchSource,
};
use crate::nn::{GridIndex, NearestNeighbours};
use crate::point_map::{index_keyframes, Keyframe};
use crate::LidarError;
use nalgebra::Point2;
use serde::{Deserialize, Serialize};
use slamkit_core::Pose2;

/// Relocalisation parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RelocalisationConfig {
    /// Search at all.
    pub enabled: bool,
    /// Search at every n-th filter update (>= 1).
    pub every_updates: usize,
    /// Fraction of the particles that search at such an update, drawn at random, in \[0, 1\]:
    /// the others keep the plain proposal, so both hypotheses stay in the filter and the
    /// weights choose (the mixture proposal of Thrun et al., "Robust Monte Carlo localization
    /// for mobile robots", Artificial Intelligence 128, 2001). Used only when
    /// `confirmations` is 0.
    pub fraction: f64,
    /// Matches in agreement after which a lineage takes a correction (0, the default: the
    /// random `fraction` searches instead, and the weights choose). One particle searches per
    /// lineage (particles sharing their ancestor `min_separation_updates` back, whose
    /// searchable pasts are the same), and a lineage that has matched searches again at the
    /// next update; when a match is the correction the lineage's previous match found (within
    /// `agree_m` and `agree_rad`, `confirmations` times running), every particle of the lineage
    /// is moved by it. The weights cannot make that choice fairly: both the moved and the
    /// unmoved particles are scored against a map whose ground around the robot is the recent,
    /// drifted pass, which the unmoved pose explains. A match the old pass also explains at the
    /// prediction does not count (`ambiguous`: a corridor slide). Not the default: at 10
    /// particles, seeds 1-10, it met MIT CSAIL's 0.049 m at every seed and ACES's 0.060 m at 9
    /// (main's filter 9 and 5), but ACES seed 2 closes its first loop late, 0.087 m
    /// (docs/experiments/pf-seeds.md).
    pub confirmations: usize,
    /// Two matches agree when the corrections they ask for move the prediction to poses
    /// within this distance \[m\] ...
    pub agree_m: f64,
    /// ... and this angle \[rad\].
    pub agree_rad: f64,
    /// A lineage's unconfirmed match is forgotten after this many updates without another.
    pub pending_updates: usize,
    /// With `confirmations`, a match within this distance \[m\] ...
    pub min_jump_m: f64,
    /// ... and this angle \[rad\] of the prediction is within the proposal's climb: it
    /// confirms the lineage where it is instead of asking for a correction (the search's ICP
    /// against thinned points would only replace the grid match's centimetres by its own).
    pub min_jump_rad: f64,
    /// Poses of the particle's trajectory this many updates old or newer are not candidates
    /// (the climb already matches against them).
    pub min_separation_updates: usize,
    /// Voxel size the scans kept for later searches are thinned to \[m\].
    pub keep_voxel_m: f64,
    /// Neighbours used to estimate each kept point's normal (for point-to-line ICP).
    pub normal_neighbours: usize,
    /// Neighbours farther than this do not count for normals \[m\].
    pub normal_radius_m: f64,
    /// Largest ratio of the small to the large eigenvalue for a neighbourhood to have a normal.
    pub normal_max_flatness: f64,
    /// The search itself: candidates, submap, windows and acceptance, as ICP-SLAM's loop
    /// closure (its pose-graph fields `every_keyframes`, `min_separation_keyframes`, `edge_*`,
    /// `robust_scale` and `optimize_iterations` are not used here). `slamkit`'s `--config`
    /// lays a file over these defaults, so a partial `[relocalisation.search]` table keeps
    /// the 2 candidates, 4 m and 0.65 below; deserialised on its own with serde, a partial
    /// table takes ICP-SLAM's loop-closure defaults (3, 10 m, 0.8) for the fields it omits.
    pub search: LoopClosureConfig,
}

impl Default for RelocalisationConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            every_updates: 2,
            fraction: 0.5,
            confirmations: 0,
            agree_m: 0.25,
            agree_rad: 0.05,
            pending_updates: 10,
            min_jump_m: 0.1,
            min_jump_rad: 0.03,
            min_separation_updates: 100,
            keep_voxel_m: 0.1,
            normal_neighbours: 6,
            normal_radius_m: 0.5,
            normal_max_flatness: 0.2,
            // ICP-SLAM's search, with a window of at most 4 m (one particle's matcher drifts
            // up to about 3.5 m between visits on ACES; wider windows found false matches) and
            // a lower ICP goodness (the submap covers only part of the scan's view).
            search: LoopClosureConfig {
                max_candidates: 2,
                max_window_m: 4.0,
                min_goodness: 0.65,
                ..LoopClosureConfig::default()
            },
        }
    }
}

impl RelocalisationConfig {
    /// Checks every field's range (the search's too), naming the first field out of range.
    pub fn validate(&self) -> Result<(), LidarError> {
        self.search.validate()?;
        let checks = [
            (
                "every_updates",
                self.every_updates as f64,
                self.every_updates >= 1,
            ),
            (
                "fraction",
                self.fraction,
                (0.0..=1.0).contains(&self.fraction),
            ),
            ("keep_voxel_m", self.keep_voxel_m, self.keep_voxel_m >= 0.0),
            ("agree_m", self.agree_m, self.agree_m >= 0.0),
            ("agree_rad", self.agree_rad, self.agree_rad >= 0.0),
            ("min_jump_m", self.min_jump_m, self.min_jump_m >= 0.0),
            ("min_jump_rad", self.min_jump_rad, self.min_jump_rad >= 0.0),
            (
                "normal_radius_m",
                self.normal_radius_m,
                self.normal_radius_m > 0.0,
            ),
            (
                "normal_max_flatness",
                self.normal_max_flatness,
                self.normal_max_flatness > 0.0,
            ),
        ];
        check_fields(checks, "out of range")
    }

    /// The points (base frame) of a scan as kept with its nodes: thinned, with normals.
    pub fn keep(&self, points: &[Point2<f64>]) -> Keyframe {
        let points = voxel_downsample(points, self.keep_voxel_m);
        let normals = estimate_normals(
            &points,
            self.normal_neighbours,
            self.normal_radius_m,
            self.normal_max_flatness,
        );
        Keyframe {
            world_from_base: Pose2::identity(),
            points,
            normals,
        }
    }
}

/// Searches the past of the particle whose newest node is `newest` for the pose of `source`
/// (the new scan) near `predicted`. The particle's earlier visits of the place are tried oldest
/// first (the place as first mapped, so later passes are tied to it rather than to each other),
/// each at its pose nearest the prediction, with a window that grows with the path the particle
/// travelled since. Returns the matched `world_from_base`.
pub(super) fn relocalise(
    newest: &Node,
    predicted: &Pose2,
    source: &SearchSource,
    config: &RelocalisationConfig,
    unambiguous_within: Option<(f64, f64)>,
) -> Option<Pose2> {
    let search = &config.search;
    // The particle's trajectory, newest first, with the path length from each node to now.
    let mut chain: Vec<(&Node, f64)> = Vec::new();
    let (mut node, mut path_m, mut next) = (Some(newest), 0.0, *predicted);
    while let Some(n) = node {
        path_m += (next.translation.vector - n.world_from_base.translation.vector).norm();
        next = n.world_from_base;
        chain.push((n, path_m));
        node = n.parent.as_deref();
    }
    let old = config.min_separation_updates.max(1);
    let near: Vec<(usize, f64, f64)> = chain
        .iter()
        .enumerate()
        .skip(old)
        .filter_map(|(depth, (n, path_m))| {
            let window = search_window(*path_m, search);
            let d = (n.world_from_base.translation.vector - predicted.translation.vector).norm();
            (d <= candidate_reach(window, search)).then_some((depth, window, d))
        })
        .collect();
    let candidates: Vec<(usize, f64)> = visits(&near)
        .into_iter()
        .rev()
        .take(search.max_candidates)
        .collect();
    candidates.into_iter().find_map(|(depth, window)| {
        let half = search.submap_half_keyframes;
        let first = depth.saturating_sub(half).max(old);
        let last = (depth + half + 1).min(chain.len());
        let keyframes: Vec<Keyframe> = chain
            .get(first..last)?
            .iter()
            .filter_map(|(n, _)| {
                n.cloud.as_ref().map(|cloud| Keyframe {
                    world_from_base: n.world_from_base,
                    points: cloud.points.clone(),
                    normals: cloud.normals.clone(),
                })
            })
            .collect();
        let submap = index_keyframes(&keyframes, search.correlative.resolution_m);
        if submap.len() < search.icp.min_correspondences {
            return None;
        }
        let fine = match_submap(
            source,
            &submap,
            predicted,
            window,
            search,
            search.min_goodness,
        )?;
        let rejected = unambiguous_within.is_some_and(|(m, rad)| {
            ambiguous(
                source,
                &submap,
                predicted,
                &fine.target_from_source,
                search,
                m,
                rad,
            )
        });
        if rejected {
            return None;
        }
        Some(fine.target_from_source)
    })
}

/// True when the old pass explains the scan at the prediction too: `predicted`, refined by the
/// search's ICP against `submap`, is itself an accepted match (goodness at least the search's
/// `min_goodness`) and lies farther than `agree_m` / `agree_rad` from `matched`. The submap
/// then holds two explanations of the scan, and the search's choice between them is not
/// evidence that the lineage is off: along a corridor whose walls repeat, the window's best
/// correlation slides by metres (ACES seed 2 took three such corrections of 2-4.5 m along one
/// corridor, every one with the prediction already matching 72-92 % of the scan's points
/// within 0.1 m, and a fourth of 5.2 m after them: 0.047 -> 0.446 m, docs/experiments/pf-seeds.md).
/// A drifted lineage's prediction does not match its old pass (the true closures of that run
/// and of seed 6: 0-33 % within 0.1 m), and a small true correction refines to the match
/// itself.
fn ambiguous(
    source: &SearchSource,
    submap: &GridIndex,
    predicted: &Pose2,
    matched: &Pose2,
    search: &LoopClosureConfig,
    agree_m: f64,
    agree_rad: f64,
) -> bool {
    align(source.points(), submap, predicted, &search.icp)
        .ok()
        .filter(|local| local.goodness >= search.min_goodness)
        .is_some_and(|local| !agree(&local.target_from_source, matched, agree_m, agree_rad))
}

/// The nearest pose of each visit of the place: `near` holds `(depth, window, distance)` of
/// the poses near the prediction, newest first; poses of consecutive depths are one visit.
/// Returns `(depth, window)` of each visit's nearest pose, newest visit first.
fn visits(near: &[(usize, f64, f64)]) -> Vec<(usize, f64)> {
    let mut out: Vec<(usize, f64, f64)> = Vec::new();
    let mut previous_depth: Option<usize> = None;
    for &(depth, window, d) in near {
        let same_visit = previous_depth.is_some_and(|p| depth == p + 1);
        match out.last_mut() {
            Some(best) if same_visit => {
                if d < best.2 {
                    *best = (depth, window, d);
                }
            }
            _ => out.push((depth, window, d)),
        }
        previous_depth = Some(depth);
    }
    out.into_iter()
        .map(|(depth, window, _)| (depth, window))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::scan_points;
    use crate::sim_scan::SegmentWorld;
    use nalgebra::Vector2;
    use std::sync::Arc;

    #[test]
    fn visits_keep_the_nearest_pose_of_each_run_of_depths() {
        let near = [
            (3, 1.0, 2.0),
            (4, 1.0, 1.5),
            (5, 1.0, 1.7),
            (9, 2.0, 0.5),
            (20, 3.0, 1.0),
            (21, 3.0, 0.2),
        ];
        assert_eq!(visits(&near), vec![(4, 1.0), (9, 2.0), (21, 3.0)]);
        assert!(visits(&[]).is_empty());
    }

    /// A trajectory along the simulated room, then back to its start with the particle's
    /// estimate 0.9 m and 0.05 rad off: the search finds the true pose in the old scans.
    #[test]
    fn a_drifted_particle_finds_its_first_pass() {
        let world = SegmentWorld::room();
        let config = RelocalisationConfig {
            min_separation_updates: 10,
            ..RelocalisationConfig::default()
        };
        let scan_at = |pose: &Pose2| world.scan(pose, 361, std::f64::consts::PI, 30.0);
        let mut node: Option<Arc<Node>> = None;
        // Out along the room and back: 40 poses 0.2 m apart, each with its scan.
        let truth: Vec<Pose2> = (0..40)
            .map(|i| {
                let k = if i < 20 { i } else { 39 - i };
                Pose2::new(Vector2::new(-3.5 + 0.3 * f64::from(k), -1.0), 0.1)
            })
            .collect();
        for (i, pose) in truth.iter().enumerate() {
            let scan = scan_at(pose);
            let cloud = config.keep(&scan_points(&scan, 0.1, config.search.max_range_m));
            node = Some(Arc::new(Node {
                scan: i,
                world_from_base: *pose,
                cloud: Some(Arc::new(cloud)),
                parent: node.take(),
            }));
        }
        let newest = node.expect("nodes");
        let actual = Pose2::new(Vector2::new(-3.4, -0.9), 0.12);
        let scan = scan_at(&actual);
        let source = SearchSource::new(
            &scan_points(&scan, 0.1, config.search.max_range_m),
            &config.search,
        );
        let predicted = Pose2::new(Vector2::new(-2.7, -0.35), 0.17);
        let found = relocalise(&newest, &predicted, &source, &config, None).expect("a match");
        // The drifted prediction does not match the old pass: the match is not ambiguous.
        let unambiguous = Some((config.agree_m, config.agree_rad));
        let checked = relocalise(&newest, &predicted, &source, &config, unambiguous);
        assert_eq!(checked, Some(found));
        let error = actual.inverse() * found;
        assert!(
            error.translation.vector.norm() < 0.03 && error.rotation.angle().abs() < 0.01,
            "{found:?}"
        );
        // Nothing old enough: the whole trajectory is within the separation.
        let strict = RelocalisationConfig {
            min_separation_updates: 40,
            ..config
        };
        assert!(relocalise(&newest, &predicted, &source, &strict, None).is_none());
    }

    /// The scans' points at their poses as one submap (world frame), and the source of a scan.
    fn submap_of(
        world: &SegmentWorld,
        poses: &[Pose2],
        config: &RelocalisationConfig,
        range_m: f64,
    ) -> GridIndex {
        let keyframes: Vec<Keyframe> = poses
            .iter()
            .map(|pose| {
                let scan = world.scan(pose, 361, std::f64::consts::PI, range_m);
                Keyframe {
                    world_from_base: *pose,
                    ..config.keep(&scan_points(&scan, 0.1, range_m - 0.01))
                }
            })
            .collect();
        index_keyframes(&keyframes, config.search.correlative.resolution_m)
    }

    fn source_at(
        world: &SegmentWorld,
        pose: &Pose2,
        config: &RelocalisationConfig,
        range_m: f64,
    ) -> SearchSource {
        let scan = world.scan(pose, 361, std::f64::consts::PI, range_m);
        SearchSource::new(&scan_points(&scan, 0.1, range_m - 0.01), &config.search)
    }

    /// In a corridor whose pillars repeat every 2 m, a match one period along the corridor
    /// from a correct prediction is ambiguous; in the asymmetric room, neither a prediction
    /// 0.9 m off (a drifted lineage) nor one 5 cm off (a small correction) is.
    #[test]
    fn a_repeating_corridor_makes_a_match_ambiguous_the_room_does_not() {
        let config = RelocalisationConfig::default();
        let (m, rad) = (config.agree_m, config.agree_rad);
        let mut corridor = SegmentWorld {
            segments: vec![
                (Point2::new(-30.0, -1.0), Point2::new(30.0, -1.0)),
                (Point2::new(-30.0, 1.0), Point2::new(30.0, 1.0)),
            ],
        };
        for k in -15..15 {
            let x = 2.0 * f64::from(k);
            corridor.segments.extend(
                SegmentWorld::polygon(&[(x, -1.0), (x + 0.3, -1.0), (x + 0.3, -0.8), (x, -0.8)])
                    .segments,
            );
        }
        let along: Vec<Pose2> = (0..25)
            .map(|i| Pose2::new(Vector2::new(-6.0 + 0.5 * f64::from(i), 0.0), 0.0))
            .collect();
        let submap = submap_of(&corridor, &along, &config, 8.0);
        let truth = Pose2::new(Vector2::new(0.3, 0.1), 0.0);
        let source = source_at(&corridor, &truth, &config, 8.0);
        let slid = Pose2::new(Vector2::new(2.3, 0.1), 0.0);
        let search = &config.search;
        assert!(ambiguous(&source, &submap, &truth, &slid, search, m, rad));
        assert!(!ambiguous(&source, &submap, &truth, &truth, search, m, rad));

        let room = SegmentWorld::room();
        let poses: Vec<Pose2> = (0..20)
            .map(|i| Pose2::new(Vector2::new(-3.5 + 0.3 * f64::from(i), -1.0), 0.1))
            .collect();
        let submap = submap_of(&room, &poses, &config, 30.0);
        let actual = Pose2::new(Vector2::new(-3.4, -0.9), 0.12);
        let source = source_at(&room, &actual, &config, 30.0);
        let drifted = Pose2::new(Vector2::new(-2.7, -0.35), 0.17);
        assert!(!ambiguous(
            &source, &submap, &drifted, &actual, search, m, rad
        ));
        let near = Pose2::new(Vector2::new(-3.35, -0.9), 0.11);
        assert!(!ambiguous(&source, &submap, &near, &actual, search, m, rad));
    }
}
