//! Many robots, one map, offline (issue 22): a Freiburg benchmark log cut into three
//! consecutive parts, each mapped on its own from the origin (so the parts' relative poses are
//! unknown), saved as a map file and merged with `slamkit_slam::merge`. Scored with the log's
//! relations over all three parts' trajectories in the merged frame, against the uninterrupted
//! mapping run of the whole log (issue: within 1.5×), and every accepted closure and every cut
//! point checked against that run (a closure is wrong when the run disagrees by more than
//! 0.3 m or 5°; the parts' relative poses at the cuts within 0.3 m and 10°). A part of another
//! building merged with the three parts is left out. Logs: `$SLAMKIT_DATA/lidar2d/SOURCES.md`.
//! Skipped when `SLAMKIT_DATA` is not set; run with `--release`.
//!
//! Intel meets the bound. ACES and MIT CSAIL do not yet: their parts' global searches
//! mostly score below the search's 0.8 goodness (ACES: true places at 0.65–0.8), so too few
//! closures are found to join every part; at 0.6 ACES joined one pair rightly and another by
//! four mutually consistent closures of a corridor seen the other way round (BENCHMARKS.md).
//! Their tests hold what stands: no wrong closure accepted, and the parts that merge are placed
//! right at their cuts. Every verified closure is printed with its free-space conflict and its
//! error against the uninterrupted run (docs/experiments/map-merge.md).
//!
//! CI time: Intel's parts are merged once, with the part of ACES among them, rather than once
//! alone and again with it (the second merge searched every Intel pair again), ACES's parts
//! are mapped once for both tests that use it, and the uninterrupted run is the one
//! `lidar_lifecycle` uses too, with each log's first part its map file at the first cut
//! ([`crate::benchmark_log::uninterrupted`]; docs/experiments/ci-time.md).

use crate::benchmark_log::{uninterrupted, Log};
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{LaserScan, Pose2, Trajectory};
use slamkit_eval::relations::GroundTruthRelation;
use slamkit_slam::lidar::LidarMap;
use slamkit_slam::merge::{merge_maps, ClosureStatus, InterClosure, MergeConfig, MergeOutcome};
use slamkit_slam::{LidarSlam, LidarSlamConfig, Session};
use std::path::Path;
use std::sync::OnceLock;
use std::time::Instant;

fn map(scans: &[LaserScan]) -> LidarSlam {
    let mut session = LidarSlam::new(LidarSlamConfig::default(), Pose2::identity()).unwrap();
    for scan in scans {
        session.push_scan(scan.clone());
    }
    session
}

/// Mean translational relations error over the relations whose both ends `trajectory` holds.
fn error(relations: &[GroundTruthRelation], trajectory: &Trajectory) -> f64 {
    slamkit_eval::relations_error(relations, trajectory)
        .unwrap()
        .trans_mean
}

/// The pose of the scan at time `t` (exactly) in `trajectory`.
fn pose_at(trajectory: &Trajectory, t: f64) -> Pose2 {
    let p = trajectory
        .poses
        .iter()
        .find(|p| p.timestamp == t)
        .unwrap_or_else(|| panic!("no pose at {t}"));
    pose3_to_pose2(&p.pose)
}

fn differ(a: &Pose2, b: &Pose2) -> (f64, f64) {
    let d = a.inverse() * b;
    (
        d.translation.vector.norm(),
        d.rotation.angle().abs().to_degrees(),
    )
}

/// Saves and reloads the map of a part mapped by `session`; returns it with the part's
/// relations error alone.
fn part(session: &LidarSlam, log: &Log, path: &Path) -> (LidarMap, f64) {
    session.save(path).unwrap();
    (
        LidarMap::load(path).unwrap().0,
        error(&log.relations, &session.trajectory()),
    )
}

/// A log mapped whole and in three parts.
struct Mapped {
    log: &'static Log,
    /// The uninterrupted run's trajectory.
    full: &'static Trajectory,
    /// The parts' maps, saved and reloaded.
    maps: Vec<LidarMap>,
    /// Each part's relations error alone \[m\].
    errors: Vec<f64>,
}

fn mapped(test: &str, name: &str) -> Option<Mapped> {
    let start = Instant::now();
    let whole = uninterrupted(test, name)?;
    let log = &whole.log;
    let dir = tempfile::tempdir().unwrap();
    // The uninterrupted run after the first cut is the first part mapped alone (the same scans
    // from the same start): that part is its map file there rather than mapped a second time.
    let first = &whole.third;
    let path = dir.path().join("part0.skmap");
    std::fs::write(&path, &first.file).unwrap();
    let mut maps = vec![LidarMap::load(&path).unwrap().0];
    let mut errors = vec![error(&log.relations, &first.trajectory)];
    let cuts = [first.scans, 2 * first.scans, log.scans.len()];
    for (k, cut) in cuts.windows(2).enumerate() {
        let session = map(&log.scans[cut[0]..cut[1]]);
        let (m, e) = part(
            &session,
            log,
            &dir.path().join(format!("part{}.skmap", k + 1)),
        );
        maps.push(m);
        errors.push(e);
    }
    eprintln!(
        "{name}: the parts after the first mapped in {:.1} s",
        start.elapsed().as_secs_f64()
    );
    Some(Mapped {
        log,
        full: &whole.trajectory,
        maps,
        errors,
    })
}

/// ACES's parts mapped once for the two tests that use it (its parts merged, and its first
/// part put among Intel's).
fn aces(test: &str) -> Option<&'static Mapped> {
    static ACES: OnceLock<Option<Mapped>> = OnceLock::new();
    ACES.get_or_init(|| mapped(test, "aces")).as_ref()
}

/// What a merge of a log's three parts reached.
struct Scored {
    /// The log's parts left out (0, 1, 2).
    unmerged: Vec<usize>,
    /// Mean relations error of all parts in the merged frame and of the uninterrupted run
    /// (`None` when a part was left out) \[m\].
    errors: Option<(f64, f64)>,
}

/// Merges the log's three parts, with `foreign` (a map of another building) put among them
/// when given, at input 1; checks that no wrong closure is accepted (none at all to the
/// foreign map), and that the parts that merged are placed right at their cuts.
fn check_merge(name: &str, mapped: &Mapped, foreign: Option<&LidarMap>) -> Scored {
    let mut maps = mapped.maps.clone();
    if let Some(other) = foreign {
        maps.insert(1, other.clone());
    }
    // the inputs holding the log's parts, in order
    let parts: Vec<usize> = (0..maps.len())
        .filter(|&i| foreign.is_none() || i != 1)
        .collect();
    let full = mapped.full;
    let start = Instant::now();
    let outcome = merge_maps(&maps, &MergeConfig::default()).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let wrong = wrong_closures(&outcome, &maps, &parts, full);
    let unmerged: Vec<usize> = (0..3)
        .filter(|&k| outcome.inputs[parts[k]].merged_from_input.is_none())
        .collect();
    eprintln!(
        "{name}: parts left out {unmerged:?}; {:?}; wrong accepted closures {wrong}; merge \
         {seconds:.1} s",
        outcome.stats
    );
    assert_eq!(wrong, 0, "{name}: wrong closures accepted");
    if foreign.is_some() {
        assert!(
            outcome.inputs[1].merged_from_input.is_none(),
            "{name}: the foreign map was merged: {:?}",
            outcome.stats
        );
    }
    // the cuts between parts that merged: the last scan of one and the first of the next
    for k in 0..2 {
        let (Some(before), Some(after)) = (
            outcome.inputs[parts[k]].trajectory.as_ref(),
            outcome.inputs[parts[k + 1]].trajectory.as_ref(),
        ) else {
            continue;
        };
        let (t1, t2) = (
            before.poses.last().unwrap().timestamp,
            after.poses[0].timestamp,
        );
        let merged_rel = pose_at(before, t1).inverse() * pose_at(after, t2);
        let full_rel = pose_at(full, t1).inverse() * pose_at(full, t2);
        let (m, deg) = differ(&merged_rel, &full_rel);
        eprintln!("{name}: cut {k}: off by {m:.3} m, {deg:.2}°");
        assert!(m <= 0.3 && deg <= 10.0, "{name}: cut {k}: {m} m, {deg}°");
    }
    if !unmerged.is_empty() {
        return Scored {
            unmerged,
            errors: None,
        };
    }
    // all three parts' scans in the merged frame, in time order
    let mut merged = Trajectory::new();
    for &i in &parts {
        for p in &outcome.inputs[i].trajectory.as_ref().unwrap().poses {
            merged.push(p.timestamp, p.pose);
        }
    }
    let relations = &mapped.log.relations;
    assert_eq!(merged.len(), mapped.log.scans.len());
    let merged_error = error(relations, &merged);
    let full_error = error(relations, full);
    let e = &mapped.errors;
    eprintln!(
        "{name}: relations error parts {:.4} / {:.4} / {:.4} m, merged {merged_error:.4} m \
         ({:.2}×), uninterrupted {full_error:.4} m; timings {:?}",
        e[0],
        e[1],
        e[2],
        merged_error / full_error,
        outcome.timings.summary(),
    );
    Scored {
        unmerged,
        errors: Some((merged_error, full_error)),
    }
}

/// How far the uninterrupted run's relative pose between a closure's keyframes is from the
/// closure's \[m, °\].
fn truth_error(c: &InterClosure, maps: &[LidarMap], full: &Trajectory) -> (f64, f64) {
    let t_from = maps[c.from_map].keyframes[c.from_keyframe].scan.timestamp;
    let t_to = maps[c.to_map].keyframes[c.to_keyframe].scan.timestamp;
    let truth = pose_at(full, t_from).inverse() * pose_at(full, t_to);
    differ(&truth, &c.from_from_to)
}

/// Accepted closures the uninterrupted run disagrees with by more than 0.3 m or 5°, and any
/// accepted closure to an input that is not one of the log's `parts`; prints every verified
/// closure with its free-space conflict and its error.
fn wrong_closures(
    outcome: &MergeOutcome,
    maps: &[LidarMap],
    parts: &[usize],
    full: &Trajectory,
) -> usize {
    let ours = |c: &InterClosure| parts.contains(&c.from_map) && parts.contains(&c.to_map);
    for c in outcome
        .closures
        .iter()
        .filter(|c| c.status != ClosureStatus::FailedVerification)
    {
        let off = if ours(c) {
            let (m, deg) = truth_error(c, maps, full);
            format!("off by {m:.2} m, {deg:.1}°")
        } else {
            "to the other building".to_string()
        };
        eprintln!(
            "  closure {}:{} -> {}:{} goodness {:.2}/{:.2} free-space conflict {:.3} \
             {:?}: {off}",
            c.from_map,
            c.from_keyframe,
            c.to_map,
            c.to_keyframe,
            c.goodness,
            c.reverse_goodness.unwrap_or(0.0),
            c.free_space_conflict.unwrap_or(f64::NAN),
            c.status,
        );
    }
    outcome
        .closures
        .iter()
        .filter(|c| c.status == ClosureStatus::Accepted)
        .filter(|c| {
            if !ours(c) {
                return true;
            }
            let (m, deg) = truth_error(c, maps, full);
            m > 0.3 || deg > 5.0
        })
        .count()
}

#[test]
fn intel_in_three_parts_merges_and_a_part_of_aces_is_left_out() {
    let test = "intel_in_three_parts_merges_and_a_part_of_aces_is_left_out";
    let Some(intel) = mapped(test, "intel") else {
        return;
    };
    let aces = aces(test).unwrap();
    let scored = check_merge("intel + aces part", &intel, Some(&aces.maps[0]));
    assert!(
        scored.unmerged.is_empty(),
        "intel: parts {:?} left out",
        scored.unmerged
    );
    let (merged, full) = scored.errors.unwrap();
    assert!(merged <= 1.5 * full, "intel: merged {merged} vs {full}");
}

#[test]
fn aces_in_three_parts_accepts_no_wrong_closure() {
    if let Some(aces) = aces("aces_in_three_parts_accepts_no_wrong_closure") {
        check_merge("aces", aces, None);
    }
}

#[test]
fn mit_csail_in_three_parts_accepts_no_wrong_closure() {
    if let Some(csail) = mapped(
        "mit_csail_in_three_parts_accepts_no_wrong_closure",
        "mit-csail",
    ) {
        check_merge("mit-csail", &csail, None);
    }
}
