//! Offline merging of 2D lidar maps made by different robots (or by one robot on different
//! days), none knowing where the others started: the first half of issue 22's "many robots, one
//! map", without the transport.
//!
//! Four stages, each in its own module:
//! 1. [`places`]: place recognition. Keyframes of one map, a few metres apart, each with its
//!    neighbours in time as a small submap (one scan of a corridor rarely tells where it is,
//!    eleven often do), are searched for in every other map with no prior pose by the global
//!    search of localisation ([`slamkit_lidar::global_search`]: coarse correlative search around
//!    anchors, fine correlative pass, ICP, unambiguous fixes only).
//! 2. [`verify`]: geometric verification the other way round: the submap around the matched
//!    keyframe of the searched map is aligned by ICP into the querying map from the inverse of
//!    the fix; it must fit as well and land on the same relative pose. A query that sees only
//!    part of what the other map holds at that place (a corridor that fits a longer one) fails
//!    here.
//! 3. [`free_space`]: how much of one map's obstacles the closure's alignment puts in the
//!    other's known free space (each map's scans ray-traced into a grid). A corridor seen
//!    driving the other way fits its walls turned by 180° but puts the rooms and corridor ends
//!    seen beyond them in the other map's free space. Measured on every closure; rejecting on
//!    it is off by default (`max_conflict = 1`): on ACES true closures reach 0.036 and the
//!    reversed corridor's 0.043–0.082 (docs/experiments/map-merge.md).
//! 4. [`pcm`]: pairwise consistency maximisation (Mangelson et al., "Pairwise Consistent
//!    Measurement Set Maximization for Robust Multi-robot Map Merging", ICRA 2018): for each pair
//!    of maps, two closures are consistent when they put one map in the other's frame at the same
//!    place, within a tolerance that grows with the distance between them; the largest set of
//!    mutually consistent closures (a maximum clique) is kept, and only when it holds at least
//!    `min_consistent` closures: one match, however good, never merges two maps.
//! 5. [`joint`]: the maps' frames chained along the accepted pairs, then one pose graph of every
//!    keyframe (each map's own edges, the accepted closures with a Cauchy kernel) optimised by
//!    the lidar crate's solver ([`slamkit_lidar::pose_graph`]). The maps joined to the largest
//!    group form the merged map, in the frame of the first of them; the rest are reported as
//!    unmerged, never forced in.
//!
//! Nothing here reads ground truth; the tests score the merge against it.

pub mod free_space;
pub mod joint;
pub mod output;
pub mod pcm;
pub mod places;
pub mod report;
pub mod verify;

use crate::lidar::LidarMap;
use crate::SlamError;
use serde::{Deserialize, Serialize};
use slamkit_core::{Pose2, StageTimings, Trajectory};
use slamkit_lidar::global_search::GlobalSearchConfig;
use slamkit_lidar::icp_slam::IcpSlamConfig;
use slamkit_lidar::point_map::Keyframe;
use std::time::Instant;

/// Settings of a merge.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MergeConfig {
    /// How keyframe scans become points with normals (ranges, normals), as in mapping.
    pub icp: IcpSlamConfig,
    /// Finding a query submap in another map with no prior pose.
    pub global_search: GlobalSearchConfig,
    /// Place recognition: which keyframes query the other maps.
    pub places: places::PlacesConfig,
    /// Geometric verification of each fix.
    pub verify: verify::VerifyConfig,
    /// Free-space consistency of each verified closure.
    pub free_space: free_space::FreeSpaceConfig,
    /// Pairwise consistency among the closures between two maps.
    pub pcm: pcm::PcmConfig,
    /// The joint pose graph.
    pub joint: joint::JointConfig,
}

impl MergeConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), SlamError> {
        self.icp.validate()?;
        self.global_search.validate()?;
        self.places.validate()?;
        self.verify.validate()?;
        self.free_space.validate()?;
        self.pcm.validate()?;
        self.joint.validate()
    }
}

/// What became of a closure found between two maps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ClosureStatus {
    /// In the largest consistent set of its pair of maps, and in the joint graph.
    Accepted,
    /// The reverse alignment did not fit, or landed elsewhere.
    FailedVerification,
    /// Verified, but it puts one map's obstacles in the other's known free space.
    FreeSpaceConflict,
    /// Verified, but not in the largest consistent set of its pair of maps.
    Inconsistent,
    /// In the largest consistent set, but that set was too small to join the two maps.
    TooFewConsistent,
    /// In the largest consistent set, but another set of closures outside it, consistent
    /// among themselves, told a different story almost as strongly.
    Ambiguous,
}

/// A closure between keyframes of two maps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterClosure {
    /// The searched map (index of the input).
    pub from_map: usize,
    /// Its keyframe nearest the fix.
    pub from_keyframe: usize,
    /// The querying map.
    pub to_map: usize,
    /// The query keyframe.
    pub to_keyframe: usize,
    /// Pose of the query keyframe in the frame of the searched one.
    pub from_from_to: Pose2,
    /// ICP goodness of the fix against the whole searched map, in \[0, 1\].
    pub goodness: f64,
    /// ICP goodness of the reverse alignment (`None`: it failed to run).
    pub reverse_goodness: Option<f64>,
    /// Fraction of the two maps' points near the closure, moved by it into the other map's
    /// known cells, that land in its known free space (`None`: not checked).
    pub free_space_conflict: Option<f64>,
    /// What became of it.
    pub status: ClosureStatus,
}

/// How one input came out of the merge.
#[derive(Debug, Clone, PartialEq)]
pub struct MergedInput {
    /// `merged_from_input`: where the input's map frame lies in the merged map (`None`:
    /// unmerged).
    pub merged_from_input: Option<Pose2>,
    /// Index of the input's first keyframe in the merged map (`None`: unmerged).
    pub keyframe_offset: Option<usize>,
    /// Every scan of the input's runs in the merged frame, following the jointly optimised
    /// keyframes (`None`: unmerged).
    pub trajectory: Option<Trajectory>,
}

/// Counters of a merge.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct MergeStats {
    /// Global searches run (query submaps times maps searched).
    pub queries: usize,
    /// Searches that found their submap unambiguously.
    pub found: usize,
    /// Searches whose best pose had a distinct rival.
    pub ambiguous: usize,
    /// Fixes the reverse alignment confirmed.
    pub verified: usize,
    /// Closures in the joint graph.
    pub accepted: usize,
    /// Inputs in the merged map.
    pub merged_inputs: usize,
}

/// The result of [`merge_maps`].
#[derive(Debug, Clone)]
pub struct MergeOutcome {
    /// The merged map: the merged inputs' keyframes at their jointly optimised poses, in input
    /// order, their edges and the accepted closures as edges, every scan of their runs.
    pub map: LidarMap,
    /// One entry per input, in input order.
    pub inputs: Vec<MergedInput>,
    /// Every closure found, whatever became of it.
    pub closures: Vec<InterClosure>,
    /// Counters.
    pub stats: MergeStats,
    /// The joint optimisation (`None` when fewer than two inputs merged).
    pub optimisation: Option<slamkit_lidar::pose_graph::OptimizeSummary>,
    /// Time per stage.
    pub timings: StageTimings,
}

impl MergeOutcome {
    /// Indices of the inputs left out of the merged map.
    pub fn unmerged(&self) -> Vec<usize> {
        (0..self.inputs.len())
            .filter(|&i| self.inputs[i].merged_from_input.is_none())
            .collect()
    }
}

/// Merges 2D lidar maps whose relative poses are unknown.
///
/// ```
/// use slamkit_core::Pose2;
/// use slamkit_slam::merge::{merge_maps, MergeConfig};
/// # use slamkit_slam::lidar::LidarMap;
/// # fn maps() -> Vec<LidarMap> { Vec::new() }
/// let maps = maps();
/// // fewer than two maps is an error, not an empty merge
/// assert!(merge_maps(&maps, &MergeConfig::default()).is_err());
/// ```
///
/// # Errors
/// [`SlamError::Map`] for fewer than two maps or a map without keyframes, and
/// [`SlamError::Config`] / [`SlamError::Lidar`] for settings out of range.
pub fn merge_maps(maps: &[LidarMap], config: &MergeConfig) -> Result<MergeOutcome, SlamError> {
    config.validate()?;
    if maps.len() < 2 {
        return Err(SlamError::Map(format!(
            "a merge needs at least two maps, got {}",
            maps.len()
        )));
    }
    if let Some(i) = maps.iter().position(|m| m.keyframes.is_empty()) {
        return Err(SlamError::Map(format!("map {} holds no keyframe", i + 1)));
    }
    let mut timings = StageTimings::default();
    let start = Instant::now();
    let keyframes: Vec<Vec<Keyframe>> = maps
        .iter()
        .map(|m| m.matcher_keyframes(&config.icp))
        .collect();
    timings.record_since("prepare_keyframes", start);
    let mut stats = MergeStats::default();
    let mut closures = places::find_candidates(&keyframes, config, &mut stats, &mut timings)?;
    let start = Instant::now();
    verify::verify_all(&keyframes, &mut closures, &config.verify);
    timings.record_since("verify", start);
    let start = Instant::now();
    free_space::check_all(maps, &keyframes, &mut closures, &config.free_space)?;
    timings.record_since("free_space", start);
    let start = Instant::now();
    let pairs = pcm::select(&keyframes, &mut closures, &config.pcm);
    timings.record_since("pcm", start);
    let start = Instant::now();
    let joined = joint::join(maps, &closures, &pairs, &config.joint);
    timings.record_since("joint_optimisation", start);
    stats.verified = closures
        .iter()
        .filter(|c| c.status != ClosureStatus::FailedVerification)
        .count();
    stats.accepted = closures
        .iter()
        .filter(|c| c.status == ClosureStatus::Accepted)
        .count();
    stats.merged_inputs = joined
        .inputs
        .iter()
        .filter(|i| i.merged_from_input.is_some())
        .count();
    Ok(MergeOutcome {
        map: joined.map,
        inputs: joined.inputs,
        closures,
        stats,
        optimisation: joined.optimisation,
        timings,
    })
}

/// The points of keyframes `centre − half ..= centre + half` of `keyframes` in the base frame
/// of keyframe `centre`: one keyframe and its neighbours in time as one view of a place.
pub(crate) fn submap_points(
    keyframes: &[Keyframe],
    centre: usize,
    half: usize,
) -> Vec<nalgebra::Point2<f64>> {
    let Some(centre_kf) = keyframes.get(centre) else {
        return Vec::new();
    };
    let centre_from_world = centre_kf.world_from_base.inverse();
    let last = (centre + half + 1).min(keyframes.len());
    keyframes[centre.saturating_sub(half)..last]
        .iter()
        .flat_map(|kf| {
            let centre_from_base = centre_from_world * kf.world_from_base;
            kf.points.iter().map(move |p| centre_from_base * p)
        })
        .collect()
}

#[cfg(test)]
mod tests;
