//! `slamkit ros2 lidar --record FILE.mcap` (issue 23): the simulated drone's scans
//! (`slamkit sim --ros2 --robot drone`, the `small` world's first [`FLIGHT_S`] seconds at
//! [`SPEED`] times real time) played over loopback into the lidar node, which records what it
//! processed; the file, read back with the `mcap` crate, must hold every processed scan with
//! its pose and transform, and the map and path at the end. Discovery is unicast on
//! `127.0.0.1` only, on a domain of this process's own: nothing leaves the machine.

use crate::loopback_discovery;
use slamkit_ros2::{run_drone_sim_node, run_lidar_node, DroneSimNodeConfig, LidarNodeConfig};
use slamkit_sim::{SimConfig, Simulation, World};
use slamkit_slam::{LidarMethod, LidarSlam, LidarSlamConfig};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Simulated seconds flown.
const FLIGHT_S: f64 = 8.0;
/// Simulated seconds per wall-clock second.
const SPEED: f64 = 4.0;

#[test]
fn the_lidar_node_records_what_it_processed() {
    let sim = Simulation::new(World::builtin("small").unwrap(), SimConfig::default(), 2).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("node.mcap");
    let discovery = loopback_discovery(1);
    let config = LidarNodeConfig {
        discovery,
        odom_topic: None,
        record: Some(path.clone()),
        ..LidarNodeConfig::default()
    };
    // the scans only: the range finders and IMU have no subscriber here, so the player waits
    // for one a short while only
    let player = DroneSimNodeConfig {
        discovery,
        speed: SPEED,
        duration_s: Some(FLIGHT_S),
        wait_for_subscribers_s: Some(3.0),
        ..DroneSimNodeConfig::default()
    };
    let session_config = LidarSlamConfig::from_files(LidarMethod::Icp, false, None, None).unwrap();
    let session = LidarSlam::new(session_config, slamkit_core::Pose2::identity()).unwrap();
    let (stop, player_stop) = (AtomicBool::new(false), AtomicBool::new(false));
    let (run, published) = std::thread::scope(|scope| {
        let node = scope.spawn(|| run_lidar_node(&config, session, &stop));
        let published = run_drone_sim_node(&player, &sim, &player_stop).unwrap();
        std::thread::sleep(Duration::from_millis(300));
        stop.store(true, Ordering::Relaxed);
        (node.join().unwrap().unwrap(), published)
    });
    let s = &run.stats;
    println!(
        "{} scans published, {} received, {} processed; recorded {:?}",
        published.scans_published, s.scans_received, s.scans_processed, run.recorded
    );
    assert!(s.scans_processed * 10 >= published.scans_published * 9);
    let (file, counts) = run.recorded.clone().expect("a recording");
    assert_eq!(file, path);
    let bytes = std::fs::read(&path).unwrap();
    let mut read: BTreeMap<String, u64> = BTreeMap::new();
    let mut schemas = BTreeMap::new();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        *read.entry(message.channel.topic.clone()).or_default() += 1;
        let schema = message.channel.schema.as_ref().map(|s| s.name.clone());
        schemas.insert(message.channel.topic.clone(), schema.unwrap_or_default());
    }
    assert_eq!(read, counts);
    let scans = s.scans_processed as u64;
    let poses = run.session.trajectory().poses.len() as u64;
    assert_eq!(read["/scan"], scans);
    assert_eq!((read["/pose"], read["/tf"]), (poses, poses));
    // no snapshot within the run (500 scans apart): the map and path at the end
    assert_eq!((read["/map"], read["/path"]), (1, 1));
    assert_eq!(schemas["/scan"], "foxglove.LaserScan");
    assert_eq!(schemas["/map"], "foxglove.Grid");
}
