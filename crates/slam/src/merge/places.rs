//! Place recognition between maps: keyframe submaps of one map searched for in another with no
//! prior pose, by the global search that finds a robot in a saved map
//! ([`slamkit_lidar::global_search`]).
//!
//! Every pair of maps is searched once, the later map's queries in the earlier map, or with
//! `both_ways` twice, each map's queries in the other: a place one robot's submap does not pin
//! down (a stretch of corridor in a map that holds a longer one) may be pinned down by the other
//! robot's submap of it, so a pair whose maps share little gets more closures. A query is a
//! keyframe with its `half_keyframes` neighbours on each side in time, in the keyframe's base
//! frame; queries are thinned in space, `spacing_m` apart, so each place the querying robot
//! went through is asked about once however often it passed there.

use super::{submap_points, ClosureStatus, InterClosure, MergeConfig, MergeStats};
use crate::SlamError;
use serde::{Deserialize, Serialize};
use slamkit_core::StageTimings;
use slamkit_lidar::cloud::voxel_downsample;
use slamkit_lidar::global_search::{GlobalOutcome, GlobalSearch};
use slamkit_lidar::point_map::Keyframe;
use std::time::Instant;

/// Which keyframes query the other maps.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlacesConfig {
    /// Query keyframes are at least this far apart \[m\].
    pub spacing_m: f64,
    /// A query holds this many keyframes on each side of its own.
    pub half_keyframes: usize,
    /// Voxel size the query's points are thinned to \[m\].
    pub voxel_m: f64,
    /// Search each pair of maps both ways (each map's queries in the other), not only the later
    /// map's queries in the earlier map: more closures between maps that share a short stretch,
    /// at twice the search time.
    pub both_ways: bool,
}

impl Default for PlacesConfig {
    fn default() -> Self {
        Self {
            spacing_m: 3.0,
            half_keyframes: 10,
            voxel_m: 0.05,
            both_ways: false,
        }
    }
}

impl PlacesConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), SlamError> {
        if !(self.spacing_m > 0.0 && self.voxel_m > 0.0) {
            return Err(SlamError::Config(format!(
                "merge places: spacing_m {} and voxel_m {} must be > 0",
                self.spacing_m, self.voxel_m
            )));
        }
        Ok(())
    }
}

/// The keyframes of `keyframes` that query other maps: the first, then each one at least
/// `spacing_m` from every query chosen before it.
pub fn query_keyframes(keyframes: &[Keyframe], spacing_m: f64) -> Vec<usize> {
    let mut chosen: Vec<usize> = Vec::new();
    for (i, kf) in keyframes.iter().enumerate() {
        let p = kf.world_from_base.translation.vector;
        let covered = chosen
            .iter()
            .any(|&c| (keyframes[c].world_from_base.translation.vector - p).norm() < spacing_m);
        if !covered {
            chosen.push(i);
        }
    }
    chosen
}

/// Searches, for every pair of maps, the later map's queries in the earlier map (and the
/// earlier map's in the later with `both_ways`); returns a
/// closure for each unambiguous fix (status [`ClosureStatus::Inconsistent`] until verification
/// and the consistency check decide).
pub fn find_candidates(
    keyframes: &[Vec<Keyframe>],
    config: &MergeConfig,
    stats: &mut MergeStats,
    timings: &mut StageTimings,
) -> Result<Vec<InterClosure>, SlamError> {
    let c = &config.places;
    let start = Instant::now();
    let queries: Vec<Vec<(usize, Vec<nalgebra::Point2<f64>>)>> = keyframes
        .iter()
        .map(|kfs| {
            query_keyframes(kfs, c.spacing_m)
                .into_iter()
                .map(|q| {
                    let points = submap_points(kfs, q, c.half_keyframes);
                    (q, voxel_downsample(&points, c.voxel_m))
                })
                .filter(|(_, points)| points.len() >= config.icp.min_scan_points)
                .collect()
        })
        .collect();
    timings.record_since("prepare_queries", start);
    let mut closures = Vec::new();
    for (from_map, searched) in keyframes.iter().enumerate() {
        let searched_by = |to_map: usize| to_map > from_map || (c.both_ways && to_map < from_map);
        if !(0..keyframes.len()).any(searched_by) {
            continue;
        }
        let start = Instant::now();
        let search = GlobalSearch::new(searched, config.global_search.clone())?;
        timings.record_since("prepare_search", start);
        for (to_map, map_queries) in queries.iter().enumerate().filter(|(m, _)| searched_by(*m)) {
            for (to_keyframe, points) in map_queries {
                let start = Instant::now();
                stats.queries += 1;
                let outcome = search.search(points);
                timings.record_since("global_search", start);
                let fix = match outcome {
                    GlobalOutcome::Found(fix) => fix,
                    GlobalOutcome::Ambiguous { .. } => {
                        stats.ambiguous += 1;
                        continue;
                    }
                    GlobalOutcome::NotFound(_) => continue,
                };
                stats.found += 1;
                let Some(from_keyframe) = nearest_keyframe(searched, &fix.world_from_base) else {
                    continue;
                };
                let world_from_from = searched[from_keyframe].world_from_base;
                closures.push(InterClosure {
                    from_map,
                    from_keyframe,
                    to_map,
                    to_keyframe: *to_keyframe,
                    from_from_to: world_from_from.inverse() * fix.world_from_base,
                    goodness: fix.goodness,
                    reverse_goodness: None,
                    free_space_conflict: None,
                    status: ClosureStatus::Inconsistent,
                });
            }
        }
    }
    Ok(closures)
}

/// The keyframe whose position is nearest `pose`'s.
fn nearest_keyframe(keyframes: &[Keyframe], pose: &slamkit_core::Pose2) -> Option<usize> {
    let p = pose.translation.vector;
    keyframes
        .iter()
        .enumerate()
        .map(|(i, kf)| ((kf.world_from_base.translation.vector - p).norm(), i))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, i)| i)
}
