#![allow(clippy::unwrap_used, clippy::expect_used)] // test helpers fail loudly

use super::map::layer_keyframes;
use super::*;
use crate::map_file::{MapFile, Rig};
use slamkit_core::Observation;
use slamkit_lidar::layers::LayeredSlamConfig;
use slamkit_sim::{SimConfig, Simulation, World};

/// The first `seconds` of the `small` world's simulated flight.
fn flight(seconds: f64) -> Vec<Observation> {
    let sim = Simulation::new(World::builtin("small").unwrap(), SimConfig::default(), 3).unwrap();
    sim.lidar_run()
        .observations()
        .into_iter()
        .filter(|o| o.timestamp() <= seconds)
        .collect()
}

fn run(session: &mut DroneSlam, observations: &[Observation]) -> Vec<Update> {
    observations
        .iter()
        .filter_map(|o| session.push(o.clone()))
        .collect()
}

#[test]
fn every_scan_gets_an_update_and_the_map_file_holds_every_keyframe() {
    let observations = flight(20.0);
    let scans = observations
        .iter()
        .filter(|o| matches!(o, Observation::Scan(_)))
        .count();
    let mut session = DroneSlam::new(DroneSlamConfig::default()).unwrap();
    let updates = run(&mut session, &observations);
    assert_eq!(updates.len(), scans);
    assert!(updates.iter().all(|u| u.pose.is_some()));
    let tracked = updates
        .iter()
        .filter(|u| u.status == TrackingStatus::Tracking)
        .count();
    assert!(tracked > scans / 2, "{tracked} of {scans} tracked");
    let added: usize = updates.iter().map(|u| u.map.keyframes_added).sum();
    assert_eq!(added, session.layered().keyframes().len());

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drone.skmap");
    session.save(&path).unwrap();
    let file = MapFile::load(&path).unwrap();
    assert_eq!(file.header.rig, Rig::Drone);
    assert_eq!(file.header.keyframes, added);
    let layers = layer_keyframes(&file).unwrap();
    assert_eq!(layers.values().map(Vec::len).sum::<usize>(), added);
    let first = &session.layered().keyframes()[0];
    let saved = &layers[&first.layer][0];
    assert_eq!(saved.points, first.keyframe.points);
    assert_eq!(saved.map_from_base, first.keyframe.world_from_base);
    assert!(file.expect_rig(Rig::Lidar2d).is_err());
}

#[test]
fn an_initial_pose_moves_the_whole_estimate() {
    let observations = flight(5.0);
    let mut plain = DroneSlam::new(DroneSlamConfig::default()).unwrap();
    run(&mut plain, &observations);
    let start = Pose2::new([2.0, -1.0].into(), 0.5);
    let mut moved = DroneSlam::with_initial_pose(DroneSlamConfig::default(), start).unwrap();
    run(&mut moved, &observations);
    let start3 = slamkit_core::pose::pose2_to_pose3(&start);
    for (a, b) in plain
        .trajectory()
        .poses
        .iter()
        .zip(&moved.trajectory().poses)
    {
        let expected = start3 * a.pose;
        assert!((expected.translation.vector - b.pose.translation.vector).norm() < 1e-9);
    }
    let (a, b) = (plain.merged_cloud(), moved.merged_cloud());
    assert_eq!(a.len(), b.len());
    assert!(a
        .iter()
        .zip(&b)
        .all(|(p, q)| ((start3 * p) - q).norm() < 1e-9));
}

#[test]
fn the_particle_filter_gives_a_pose_online_and_a_trajectory() {
    let observations = flight(10.0);
    let config = DroneSlamConfig {
        particle_filter: Some(particle_filter::drone_pf_config(1)),
        ..DroneSlamConfig::default()
    };
    let mut session = DroneSlam::new(config).unwrap();
    let mut online = 0;
    for o in observations {
        let Some(update) = session.push(o) else {
            continue;
        };
        let Some(pf) = session.pf_pose() else {
            continue;
        };
        online += 1;
        let layered = update.pose.unwrap();
        let apart = (pf.translation.vector - layered.translation.vector).norm();
        assert!(apart < 0.2, "the filter {apart} m from the layered pose");
    }
    assert!(online > 0, "the filter gave a pose online");
    let trajectory = session.pf_trajectory().unwrap();
    assert_eq!(trajectory.poses.len(), session.scans().len());
    assert!(trajectory.poses.iter().all(|p| p
        .pose
        .translation
        .vector
        .iter()
        .all(|c| c.is_finite())));
    assert!(session.particle_filter().unwrap().stats().updates > 0);
}

#[test]
fn kinds_it_does_not_use_are_counted() {
    let mut session = DroneSlam::new(DroneSlamConfig::default()).unwrap();
    let odometry = Observation::Odometry(slamkit_core::observation::OdometryReading {
        timestamp: 0.0,
        pose: Pose2::identity(),
    });
    assert!(session.push(odometry).is_none());
    assert_eq!(session.ignored(), 1);
}

#[test]
fn the_config_reads_from_toml_and_refuses_unknown_fields() {
    let config: DroneSlamConfig = toml::from_str("[layers]\nmax_tilt_rad = 0.1\n").unwrap();
    assert_eq!(config.layers.max_tilt_rad, 0.1);
    assert!(toml::from_str::<DroneSlamConfig>("speed = 1\n").is_err());
}

#[test]
fn frame_counts_and_layer_grids_cover_every_scan() {
    let observations = flight(20.0);
    let scans: Vec<LaserScan> = observations
        .iter()
        .filter_map(|o| match o {
            Observation::Scan(s) => Some(s.clone()),
            _ => None,
        })
        .collect();
    let mut calls = 0;
    let session =
        DroneSlam::from_observations(DroneSlamConfig::default(), observations, || calls += 1)
            .unwrap();
    assert_eq!(calls, scans.len(), "one call per scan");
    let counts = session.frame_counts();
    assert_eq!(counts.processed + counts.skipped, scans.len());
    assert!(counts.processed > scans.len() / 2, "{counts:?}");
    let config = slamkit_map::OccupancyGridConfig::default();
    let grids = session
        .layer_grids(&scans, &session.map_from_world(), &config)
        .unwrap();
    assert!(grids.layers.len() >= 2, "the flight climbs through layers");
    let in_layers: usize = grids.layers.values().map(|l| l.scans).sum();
    assert_eq!(in_layers, counts.processed);
    let h = session.config().layers.height.layer_height_m;
    for (k, l) in &grids.layers {
        assert!((l.z_range_m[0] - *k as f64 * h).abs() < 1e-12);
        assert!((l.z_range_m[1] - l.z_range_m[0] - h).abs() < 1e-12);
    }
    assert_eq!(grids.into_layer_maps().len(), session.layer_maps().len());
}

#[test]
fn an_odometry_jump_no_drone_can_make_is_taken_as_no_motion() {
    let config = DroneSlamConfig {
        layers: LayeredSlamConfig {
            use_odometry: true,
            ..LayeredSlamConfig::default()
        },
        ..DroneSlamConfig::default()
    };
    let clean = flight(20.0);
    let mut jumped = clean.clone();
    let scan = jumped
        .iter_mut()
        .filter_map(|o| match o {
            Observation::Scan(s) => Some(s),
            _ => None,
        })
        .nth(100)
        .unwrap();
    let odometry = scan.odometry.as_mut().unwrap();
    odometry.translation.vector.x += 1.0e6;
    let mut a = DroneSlam::new(config.clone()).unwrap();
    let mut b = DroneSlam::new(config).unwrap();
    let (pa, pb) = (run(&mut a, &clean), run(&mut b, &jumped));
    // one reading off: the jump there and the jump back
    assert_eq!((a.odometry_rejected(), b.odometry_rejected()), (0, 2));
    let worst = pa
        .iter()
        .zip(&pb)
        .map(|(u, v)| {
            (u.pose.unwrap().translation.vector - v.pose.unwrap().translation.vector).norm()
        })
        .fold(0.0, f64::max);
    assert!(worst < 0.2, "the jump moved the estimate by {worst} m");
}
