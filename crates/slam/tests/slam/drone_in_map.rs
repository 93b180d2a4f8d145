//! A drone's map lasts: one simulated flight through `office` maps it and saves it; a second
//! flight (other sensor noise), picked up half-way with no start pose given, finds itself in
//! the loaded map and localises in it without changing it, or continues it.

use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{Observation, Pose2, Trajectory};
use slamkit_sim::{SimConfig, Simulation, World};
use slamkit_slam::drone::map::DroneMap;
use slamkit_slam::map_file::MapFile;
use slamkit_slam::{DroneSlam, DroneSlamConfig, Session, TrackingStatus};

/// The simulated flight with `seed`: its observations and true poses.
fn flight(seed: u64) -> (Vec<Observation>, Trajectory) {
    let sim = Simulation::new(
        World::builtin("office").unwrap(),
        SimConfig::default(),
        seed,
    )
    .unwrap();
    let run = sim.lidar_run();
    (run.observations(), run.ground_truth)
}

/// Mean and largest horizontal distance of the placed poses from the truth, the truth seen
/// from the map frame (the first flight's first pose).
fn errors(
    session: &DroneSlam,
    truth: &Trajectory,
    map_from_world: &Pose2,
    from_s: f64,
) -> (f64, f64) {
    let estimate = session.trajectory();
    let mut sum = 0.0;
    let mut max: f64 = 0.0;
    let mut n = 0;
    for e in estimate.poses.iter().filter(|e| e.timestamp >= from_s) {
        n += 1;
        let t = truth
            .poses
            .iter()
            .find(|p| (p.timestamp - e.timestamp).abs() < 1e-9)
            .expect("a true pose at every scan");
        let true_xy = map_from_world * pose3_to_pose2(&t.pose);
        let d = (e.pose.translation.vector.xy() - true_xy.translation.vector).norm();
        sum += d;
        max = max.max(d);
    }
    assert!(n > 0);
    (sum / n as f64, max)
}

/// The largest difference of keyframe poses between two maps of the same keyframes \[m, rad\]
/// (a pose's heading is stored as an angle, so a round trip may move its last bits); `None`
/// when their layers, times or points differ.
fn pose_difference(a: &DroneMap, b: &DroneMap) -> Option<f64> {
    let mut worst: f64 = 0.0;
    if a.config != b.config || a.layers.keys().ne(b.layers.keys()) {
        return None;
    }
    for (x, y) in a.layers.values().zip(b.layers.values()) {
        if x.len() != y.len() {
            return None;
        }
        for (k, l) in x.iter().zip(y) {
            if k.time_s != l.time_s || k.points != l.points {
                return None;
            }
            let d = k.map_from_base.inverse() * l.map_from_base;
            worst = worst
                .max(d.translation.vector.norm())
                .max(d.rotation.angle().abs());
        }
    }
    Some(worst)
}

#[test]
fn a_second_flight_finds_itself_in_the_saved_map_and_localises_or_continues() {
    if cfg!(debug_assertions) {
        eprintln!("skipped: two simulated flights; run with --release");
        return;
    }
    let (observations, truth) = flight(1);
    let map_from_world = pose3_to_pose2(&truth.poses[0].pose).inverse();
    let mut mapping = DroneSlam::new(DroneSlamConfig::default()).unwrap();
    for o in &observations {
        mapping.push(o.clone());
    }

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("office.skmap");
    mapping.save(&path).unwrap();
    let map = DroneMap::from_file(&MapFile::load(&path).unwrap()).unwrap();
    let round_trip = pose_difference(&map, &mapping.map());
    assert!(
        round_trip.is_some_and(|d| d < 1e-12),
        "round trip: {round_trip:?}"
    );

    // the second flight, from half-way: its start is not given
    let (observations, truth) = flight(2);
    let half = observations.last().unwrap().timestamp() / 2.0;
    // the map's own error where the second flight flies (the same path, the same timing)
    let (mapping_mean, mapping_max) = errors(&mapping, &truth, &map_from_world, half);
    let second: Vec<Observation> = observations
        .into_iter()
        .filter(|o| o.timestamp() >= half)
        .collect();
    for frozen in [true, false] {
        let config = DroneSlamConfig::default();
        let mut session = if frozen {
            DroneSlam::localise(config, map.clone()).unwrap()
        } else {
            DroneSlam::resume(config, map.clone()).unwrap()
        };
        let mut unplaced = 0;
        for o in &second {
            if let Some(update) = session.push(o.clone()) {
                if update.status == TrackingStatus::Initialising {
                    assert!(update.pose.is_none(), "a pose before the drone was found");
                    unplaced += 1;
                }
            }
        }
        assert_eq!(unplaced, session.unplaced_scans());
        let stats = session.in_map_stats().unwrap();
        let found = stats.found_at_scan.expect("found in the map");
        let (mean, max) = errors(&session, &truth, &map_from_world, half);
        eprintln!(
            "frozen {frozen}: found after {found} scans ({} searches), error mean {mean:.3} m, \
             max {max:.3} m; mapping run mean {mapping_mean:.3} m, max {mapping_max:.3} m",
            stats.searches
        );
        assert!(found <= 50, "found after {found} scans");
        assert!(
            mean <= 1.2 * mapping_mean + 0.02,
            "mean {mean} vs {mapping_mean}"
        );
        let after = session.map();
        let keyframes = |m: &DroneMap| m.layers.values().map(Vec::len).sum::<usize>();
        if frozen {
            assert!(after == map, "localisation changed the map");
        } else {
            assert!(keyframes(&after) > keyframes(&map), "no keyframe added");
            for (layer, saved) in &map.layers {
                assert!(
                    after.layers[layer][..saved.len()] == saved[..],
                    "layer {layer}"
                );
            }
        }
    }
}
