//! slamkit-sim: a small-robot simulator with ground truth, so that every slamkit algorithm can
//! be run and scored without a download.
//!
//! * [`world`]: worlds in TOML (room, walls, boxes, cylinders, ramps, each with a height range;
//!   textures), three built in: `small`, `large`, `office`.
//! * [`scene`]: the world compiled for ray casting (every sensor casts through [`Scene::cast`]).
//! * [`motion`]: a drone flying waypoints `x y z yaw` (tilting as it accelerates) and a
//!   differential-drive robot; ground truth `world_from_base` at any time.
//! * Sensors with seeded noise: [`lidar`] (planar, tilting with the robot), [`range_finder`]
//!   (up and down), [`odometry`] (drifting), [`attitude`] (roll, pitch, gyro heading),
//!   [`flow`] (downward optical-flow velocity),
//!   [`camera`] (RGB-D: colour and Kinect-like depth) and [`stereo`] (a rectified grey pair),
//!   both ray-cast per pixel: [`Simulation::rgbd_frame`], [`Simulation::stereo_frame`].
//! * [`ground_robot`]: a ground robot driven by velocity commands (closed loops), with its
//!   camera, collisions and the world rasterised for scoring.
//! * [`texture`]: procedural surface textures (checkerboards, hash-noise blobs) fixed to the
//!   world, so camera images have features to track.
//! * [`relations`]: pairs of scans for benchmark relations files.
//! * [`error`]: [`SimError`], bad world descriptions and impossible robot paths.
//! * [`simulation`]: a robot, a world and its sensors; [`Simulation::lidar_run`] gives the scans,
//!   ranges and ground truth of a whole run.
//! * [`recording`]: a run written as a recording in real dataset formats (CARMEN log and
//!   relations, the drone's CSV files, TUM RGB-D and KITTI folders), through `slamkit_io`'s
//!   writers.
//! * [`observations`]: the run's readings as `slamkit_core` [`Observation`](slamkit_core::Observation)s
//!   in time order, ready for a session.
//!
//! Frames: world z up, origin at a floor corner of the room; base x forward, y left, z up;
//! cameras x right, y down, z forward. Units m, rad, s. Nothing here prints; only [`recording`]
//! writes files.
//!
//! ```
//! use slamkit_sim::{SimConfig, Simulation, World};
//! let world = World::builtin("small")?;
//! let sim = Simulation::new(world, SimConfig::default(), 42)?;
//! let scan = sim.lidar_scan(0, 0.0);
//! assert_eq!(scan.ranges_m.len(), 512);
//! let truth = sim.state_at(0.0).world_from_base;
//! assert!(truth.translation.z > 0.0);
//! # Ok::<(), slamkit_sim::SimError>(())
//! ```

pub mod attitude;
pub mod camera;
pub mod error;
pub mod flow;
pub mod ground_robot;
pub mod lidar;
pub mod motion;
pub mod observations;
pub mod odometry;
pub mod range_finder;
pub mod recording;
pub mod relations;
pub mod scene;
pub mod simulation;
pub mod stereo;
pub mod texture;
pub mod world;

pub use attitude::{AttitudeConfig, AttitudeReading, GyroConfig, YawGyro};
pub use camera::{CameraMount, RgbdCameraConfig, RgbdFrame, View, TUM_FR1_INTRINSICS};
pub use error::SimError;
pub use flow::{FlowReading, OpticalFlowConfig};
pub use ground_robot::GroundRobot;
pub use lidar::Lidar2dConfig;
pub use motion::{DiffDriveConfig, DroneConfig, RobotState, WaypointMotion};
pub use odometry::{OdometryConfig, OdometrySimulator};
pub use range_finder::{RangeFinderConfig, RangeReading};
pub use relations::relation_pairs;
pub use scene::{Hit, Scene};
pub use simulation::{sample_times, LidarRun, RobotKind, RobotPath, SimConfig, Simulation, Stream};
pub use stereo::{StereoCameraConfig, StereoFrame};
pub use texture::{Pattern, Texture};
pub use world::{World, BUILTIN_WORLDS};
