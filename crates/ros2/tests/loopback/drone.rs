//! `slamkit sim --ros2 --robot drone` into `slamkit ros2 drone` with nothing but slamkit: the
//! simulated drone flies the `small` world's flight for [`FLIGHT_S`] seconds, played at
//! [`SPEED`] times real time, publishing its scans, range finders and IMU on DDS; the drone
//! node maps it in height layers. The node's poses must follow the simulator's truth (the
//! session never sees it), every scan must have been used with its readings in time order,
//! the laser's mounting must come from `/tf_static`, and `/map` and the layer topic must come
//! with the layer of the last scan. Both sides find each other by unicast on `127.0.0.1` only
//! (`ROS_LOCALHOST_ONLY`), on a domain of their own, so nothing leaves the machine.

use crate::loopback_discovery;
use nalgebra::{Translation3, UnitQuaternion};
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::Pose3;
use slamkit_io::bag::scans::Mounting;
use slamkit_ros2::dds::{latched_qos, subscribe};
use slamkit_ros2::msgs;
use slamkit_ros2::{run_drone_node, run_drone_sim_node, DroneNodeConfig, DroneSimNodeConfig};
use slamkit_sim::{SimConfig, Simulation, World};
use slamkit_slam::{DroneSlam, DroneSlamConfig};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Simulated seconds flown.
const FLIGHT_S: f64 = 24.0;
/// Simulated seconds per wall-clock second.
const SPEED: f64 = 4.0;

#[test]
fn the_drone_node_maps_the_simulated_flight_over_loopback() {
    let started = Instant::now();
    let sim = Simulation::new(World::builtin("small").unwrap(), SimConfig::default(), 1).unwrap();
    let discovery = loopback_discovery(0);
    let mut node_config = DroneNodeConfig::default();
    node_config.lidar.discovery = discovery;
    node_config.lidar.map_update_interval_s = 0.5;
    let sim_config = DroneSimNodeConfig {
        discovery,
        speed: SPEED,
        duration_s: Some(FLIGHT_S),
        wait_for_subscribers_s: Some(10.0),
        ..DroneSimNodeConfig::default()
    };
    let stop = AtomicBool::new(false);
    let sim_stop = AtomicBool::new(false);
    let session = DroneSlam::new(DroneSlamConfig::default()).unwrap();
    let (run, published, maps, layers) = std::thread::scope(|scope| {
        let node = scope.spawn(|| run_drone_node(&node_config, session, &stop));
        let mut ros = discovery.node("viewer").unwrap();
        let map_r = subscribe::<msgs::OccupancyGrid>(
            &mut ros,
            "/map",
            ("nav_msgs", "OccupancyGrid"),
            &latched_qos(),
        )
        .unwrap();
        let layer_r = subscribe::<i32>(
            &mut ros,
            "/slamkit/layer",
            ("std_msgs", "Int32"),
            &latched_qos(),
        )
        .unwrap();
        let flight = scope.spawn(|| run_drone_sim_node(&sim_config, &sim, &sim_stop));
        let (mut maps, mut layers) = (Vec::new(), Vec::new());
        let mut take = || {
            while let Ok(Some((m, _))) = map_r.take() {
                maps.push(m);
            }
            while let Ok(Some((l, _))) = layer_r.take() {
                layers.push(l);
            }
        };
        while !flight.is_finished() {
            take();
            std::thread::sleep(Duration::from_millis(20));
        }
        let published = flight.join().unwrap().unwrap();
        std::thread::sleep(Duration::from_millis(500));
        stop.store(true, Ordering::Relaxed);
        while !node.is_finished() {
            take();
            std::thread::sleep(Duration::from_millis(10));
        }
        take();
        (node.join().unwrap().unwrap(), published, maps, layers)
    });
    let s = &run.stats;
    let latency = s.latency.summary();
    println!(
        "published {} scans, {} ranges, {} IMU ({} late, {:.2} s waiting for subscribers); \
         received {} scans, {} ranges, {} IMU; {} processed, {} out of order, {} maps, layers \
         {layers:?}; latency {latency:?}; {:.1} s in all",
        published.scans_published,
        published.ranges_published,
        published.imu_published,
        published.late,
        published.waited_for_subscribers_s,
        s.scans_received,
        s.ranges_received,
        s.imu_received,
        s.scans_processed,
        s.dropped_out_of_order,
        maps.len(),
        started.elapsed().as_secs_f64()
    );
    let expected = (FLIGHT_S * sim.config.lidar.rate_hz) as usize + 1;
    assert_eq!(published.scans_published, expected);
    // best effort on loopback: a scan may be lost, not many
    assert!(
        s.scans_received * 100 >= expected * 95,
        "{}",
        s.scans_received
    );
    assert!(s.ranges_received * 100 >= published.ranges_published * 95);
    assert!(s.imu_received * 100 >= published.imu_published * 95);
    assert_eq!(s.undecodable.count, 0, "{:?}", s.undecodable);
    assert_eq!(s.scans_processed, s.scans_received);
    assert_eq!(s.dropped_out_of_order, 0);
    match &s.mounting {
        Some(Mounting::TfStatic { laser_frame, .. }) => assert_eq!(laser_frame, "laser"),
        other => panic!("mounting {other:?}"),
    }
    // the map frame is the first scan's x, y and heading, z = 0 at the floor under it
    let trajectory = run.session.trajectory();
    let first = trajectory.poses.first().unwrap();
    let truth_at = |t: f64| {
        published
            .truth
            .poses
            .iter()
            .find(|p| p.timestamp == t)
            .unwrap_or_else(|| panic!("no true pose at {t}"))
            .pose
    };
    let planar = pose3_to_pose2(&truth_at(first.timestamp));
    let sim_from_map = Pose3::from_parts(
        Translation3::new(planar.translation.x, planar.translation.y, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, planar.rotation.angle()),
    );
    let errors: Vec<f64> = trajectory
        .poses
        .iter()
        .map(|p| {
            let truth = truth_at(p.timestamp);
            ((sim_from_map * p.pose).translation.vector - truth.translation.vector).norm()
        })
        .collect();
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let max = errors.iter().copied().fold(0.0, f64::max);
    println!(
        "{} poses: position error mean {mean:.4} m, max {max:.4} m",
        errors.len()
    );
    assert!(mean < 0.05 && max < 0.15, "mean {mean} m, max {max} m");
    // /map: the last scan's layer, its plane at the layer's floor
    let layer = run.session.scans().last().unwrap().estimate.layer.unwrap();
    assert_eq!(layers.last(), Some(&(layer as i32)));
    let map = maps.last().expect("a map on /map");
    let height = run.session.config().layers.height.layer_height_m;
    assert!((map.info.origin.position.z - layer as f64 * height).abs() < 1e-9);
    assert_eq!(map.header.frame_id, "map");
    assert_eq!(map.data.len(), (map.info.width * map.info.height) as usize);
    assert!(map.data.contains(&0) && map.data.contains(&100));
}
