//! Global localisation in a keyframe map: where in a known map is the robot, with no prior
//! pose at all? (A robot switched on in a building it mapped last week; a robot that lost
//! track.)
//!
//! The map's keyframes are thinned to anchors a few metres apart, so every place the robot
//! can stand in the mapped area is within reach of one. Around each anchor, a correlative
//! search (Olson 2009, with the branch and bound of [`crate::correlative`]) at a coarse
//! resolution tries every heading and every position in a window as wide as the anchor spacing;
//! as Hess et al. (ICRA 2016) do for their global constraint search, a coarse exhaustive
//! search replaces any guess. The best few distinct coarse poses are refined by a fine
//! correlative pass and point-to-line ICP against the whole map, and the best is accepted only
//! when its ICP goodness is high and no other distinct pose comes close: in a building of
//! identical offices one scan cannot tell which office, and a wrong fix is worse than waiting
//! for the robot to move somewhere telling.

use crate::cloud::voxel_downsample;
use crate::correlative::{correlative_match, CorrelativeConfig, LikelihoodField};
use crate::error::check_fields;
use crate::icp::{align, IcpConfig};
use crate::nn::GridIndex;
use crate::point_map::{index_keyframes, Keyframe};
use crate::LidarError;
use nalgebra::Point2;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use slamkit_core::Pose2;
use std::sync::OnceLock;

/// Global search parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GlobalSearchConfig {
    /// Keyframes closer than this to an anchor are covered by it \[m\].
    pub anchor_spacing_m: f64,
    /// How far from the mapping run's path the robot may stand \[m\]: each anchor's
    /// translation window reaches `anchor_spacing_m + off_path_m`.
    pub off_path_m: f64,
    /// The full turn is searched in this many sectors, each keeping its best pose, so that
    /// the turns a symmetric room allows are all refined and compared (>= 1).
    pub heading_sectors: usize,
    /// Beams longer than this are left out of the search (long beams make the rotation steps
    /// fine and the search slow) \[m\].
    pub max_range_m: f64,
    /// Voxel size for thinning the scan before the coarse search \[m\].
    pub search_voxel_m: f64,
    /// Cell size of the coarse search \[m\].
    pub coarse_resolution_m: f64,
    /// The fine correlative pass around each refined candidate.
    pub fine: CorrelativeConfig,
    /// Coarse candidates refined, best coarse score first.
    pub refine_candidates: usize,
    /// Voxel size of the map the refinement matches against \[m\].
    pub map_voxel_m: f64,
    /// Final alignment.
    pub icp: IcpConfig,
    /// Lowest ICP goodness for a fix, in \[0, 1\].
    pub min_goodness: f64,
    /// A fix is ambiguous when a distinct pose reaches a goodness within this of the best.
    pub ambiguity_margin: f64,
    /// Poses farther apart than this are distinct \[m\]...
    pub distinct_m: f64,
    /// ...or turned by more than this \[rad\].
    pub distinct_rad: f64,
}

impl Default for GlobalSearchConfig {
    fn default() -> Self {
        Self {
            anchor_spacing_m: 2.0,
            off_path_m: 1.0,
            heading_sectors: 4,
            max_range_m: 10.0,
            search_voxel_m: 0.3,
            coarse_resolution_m: 0.3,
            fine: CorrelativeConfig {
                linear_window_m: 0.4,
                angular_window_rad: 4f64.to_radians(),
                resolution_m: 0.05,
                sigma_m: 0.05,
                ..CorrelativeConfig::default()
            },
            refine_candidates: 6,
            map_voxel_m: 0.05,
            icp: IcpConfig::default(),
            min_goodness: 0.8,
            ambiguity_margin: 0.05,
            distinct_m: 1.0,
            distinct_rad: 30f64.to_radians(),
        }
    }
}

impl GlobalSearchConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), LidarError> {
        self.icp.validate()?;
        let positive = |name, v: f64| (name, v, v > 0.0);
        check_fields(
            [
                positive("anchor_spacing_m", self.anchor_spacing_m),
                ("off_path_m", self.off_path_m, self.off_path_m >= 0.0),
                (
                    "heading_sectors",
                    self.heading_sectors as f64,
                    self.heading_sectors >= 1,
                ),
                positive("max_range_m", self.max_range_m),
                positive("search_voxel_m", self.search_voxel_m),
                positive("coarse_resolution_m", self.coarse_resolution_m),
                positive("map_voxel_m", self.map_voxel_m),
                positive("distinct_m", self.distinct_m),
                positive("distinct_rad", self.distinct_rad),
                (
                    "min_goodness",
                    self.min_goodness,
                    (0.0..=1.0).contains(&self.min_goodness),
                ),
                (
                    "ambiguity_margin",
                    self.ambiguity_margin,
                    self.ambiguity_margin >= 0.0,
                ),
            ],
            "out of range",
        )
    }
}

/// A pose the search refined.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// `world_from_base`.
    pub world_from_base: Pose2,
    /// ICP goodness against the whole map, in \[0, 1\].
    pub goodness: f64,
}

/// What a search concluded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GlobalOutcome {
    /// One pose fits well and no distinct one comes close.
    Found(Candidate),
    /// The best pose fits, but so does a distinct one: wait for a more telling view.
    Ambiguous {
        /// The best pose.
        best: Candidate,
        /// The best distinct one.
        runner_up: Candidate,
    },
    /// Nothing fits well enough (the robot is outside the map, or the view is blocked).
    NotFound(Option<Candidate>),
}

/// A keyframe map prepared for global searches.
pub struct GlobalSearch {
    config: GlobalSearchConfig,
    anchors: Vec<Pose2>,
    /// Each anchor's coarse likelihood field, built at the first search and kept: the map does
    /// not change between queries (building them at every query took about 15 % of the
    /// global search in the Intel merge test). `None` when the anchor's field cannot be built.
    fields: Vec<OnceLock<Option<LikelihoodField>>>,
    coarse_points: Vec<Point2<f64>>,
    index: GridIndex,
}

impl GlobalSearch {
    /// Prepares `keyframes` (poses in the map frame, points and normals in their base frames).
    pub fn new(keyframes: &[Keyframe], config: GlobalSearchConfig) -> Result<Self, LidarError> {
        config.validate()?;
        let index = index_keyframes(keyframes, config.map_voxel_m);
        let coarse_points = voxel_downsample(
            crate::nn::NearestNeighbours::points(&index),
            config.coarse_resolution_m / 2.0,
        );
        let mut anchors: Vec<Pose2> = Vec::new();
        for kf in keyframes {
            let p = kf.world_from_base.translation.vector;
            let covered = anchors
                .iter()
                .any(|a| (a.translation.vector - p).norm() < config.anchor_spacing_m);
            if !covered {
                anchors.push(kf.world_from_base);
            }
        }
        Ok(Self {
            config,
            fields: anchors.iter().map(|_| OnceLock::new()).collect(),
            anchors,
            coarse_points,
            index,
        })
    }

    /// Anchors the coarse search is centred on.
    pub fn anchors(&self) -> usize {
        self.anchors.len()
    }

    /// Bytes held by the anchors' coarse likelihood fields built so far (each is built at the
    /// first search and kept).
    pub fn field_bytes(&self) -> usize {
        self.fields
            .iter()
            .filter_map(|f| f.get().and_then(Option::as_ref))
            .map(LikelihoodField::bytes)
            .sum()
    }

    /// The coarse correlative search around each anchor: one sector of headings each side of
    /// a sector's centre, a window as wide as the anchor spacing plus the way off the path.
    fn coarse_config(&self) -> CorrelativeConfig {
        let c = &self.config;
        CorrelativeConfig {
            linear_window_m: c.anchor_spacing_m + c.off_path_m,
            angular_window_rad: self.sector_rad() / 2.0,
            resolution_m: c.coarse_resolution_m,
            sigma_m: c.coarse_resolution_m,
            max_angular_step_rad: 2f64.to_radians(),
            ..c.fine.clone()
        }
    }

    fn sector_rad(&self) -> f64 {
        2.0 * std::f64::consts::PI / self.config.heading_sectors.max(1) as f64
    }

    /// Anchor `k`'s coarse field, built at the first call: a square around the anchor on a
    /// lattice fixed by the anchor alone (so scores do not depend on the query), wide enough for
    /// any query, whose points all lie within `max_range_m`.
    fn field(&self, k: usize, coarse: &CorrelativeConfig) -> Option<&LikelihoodField> {
        let anchor = self.anchors.get(k)?;
        self.fields
            .get(k)?
            .get_or_init(|| {
                let centre = anchor.translation.vector;
                let half = LikelihoodField::half_m_for_reach(self.config.max_range_m, coarse);
                // the points whose field (3σ, rounded out to whole cells) reaches the square
                let margin = half + 4.0 * coarse.sigma_m + coarse.resolution_m;
                let target: Vec<Point2<f64>> = self
                    .coarse_points
                    .iter()
                    .filter(|p| (p.coords - centre).amax() < margin)
                    .copied()
                    .collect();
                LikelihoodField::square(&target, &centre, half, coarse).ok()
            })
            .as_ref()
    }

    /// Searches the whole map for the pose of a scan whose usable points (base frame) are
    /// `points`.
    pub fn search(&self, points: &[Point2<f64>]) -> GlobalOutcome {
        let c = &self.config;
        let near: Vec<Point2<f64>> = points
            .iter()
            .filter(|p| p.coords.norm() < c.max_range_m)
            .copied()
            .collect();
        let source = voxel_downsample(&near, c.search_voxel_m);
        let sector_rad = self.sector_rad();
        let coarse = self.coarse_config();
        let mut coarse_hits: Vec<(f64, Pose2)> = self
            .anchors
            .par_iter()
            .enumerate()
            .flat_map_iter(|(k, anchor)| {
                let centre = anchor.translation.vector;
                // One likelihood field for every sector (each heading a pose's own angle).
                let headings: Vec<f64> = (0..c.heading_sectors.max(1))
                    .map(|s| Pose2::new(centre, s as f64 * sector_rad).rotation.angle())
                    .collect();
                self.field(k, &coarse)
                    .and_then(|field| field.match_headings(&source, &centre, &headings).ok())
                    .unwrap_or_default()
                    .into_iter()
                    .map(|hit| (hit.score, hit.target_from_source))
            })
            .collect();
        coarse_hits.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut seeds: Vec<Pose2> = Vec::new();
        for (_, pose) in coarse_hits {
            if seeds.len() >= c.refine_candidates {
                break;
            }
            if !seeds.iter().any(|s| !self.distinct(s, &pose)) {
                seeds.push(pose);
            }
        }
        let mut refined: Vec<Candidate> = seeds
            .par_iter()
            .filter_map(|seed| self.refine(&near, seed))
            .collect();
        refined.sort_by(|a, b| b.goodness.total_cmp(&a.goodness));
        let Some(&best) = refined.first() else {
            return GlobalOutcome::NotFound(None);
        };
        if best.goodness < c.min_goodness {
            return GlobalOutcome::NotFound(Some(best));
        }
        let runner_up = refined.iter().skip(1).find(|r| {
            self.distinct(&r.world_from_base, &best.world_from_base)
                && r.goodness >= best.goodness - c.ambiguity_margin
        });
        match runner_up {
            Some(&runner_up) => GlobalOutcome::Ambiguous { best, runner_up },
            None => GlobalOutcome::Found(best),
        }
    }

    /// A fine correlative pass then ICP against the whole map, from `seed`.
    fn refine(&self, points: &[Point2<f64>], seed: &Pose2) -> Option<Candidate> {
        let c = &self.config;
        let reach = c.max_range_m + c.fine.linear_window_m + 1.0;
        let centre = seed.translation.vector;
        let target: Vec<Point2<f64>> = crate::nn::NearestNeighbours::points(&self.index)
            .iter()
            .filter(|p| (p.coords - centre).norm() < reach)
            .copied()
            .collect();
        let fine = correlative_match(
            &voxel_downsample(points, c.fine.resolution_m),
            &target,
            seed,
            &c.fine,
        )
        .ok()?;
        let fit = align(points, &self.index, &fine.target_from_source, &c.icp).ok()?;
        Some(Candidate {
            world_from_base: fit.target_from_source,
            goodness: fit.goodness,
        })
    }

    fn distinct(&self, a: &Pose2, b: &Pose2) -> bool {
        let d = a.inverse() * b;
        d.translation.vector.norm() > self.config.distinct_m
            || d.rotation.angle().abs() > self.config.distinct_rad
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::{estimate_normals, scan_points};
    use crate::sim_scan::SegmentWorld;
    use nalgebra::Vector2;

    fn keyframe(world: &SegmentWorld, pose: Pose2) -> Keyframe {
        let scan = world.scan(&pose, 360, 2.0 * std::f64::consts::PI - 0.01, 20.0);
        let points = scan_points(&scan, 0.1, 20.0);
        let normals = estimate_normals(&points, 6, 0.5, 0.2);
        Keyframe {
            world_from_base: pose,
            points,
            normals,
        }
    }

    #[test]
    fn finds_an_unseen_pose_in_an_asymmetric_room_from_nothing() {
        let world = SegmentWorld::room();
        let keyframes: Vec<Keyframe> = (0..12)
            .map(|i| {
                let x = -5.0 + i as f64;
                keyframe(
                    &world,
                    Pose2::new(Vector2::new(x, -2.5 + 0.3 * i as f64), 0.0),
                )
            })
            .collect();
        let search = GlobalSearch::new(&keyframes, GlobalSearchConfig::default()).unwrap();
        assert!(search.anchors() < keyframes.len());
        let truth = Pose2::new(Vector2::new(0.3, 0.0), 2.4);
        let scan = world.scan(&truth, 360, 2.0 * std::f64::consts::PI - 0.01, 20.0);
        let points = scan_points(&scan, 0.1, 20.0);
        assert_eq!(
            search.field_bytes(),
            0,
            "the fields are built at the first search"
        );
        let GlobalOutcome::Found(fix) = search.search(&points) else {
            panic!("not found: {:?}", search.search(&points));
        };
        let bytes = search.field_bytes();
        assert!(bytes > 0);
        // the second search reads the kept fields and finds the same
        assert_eq!(search.search(&points), GlobalOutcome::Found(fix));
        assert_eq!(search.field_bytes(), bytes);
        let err = truth.inverse() * fix.world_from_base;
        assert!(err.translation.vector.norm() < 0.03, "{err:?}");
        assert!(err.rotation.angle().abs() < 0.01, "{err:?}");
    }

    #[test]
    fn a_square_room_is_ambiguous_and_open_space_is_not_found() {
        // Four walls, 6 × 6 m: every quarter turn fits as well.
        let world = SegmentWorld::polygon(&[(-3.0, -3.0), (3.0, -3.0), (3.0, 3.0), (-3.0, 3.0)]);
        let keyframes = vec![keyframe(&world, Pose2::new(Vector2::new(0.0, 0.0), 0.0))];
        let search = GlobalSearch::new(&keyframes, GlobalSearchConfig::default()).unwrap();
        let scan = world.scan(
            &Pose2::new(Vector2::new(0.0, 0.0), 0.3),
            360,
            2.0 * std::f64::consts::PI - 0.01,
            20.0,
        );
        let outcome = search.search(&scan_points(&scan, 0.1, 20.0));
        assert!(
            matches!(outcome, GlobalOutcome::Ambiguous { .. }),
            "{outcome:?}"
        );
        // a corridor seen from elsewhere does not fit the room
        let corridor = SegmentWorld {
            segments: vec![
                (Point2::new(-10.0, -0.8), Point2::new(10.0, -0.8)),
                (Point2::new(-10.0, 0.8), Point2::new(10.0, 0.8)),
            ],
        };
        let scan = corridor.scan(&Pose2::identity(), 360, 6.0, 20.0);
        let outcome = search.search(&scan_points(&scan, 0.1, 20.0));
        assert!(matches!(outcome, GlobalOutcome::NotFound(_)), "{outcome:?}");
    }
    /// Time of global searches on the Intel log: keyframes every 10th of the first 1500 scans
    /// at their odometry poses, queried with 11-scan submaps from further on. A measurement
    /// (`cargo test --release -p slamkit-lidar --lib global_search_time -- --ignored
    /// --nocapture`), not a check.
    #[test]
    #[ignore]
    fn global_search_time_on_intel() {
        let Some(path) = slamkit_testdata::data(
            "global_search_time_on_intel",
            "lidar2d/intel/intel.fromrosbag.clf.gz",
        ) else {
            return;
        };
        let log = slamkit_io::carmen::read_carmen(&path).unwrap();
        let keyframe = |k: usize| {
            let scan = &log.scans[k];
            let points = scan_points(scan, 0.1, 20.0);
            let normals = estimate_normals(&points, 6, 0.5, 0.2);
            Keyframe {
                world_from_base: scan.odometry.unwrap_or_else(Pose2::identity),
                points,
                normals,
            }
        };
        let keyframes: Vec<Keyframe> = (0..1500).step_by(10).map(keyframe).collect();
        let search = GlobalSearch::new(&keyframes, GlobalSearchConfig::default()).unwrap();
        let start = std::time::Instant::now();
        let mut outcomes = Vec::new();
        for q in (1600..2400).step_by(100) {
            let centre = log.scans[q].odometry.unwrap_or_else(Pose2::identity);
            let points: Vec<Point2<f64>> = (q - 50..=q + 50)
                .step_by(10)
                .flat_map(|k| {
                    let odom = log.scans[k].odometry.unwrap_or_else(Pose2::identity);
                    let rel = centre.inverse() * odom;
                    scan_points(&log.scans[k], 0.1, 20.0)
                        .into_iter()
                        .map(move |p| rel * p)
                })
                .collect();
            let points = voxel_downsample(&points, 0.05);
            outcomes.push(search.search(&points));
        }
        eprintln!(
            "{} anchors, {} searches in {:.2} s: {outcomes:?}",
            search.anchors(),
            outcomes.len(),
            start.elapsed().as_secs_f64()
        );
    }
}
