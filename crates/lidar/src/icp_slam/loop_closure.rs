//! Loop closure for ICP-SLAM: a new keyframe is matched against old keyframes near its
//! estimated pose, and a match becomes a pose-graph edge (the constraint search of Hess et al.,
//! ICRA 2016, with the correlative search of Olson 2009 for the coarse pose and point-to-line
//! ICP for the fine one).
//!
//! The old keyframe and its neighbours in time form a small submap, so one wall seen at a
//! grazing angle in one scan does not decide the match. The search window has to hold the drift
//! accumulated since the last closure; closures are tried often enough that it stays small.

use crate::cloud::voxel_downsample;
use crate::correlative::{correlative_match, CorrelativeConfig};
use crate::error::check_fields;
use crate::icp::{align, IcpConfig, IcpResult};
use crate::nn::{GridIndex, NearestNeighbours};
use crate::point_map::{index_keyframes, Keyframe};
use crate::LidarError;
use nalgebra::Point2;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use slamkit_core::Pose2;

/// Loop-closure parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LoopClosureConfig {
    /// Search for loop closures at all.
    pub enabled: bool,
    /// Try a closure at every N-th keyframe (>= 1).
    pub every_keyframes: usize,
    /// Old keyframes within this distance of the new one are candidates \[m\].
    pub search_radius_m: f64,
    /// Keyframes this recent are not candidates (the local map already holds them).
    pub min_separation_keyframes: usize,
    /// Candidates tried per attempt, nearest first.
    pub max_candidates: usize,
    /// The submap around a candidate holds this many keyframes on each side of it.
    pub submap_half_keyframes: usize,
    /// Voxel size for thinning the new keyframe before the correlative search \[m\].
    pub search_voxel_m: f64,
    /// Beams longer than this are left out of the match \[m\].
    pub max_range_m: f64,
    /// Search around the estimated pose, at the resolution of the final coarse pose.
    pub correlative: CorrelativeConfig,
    /// The translation window grows by this fraction of the distance travelled since the last
    /// closure (the drift odometry and scan matching may have gathered), so long open loops are
    /// still found.
    pub window_growth: f64,
    /// The largest translation window \[m\].
    pub max_window_m: f64,
    /// Cell size of the wide first pass when the window is wider than `correlative`'s \[m\].
    pub wide_resolution_m: f64,
    /// Lowest correlative score (mean likelihood) worth refining, in \[0, 1\].
    pub min_score: f64,
    /// Fine alignment.
    pub icp: IcpConfig,
    /// Lowest ICP goodness for a closure to be accepted, in \[0, 1\].
    pub min_goodness: f64,
    /// Standard deviation of the translation of every edge (consecutive keyframes and closures)
    /// \[m\].
    pub edge_sigma_m: f64,
    /// Standard deviation of the rotation of every edge \[rad\].
    pub edge_sigma_rad: f64,
    /// Cauchy kernel scale on a closure's Mahalanobis error (in standard deviations).
    pub robust_scale: f64,
    /// Gauss–Newton iterations after each closure.
    pub optimize_iterations: usize,
}

impl Default for LoopClosureConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            every_keyframes: 2,
            search_radius_m: 3.0,
            min_separation_keyframes: 100,
            max_candidates: 3,
            submap_half_keyframes: 15,
            search_voxel_m: 0.1,
            max_range_m: 15.0,
            correlative: CorrelativeConfig {
                linear_window_m: 1.0,
                angular_window_rad: 15f64.to_radians(),
                resolution_m: 0.1,
                sigma_m: 0.1,
                ..CorrelativeConfig::default()
            },
            window_growth: 0.05,
            max_window_m: 10.0,
            wide_resolution_m: 0.25,
            min_score: 0.3,
            icp: IcpConfig::default(),
            min_goodness: 0.8,
            edge_sigma_m: 0.02,
            edge_sigma_rad: 0.5f64.to_radians(),
            robust_scale: 3.0,
            optimize_iterations: 10,
        }
    }
}

impl LoopClosureConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), LidarError> {
        self.icp.validate()?;
        let checks = [
            (
                "every_keyframes",
                self.every_keyframes as f64,
                self.every_keyframes >= 1,
            ),
            (
                "search_radius_m",
                self.search_radius_m,
                self.search_radius_m >= 0.0,
            ),
            (
                "search_voxel_m",
                self.search_voxel_m,
                self.search_voxel_m >= 0.0,
            ),
            ("max_range_m", self.max_range_m, self.max_range_m > 0.0),
            (
                "window_growth",
                self.window_growth,
                self.window_growth >= 0.0,
            ),
            ("max_window_m", self.max_window_m, self.max_window_m >= 0.0),
            (
                "wide_resolution_m",
                self.wide_resolution_m,
                self.wide_resolution_m > 0.0,
            ),
            (
                "min_score",
                self.min_score,
                (0.0..=1.0).contains(&self.min_score),
            ),
            (
                "min_goodness",
                self.min_goodness,
                (0.0..=1.0).contains(&self.min_goodness),
            ),
            ("edge_sigma_m", self.edge_sigma_m, self.edge_sigma_m > 0.0),
            (
                "edge_sigma_rad",
                self.edge_sigma_rad,
                self.edge_sigma_rad > 0.0,
            ),
            ("robust_scale", self.robust_scale, self.robust_scale > 0.0),
        ];
        check_fields(checks, "out of range")
    }
}

/// An accepted loop closure: the pose of keyframe `to` measured in the frame of keyframe `from`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closure {
    /// The old keyframe.
    pub from: usize,
    /// The new keyframe.
    pub to: usize,
    /// Pose of `to` in the frame of `from`.
    pub from_from_to: Pose2,
    /// ICP goodness of the match.
    pub goodness: f64,
}

/// Searches old keyframes near the newest one (the last of `keyframes`) for loop closures;
/// `open_distance_m` is the distance travelled since the last closure.
pub fn find_closures(
    keyframes: &[Keyframe],
    open_distance_m: f64,
    config: &LoopClosureConfig,
) -> Vec<Closure> {
    let Some((to, newest)) = keyframes.iter().enumerate().next_back() else {
        return Vec::new();
    };
    let pose = newest.world_from_base;
    let window = search_window(open_distance_m, config);
    let old = to.saturating_sub(config.min_separation_keyframes);
    let reach = candidate_reach(window, config);
    let mut candidates: Vec<(f64, usize)> = keyframes
        .get(..old)
        .unwrap_or_default()
        .iter()
        .enumerate()
        .map(|(j, kf)| {
            let d = kf.world_from_base.translation.vector - pose.translation.vector;
            (d.norm(), j)
        })
        .filter(|(d, _)| *d <= reach)
        .collect();
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
    let source = SearchSource::new(&newest.points, config);
    candidates.truncate(config.max_candidates);
    // Candidates are independent: search them in parallel; `collect` keeps their order, so
    // the result does not depend on the thread count.
    candidates
        .into_par_iter()
        .filter_map(|(_, from)| {
            let submap = submap(keyframes, from, old, config)?;
            let fine = match_submap(&source, &submap, &pose, window, config)?;
            let world_from_from = keyframes.get(from)?.world_from_base;
            Some(Closure {
                from,
                to,
                from_from_to: world_from_from.inverse() * fine.target_from_source,
                goodness: fine.goodness,
            })
        })
        .collect()
}

/// Half-width of the translation window of a search after `open_distance_m` of travel since
/// the last closure \[m\]: the fine window grown by `window_growth` of that distance, at most
/// `max_window_m`.
pub fn search_window(open_distance_m: f64, config: &LoopClosureConfig) -> f64 {
    let fine_window = config.correlative.linear_window_m;
    (fine_window + config.window_growth * open_distance_m)
        .min(config.max_window_m)
        .max(fine_window)
}

/// Old keyframes this close to the estimated pose are candidates for a search with
/// translation window `window` \[m\].
pub fn candidate_reach(window: f64, config: &LoopClosureConfig) -> f64 {
    config.search_radius_m + window - config.correlative.linear_window_m
}

/// A scan's points prepared for [`match_submap`]: beams beyond `max_range_m` left out, and a
/// voxel-thinned copy for the correlative search.
pub struct SearchSource {
    points: Vec<Point2<f64>>,
    coarse: Vec<Point2<f64>>,
}

impl SearchSource {
    /// `points` (base frame) prepared for a search with `config`.
    pub fn new(points: &[Point2<f64>], config: &LoopClosureConfig) -> Self {
        let points: Vec<Point2<f64>> = points
            .iter()
            .filter(|p| p.coords.norm() < config.max_range_m)
            .copied()
            .collect();
        let coarse = voxel_downsample(&points, config.search_voxel_m);
        Self { points, coarse }
    }
}

/// Matches `source` against `submap` (world frame) within `window` \[m\] of `pose` (the
/// source's estimated `world_from_base`): a wide correlative pass when `window` is wider than
/// the fine one, a fine correlative pass, then ICP. The ICP result (`target_from_source` is the
/// corrected world pose) when every stage reaches its minimum score.
pub fn match_submap(
    source: &SearchSource,
    submap: &GridIndex,
    pose: &Pose2,
    window: f64,
    config: &LoopClosureConfig,
) -> Option<IcpResult> {
    let guess = if window > config.correlative.linear_window_m {
        let wide = CorrelativeConfig {
            linear_window_m: window,
            resolution_m: config.wide_resolution_m,
            sigma_m: config.wide_resolution_m,
            ..config.correlative.clone()
        };
        correlative_match(&source.coarse, submap.points(), pose, &wide)
            .ok()
            .filter(|c| c.score >= config.min_score)?
            .target_from_source
    } else {
        *pose
    };
    let coarse = correlative_match(&source.coarse, submap.points(), &guess, &config.correlative)
        .ok()
        .filter(|c| c.score >= config.min_score)?;
    align(
        &source.points,
        submap,
        &coarse.target_from_source,
        &config.icp,
    )
    .ok()
    .filter(|r| r.goodness >= config.min_goodness)
}

/// The keyframes around `centre` (older than `end`) in one point map, world frame.
fn submap(
    keyframes: &[Keyframe],
    centre: usize,
    end: usize,
    config: &LoopClosureConfig,
) -> Option<GridIndex> {
    let first = centre.saturating_sub(config.submap_half_keyframes);
    let last = (centre + config.submap_half_keyframes + 1).min(end);
    let index = index_keyframes(keyframes.get(first..last)?, config.correlative.resolution_m);
    (index.len() >= config.icp.min_correspondences).then_some(index)
}
