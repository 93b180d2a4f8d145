//! A ground robot's session saves a map another program can load and plan in: the floor grid
//! comes back cell for cell, the camera's keyframes come back, and a plan on the loaded grid
//! finds a way from where the robot stood.

use nalgebra::Point2;
use slamkit_core::Observation;
use slamkit_sim::{GroundRobot, World};
use slamkit_slam::ground_robot::closed_loop::NavLoopConfig;
use slamkit_slam::ground_robot::map::floor_grid;
use slamkit_slam::ground_robot::{plan_inflated, GroundRobotNavConfig, MountedCamera};
use slamkit_slam::map_file::{MapFile, Rig};
use slamkit_slam::visual::keyframes::VisualMap;
use slamkit_slam::{GroundRobotNav, Session, TrackingStatus};

#[test]
fn a_saved_ground_robot_map_loads_with_its_grid_and_keyframes() {
    let sim = NavLoopConfig::default().sim;
    let mut robot = GroundRobot::new(World::builtin("office").unwrap(), &sim, 1).unwrap();
    let camera = MountedCamera {
        intrinsics: sim.rgbd.intrinsics,
        base_from_camera: sim.rgbd.mount.base_from_camera(),
    };
    let start = robot.at_base_height(&robot.truth());
    let goal = Point2::new(11.5, 5.0);
    let config = GroundRobotNavConfig::default();
    let mut nav = GroundRobotNav::new(&config, camera, &start, goal).unwrap();
    let dt = 1.0 / sim.rgbd.rate_hz;
    let mut keyframes = 0;
    for index in 0..30 {
        let frame = robot.rgbd_frame(index, index as f64 * dt);
        let update = Session::push(&mut nav, Observation::Rgbd(frame)).unwrap();
        assert_eq!(update.status, TrackingStatus::Tracking, "frame {index}");
        let z = update.pose.unwrap().translation.z;
        assert!((z - start.translation.z).abs() < 1e-9, "base height {z}");
        keyframes += update.map.keyframes_added;
        let command = nav.command(dt);
        robot.drive(command.speed_m_s, command.yaw_rate_rad_s, dt, 0.15);
    }
    assert!(keyframes > 0);

    let path = std::env::temp_dir().join(format!("ground-robot-{}.skmap", std::process::id()));
    nav.save(&path).unwrap();
    let file = MapFile::load(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(file.header.rig, Rig::Rgbd);
    let grid = floor_grid(&file).unwrap().expect("a floor grid section");
    assert_eq!(grid, nav.grid());
    let visual = VisualMap::from_map_file(&file, Rig::Rgbd).unwrap();
    assert_eq!(visual.keyframes.len(), keyframes);

    let here = Point2::from(robot.truth().translation.vector);
    let plan = plan_inflated(
        &grid,
        &here,
        &goal,
        config.inflate_cells(grid.resolution_m()),
    );
    assert!(plan.is_ok(), "no plan on the loaded grid: {plan:?}");
}
