//! `slamkit ros2 nav` live on loopback (issue 21), the loop closed over DDS: the simulated
//! ground robot of `slamkit nav` (office world, seed 1, its camera 0.45 m up and tilted 10°
//! down, 10 Hz) renders a frame where it stands, this test publishes it as a RealSense driver
//! would (rgb8 colour, 32FC1 depth, CameraInfo, `base_footprint → camera_color_optical_frame`
//! on `/tf_static`, the goal as RViz sends it on `/goal_pose`), waits for the node's answer on
//! `/cmd_vel` and drives the simulated robot by it for the frame's period.
//!
//! The commands must be those of the same session run here directly on the frames the node
//! received (a frame lost by best-effort DDS is left out of both); the robot must have
//! moved; `/map` must come as an occupancy grid with free and occupied cells; and the node
//! stops the robot when it stops. Both sides find each other by unicast on `127.0.0.1` only
//! (`ROS_LOCALHOST_ONLY`), on a domain of their own.

use crate::{loopback_discovery, typed_topic, wait_until_matched, Peer};
use nalgebra::{Isometry2, Point2};
use ros2_client::dds::rustdds::StatusEvented;
use slamkit_core::observation::{Observation, RgbdFrame};
use slamkit_core::Pose3;
use slamkit_ros2::dds::{latched_qos, reliable_qos};
use slamkit_ros2::msgs::{self, Header, Time};
use slamkit_ros2::{run_nav_node, run_sim_node, NavNodeConfig, SimNodeConfig};
use slamkit_sim::{GroundRobot, World};
use slamkit_slam::ground_robot::closed_loop::NavLoopConfig;
use slamkit_slam::ground_robot::MountedCamera;
use slamkit_slam::GroundRobotNav;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

const OPTICAL: &str = "camera_color_optical_frame";
/// Camera frames played (3 s at 10 Hz).
const FRAMES: usize = 30;

#[test]
fn the_nav_node_drives_the_simulated_robot_over_loopback() {
    let started = Instant::now();
    let loop_config = NavLoopConfig::default();
    let nav_config = loop_config.nav();
    let world = World::builtin("office").unwrap();
    let goal_world = Point2::new(world.nav_goal[0], world.nav_goal[1]);
    let mut robot = GroundRobot::new(world, &loop_config.sim, 1).unwrap();
    let rgbd = robot.simulation().config.rgbd.clone();
    let base_from_camera = rgbd.mount.base_from_camera();
    // the map frame is the base frame at the start
    let start: Isometry2<f64> = robot.truth();
    let goal = start.inverse() * goal_world;
    let discovery = loopback_discovery(2);
    let mut config = NavNodeConfig::default();
    config.camera.discovery = discovery;
    config.camera.frame_queue = 1000;
    config.camera.rgb_topic = "/camera/color/image_raw".into();
    config.camera.depth_topic = "/camera/aligned_depth_to_color/image_raw".into();
    config.camera.camera_info_topic = "/camera/color/camera_info".into();
    let stop = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let node = scope.spawn(|| run_nav_node(&config, &nav_config, None, &stop));
        let Peer {
            mut ros,
            publisher,
            subscriber,
            ..
        } = Peer::new(&discovery, "robot");
        let qos = reliable_qos(100);
        let c = &config.camera;
        let mut t = |name: &str, ty: &str, qos: &_| typed_topic(&mut ros, name, ty, qos);
        let rgb_w = publisher
            .create_datawriter_no_key_cdr::<msgs::Image>(
                &t(&c.rgb_topic, "sensor_msgs/Image", &qos),
                None,
            )
            .unwrap();
        let depth_w = publisher
            .create_datawriter_no_key_cdr::<msgs::Image>(
                &t(&c.depth_topic, "sensor_msgs/Image", &qos),
                None,
            )
            .unwrap();
        let info_t = t(&c.camera_info_topic, "sensor_msgs/CameraInfo", &qos);
        let info_w = publisher
            .create_datawriter_no_key_cdr::<msgs::CameraInfo>(&info_t, None)
            .unwrap();
        let tf_t = t("/tf_static", "tf2_msgs/TFMessage", &latched_qos());
        let tf_w = publisher
            .create_datawriter_no_key_cdr::<msgs::TfMessage>(&tf_t, None)
            .unwrap();
        let goal_t = t("/goal_pose", "geometry_msgs/PoseStamped", &reliable_qos(10));
        let goal_w = publisher
            .create_datawriter_no_key_cdr::<msgs::PoseStamped>(&goal_t, None)
            .unwrap();
        let cmd_t = t("/cmd_vel", "geometry_msgs/Twist", &reliable_qos(1000));
        let mut cmd_r = subscriber
            .create_datareader_no_key_cdr::<msgs::Twist>(&cmd_t, None)
            .unwrap();
        let map_t = t("/map", "nav_msgs/OccupancyGrid", &latched_qos());
        let mut map_r = subscriber
            .create_datareader_no_key_cdr::<msgs::OccupancyGrid>(&map_t, None)
            .unwrap();
        wait_until_matched(&[
            &|| rgb_w.try_recv_status(),
            &|| depth_w.try_recv_status(),
            &|| info_w.try_recv_status(),
            &|| tf_w.try_recv_status(),
            &|| goal_w.try_recv_status(),
        ]);
        let discovered_s = started.elapsed().as_secs_f64();
        let header = |stamp, frame: &str| Header {
            stamp,
            frame_id: frame.into(),
        };
        let t0 = Time {
            sec: 1000,
            nanosec: 0,
        };
        let tf = msgs::TransformStamped {
            header: header(t0, "base_footprint"),
            child_frame_id: OPTICAL.into(),
            transform: msgs::Pose::from_isometry(&base_from_camera),
        };
        tf_w.write(
            msgs::TfMessage {
                transforms: vec![tf],
            },
            None,
        )
        .unwrap();
        let mut goal_msg = msgs::PoseStamped {
            header: header(t0, "map"),
            ..msgs::PoseStamped::default()
        };
        (goal_msg.pose.position.x, goal_msg.pose.position.y) = (goal.x, goal.y);
        goal_w.write(goal_msg, None).unwrap();
        std::thread::sleep(Duration::from_millis(200));
        let info = msgs::CameraInfo::pinhole(header(t0, OPTICAL), &rgbd.intrinsics);
        let dt = 1.0 / rgbd.rate_hz;
        let mut frames = Vec::new();
        let mut commands = Vec::new();
        let mut lost = 0;
        for index in 0..FRAMES {
            let stamp = Time::from_secs_f64(1000.0 + index as f64 * dt);
            let frame = robot.rgbd_frame(index, stamp.as_secs_f64());
            info_w.write(info.clone(), None).unwrap();
            let h = header(stamp, OPTICAL);
            depth_w
                .write(msgs::Image::depth_32fc1(h.clone(), &frame.depth_m), None)
                .unwrap();
            rgb_w
                .write(msgs::Image::rgb8(h, &frame.color), None)
                .unwrap();
            frames.push(frame);
            // the answer; none within a second: the frame was lost on the way
            let waiting = Instant::now() + Duration::from_secs(1);
            let command = loop {
                if let Ok(Some(sample)) = cmd_r.take_next_sample() {
                    break Some(sample.into_value());
                }
                if Instant::now() > waiting {
                    break None;
                }
                std::thread::sleep(Duration::from_millis(2));
            };
            let Some(command) = command else {
                lost += 1;
                continue;
            };
            commands.push(command);
            robot.drive(
                command.linear.x,
                command.angular.z,
                dt,
                loop_config.robot_radius_m,
            );
        }
        std::thread::sleep(Duration::from_millis(200));
        stop.store(true, Ordering::Relaxed);
        // the stop command and the maps, taken while the node lingers (its writers go with it)
        let mut map = None;
        let mut take = || {
            while let Ok(Some(sample)) = cmd_r.take_next_sample() {
                commands.push(sample.into_value());
            }
            while let Ok(Some(sample)) = map_r.take_next_sample() {
                map = Some(sample.into_value());
            }
        };
        while !node.is_finished() {
            take();
            std::thread::sleep(Duration::from_millis(10));
        }
        take();
        let run = node.join().unwrap().unwrap();
        let s = &run.stats;
        println!(
            "discovered in {discovered_s:.2} s; {FRAMES} frames sent, {lost} unanswered, {} \
             queued, {} commands published ({} received), {} poses, {} maps, {} before a goal, \
             status {:?}, mounting {:?}",
            s.camera.frames_queued,
            s.commands_published,
            commands.len(),
            s.camera.poses_published,
            s.maps_published,
            s.frames_before_goal,
            s.last_status,
            s.camera.mounting
        );
        assert_eq!(s.goals_received, 1);
        assert_eq!(s.frames_before_goal, 0);
        assert_eq!(s.camera.undecodable.count, 0, "{:?}", s.camera.undecodable);
        assert!(
            run.commands.len() >= FRAMES * 9 / 10,
            "{}",
            run.commands.len()
        );
        assert_eq!(commands.len(), run.commands.len() + 1);
        assert_eq!(commands.last(), Some(&msgs::Twist::default()));
        // the same session on the frames that came, directly
        let camera = MountedCamera {
            intrinsics: rgbd.intrinsics,
            base_from_camera,
        };
        let mut direct =
            GroundRobotNav::new(&nav_config, camera, &Pose3::identity(), goal).unwrap();
        let received: Vec<RgbdFrame> = frames
            .into_iter()
            .filter(|f| run.commands.iter().any(|(t, _)| *t == f.timestamp))
            .collect();
        assert_eq!(received.len(), run.commands.len());
        let mut previous = None;
        for (frame, (t, got)) in received.into_iter().zip(&run.commands) {
            direct.process(Observation::Rgbd(frame)).unwrap();
            let want = direct.command(previous.map_or(0.0, |p| t - p));
            previous = Some(*t);
            assert_eq!(*got, want, "at {t} s");
        }
        for (sent, (_, got)) in commands.iter().zip(&run.commands) {
            assert_eq!(
                (sent.linear.x, sent.angular.z),
                (got.speed_m_s, got.yaw_rate_rad_s)
            );
        }
        let moved = (Point2::from(robot.truth().translation.vector)
            - Point2::from(start.translation.vector))
        .norm();
        println!(
            "moved {moved:.3} m; {} plans; {:.1} s in all",
            direct.plans().len(),
            started.elapsed().as_secs_f64()
        );
        assert!(moved > 0.1, "{moved} m");
        let map = map.expect("a map on /map");
        assert_eq!(map.header.frame_id, "map");
        let n = (map.info.width * map.info.height) as usize;
        assert_eq!(map.data.len(), n);
        assert!(map.data.contains(&0) && map.data.contains(&100));
        assert_eq!(direct.grid().width(), map.info.width as usize);
    });
}

/// `slamkit sim --ros2`: the robot's camera comes out (at its rate, or as fast as it renders),
/// and a constant command on
/// `/cmd_vel` drives it straight ahead by speed × period for every period it was fresh.
#[test]
fn the_simulated_robot_publishes_its_camera_and_drives_by_cmd_vel() {
    let loop_config = NavLoopConfig::default();
    let world = World::builtin("office").unwrap();
    let mut robot = GroundRobot::new(world, &loop_config.sim, 1).unwrap();
    let start = robot.truth();
    let discovery = loopback_discovery(3);
    let config = SimNodeConfig {
        discovery,
        duration_s: Some(2.0),
        ..SimNodeConfig::default()
    };
    let stop = AtomicBool::new(false);
    let speed = 0.2;
    let (stats, images) = std::thread::scope(|scope| {
        let sim = scope.spawn(|| run_sim_node(&config, &mut robot, &stop));
        let mut ros = discovery.node("driver").unwrap();
        let twist = ("geometry_msgs", "Twist");
        let cmd = slamkit_ros2::dds::advertise::<msgs::Twist>(
            &mut ros,
            "/cmd_vel",
            twist,
            &reliable_qos(10),
        )
        .unwrap();
        let image = ("sensor_msgs", "Image");
        let qos = slamkit_ros2::dds::sensor_qos();
        let colour =
            slamkit_ros2::dds::subscribe::<msgs::Image>(&mut ros, &config.rgb_topic, image, &qos)
                .unwrap();
        let mut images = Vec::new();
        let mut command = msgs::Twist::default();
        command.linear.x = speed;
        while !sim.is_finished() {
            let _ = cmd.publish(command);
            while let Ok(Some((m, _))) = colour.take() {
                images.push((m.width, m.height, m.encoding, m.data.len()));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        (sim.join().unwrap().unwrap(), images)
    });
    println!(
        "{} frames published, {} received, {} commands, {} steps driven, {} late",
        stats.frames_published,
        images.len(),
        stats.commands_received,
        stats.steps_driven,
        stats.late_frames
    );
    // 2 s at 10 Hz: frames at 0, 0.1, ..., 2.0 s; fewer only when a frame took longer to
    // render than its period (a loaded machine), and then counted late
    let frames = stats.frames_published;
    assert!((3..=21).contains(&frames), "{frames}");
    assert!(
        frames == 21 || stats.late_frames > 0,
        "{frames} frames, none late"
    );
    assert!(images.len() * 2 >= frames, "{} images", images.len());
    for (w, h, encoding, bytes) in &images {
        assert_eq!(
            (*w, *h, encoding.as_str(), *bytes),
            (640, 480, "rgb8", 640 * 480 * 3)
        );
    }
    assert!(stats.steps_driven >= 1, "{}", stats.steps_driven);
    assert_eq!(stats.blocked_steps, 0);
    let driven = speed * 0.1 * stats.steps_driven as f64;
    let moved = start.inverse() * robot.truth();
    assert!(
        (moved.translation.x - driven).abs() < 1e-9,
        "{moved:?} for {driven} m"
    );
    assert!(moved.translation.y.abs() < 1e-9 && moved.rotation.angle().abs() < 1e-12);
    assert_eq!(stats.truth.poses.len(), stats.frames_published);
}
