//! A robot in a world with its sensors: ground truth and noisy readings at every sensor time.
//!
//! Every random draw comes from a ChaCha8 stream chosen by (seed, sensor, sample index), so any
//! sample can be produced on its own, in any order or in parallel, and the same seed always
//! gives the same readings. Odometry and the gyro's integrated heading, running sums, are the
//! sequential streams.
//!
//! Sensor times are whole microseconds (`k · period`), stored as `µs / 1e6`, so that printing
//! them with 6 decimals (CARMEN, TUM) and parsing them back gives the same numbers.

use crate::attitude::{AttitudeConfig, AttitudeReading, YawGyro};
use crate::camera::{render_rgbd, RgbdCameraConfig, RgbdFrame};
use crate::flow::{FlowReading, OpticalFlowConfig};
use crate::lidar::Lidar2dConfig;
use crate::motion::{DiffDriveConfig, DroneConfig, RobotState, WaypointMotion};
use crate::odometry::{OdometryConfig, OdometrySimulator};
use crate::range_finder::{RangeFinderConfig, RangeReading};
use crate::scene::Scene;
use crate::stereo::{render_stereo, StereoCameraConfig, StereoFrame};
use crate::world::World;
use crate::SimError;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{LaserScan, Pose3, Trajectory};

/// Which robot moves through the world.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RobotKind {
    /// A drone flying the world's `flight_path`.
    Drone,
    /// A differential-drive ground robot driving the world's `drive_path`.
    DiffDrive,
}

/// The path a robot follows through its world.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RobotPath {
    /// The world's `flight_path` (drone) or `drive_path` (ground robot).
    #[default]
    Default,
    /// This many laps of the world's `drive_loop` (ground robot): the same places seen again,
    /// for loop closing. Named `loopN` (`loop3`: three laps).
    Laps(usize),
}

impl std::str::FromStr for RobotPath {
    type Err = SimError;

    /// `default` or `loopN` (N ≥ 1 laps).
    ///
    /// ```
    /// use slamkit_sim::RobotPath;
    /// assert_eq!("loop3".parse::<RobotPath>()?, RobotPath::Laps(3));
    /// assert_eq!("default".parse::<RobotPath>()?, RobotPath::Default);
    /// assert!("loop0".parse::<RobotPath>().is_err() && "spiral".parse::<RobotPath>().is_err());
    /// # Ok::<(), slamkit_sim::SimError>(())
    /// ```
    fn from_str(name: &str) -> Result<Self, SimError> {
        if name == "default" {
            return Ok(Self::Default);
        }
        match name.strip_prefix("loop").map(str::parse::<usize>) {
            Some(Ok(laps)) if laps >= 1 => Ok(Self::Laps(laps)),
            _ => Err(SimError::InvalidConfig(format!(
                "path {name:?}: `default` or `loopN` (N ≥ 1 laps of the world's drive_loop)"
            ))),
        }
    }
}

/// Everything about a simulated run but the world and the seed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// The robot.
    pub robot: RobotKind,
    /// Drone speeds (used when `robot = "drone"`).
    pub drone: DroneConfig,
    /// Ground-robot speeds (used when `robot = "diff_drive"`).
    pub diff_drive: DiffDriveConfig,
    /// Wheel odometry noise of the ground robot.
    pub wheel_odometry: OdometryConfig,
    /// Visual-odometry-like increments of the drone.
    pub drone_odometry: OdometryConfig,
    /// The planar lidar.
    pub lidar: Lidar2dConfig,
    /// The up- and down-looking range finders.
    pub range_finder: RangeFinderConfig,
    /// Roll and pitch from the flight controller.
    pub attitude: AttitudeConfig,
    /// The drone's downward optical-flow velocity sensor.
    pub flow: OpticalFlowConfig,
    /// The RGB-D camera.
    pub rgbd: RgbdCameraConfig,
    /// The stereo pair.
    pub stereo: StereoCameraConfig,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            robot: RobotKind::Drone,
            drone: DroneConfig::default(),
            diff_drive: DiffDriveConfig::default(),
            wheel_odometry: OdometryConfig::wheel(),
            drone_odometry: OdometryConfig::visual(),
            lidar: Lidar2dConfig::default(),
            range_finder: RangeFinderConfig::default(),
            attitude: AttitudeConfig::default(),
            flow: OpticalFlowConfig::default(),
            rgbd: RgbdCameraConfig::default(),
            stereo: StereoCameraConfig::default(),
        }
    }
}

/// The random streams, one per sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u64)]
pub enum Stream {
    /// Lidar range noise and dropouts.
    Lidar = 1,
    /// Range finder noise.
    RangeFinder = 2,
    /// Odometry noise (one sequential stream).
    Odometry = 3,
    /// Depth camera noise and holes.
    Depth = 4,
    /// Colour and grey image noise.
    Image = 5,
    /// Choice of far pairs for relations.
    Relations = 6,
    /// Roll and pitch noise.
    Attitude = 7,
    /// Stereo image noise.
    Stereo = 8,
    /// Yaw-rate gyro noise and bias (one sequential stream).
    Gyro = 9,
    /// Optical-flow noise (index 0: the run's scale error; `k + 1`: reading `k`).
    Flow = 10,
}

/// The lidar part of a run: what 2D lidar SLAM needs.
#[derive(Debug, Clone, PartialEq)]
pub struct LidarRun {
    /// Noisy scans, each with its (drifting) odometry.
    pub scans: Vec<LaserScan>,
    /// Range finder readings.
    pub ranges: Vec<RangeReading>,
    /// Roll, pitch and integrated gyro heading at every scan time.
    pub attitudes: Vec<AttitudeReading>,
    /// Optical-flow velocities, at the flow sensor's rate.
    pub flows: Vec<FlowReading>,
    /// True `world_from_base` at every scan time.
    pub ground_truth: Trajectory,
}

/// A robot moving through a world, ready to produce sensor readings.
#[derive(Debug, Clone)]
pub struct Simulation {
    /// The world.
    pub world: World,
    /// The world compiled for ray casting.
    pub scene: Scene,
    /// The robot's motion (ground truth).
    pub motion: WaypointMotion,
    /// Sensor and robot settings.
    pub config: SimConfig,
    /// Seed of every random draw.
    pub seed: u64,
}

impl Simulation {
    /// The configured robot following the world's default path.
    pub fn new(world: World, config: SimConfig, seed: u64) -> Result<Self, SimError> {
        let motion = match config.robot {
            RobotKind::Drone => WaypointMotion::drone(&world.flight_path, &config.drone)?,
            RobotKind::DiffDrive => {
                WaypointMotion::diff_drive(&world.drive_path, &config.diff_drive)?
            }
        };
        Self::with_motion(world, motion, config, seed)
    }

    /// The configured robot following `path` in `world`.
    ///
    /// ```
    /// use slamkit_sim::{RobotKind, RobotPath, SimConfig, Simulation, World};
    /// let config = SimConfig { robot: RobotKind::DiffDrive, ..SimConfig::default() };
    /// let office = World::builtin("office")?;
    /// let path: RobotPath = "loop3".parse()?;
    /// let sim = Simulation::on_path(office, config, path, 1)?;
    /// // three laps end where they started
    /// let (start, end) = (sim.state_at(0.0), sim.state_at(sim.duration_s()));
    /// let moved = end.world_from_base.translation.vector - start.world_from_base.translation.vector;
    /// assert!(moved.norm() < 1e-9 && sim.duration_s() > 120.0);
    /// # Ok::<(), slamkit_sim::SimError>(())
    /// ```
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] for laps of a drone (a loop is a drive), of a world without
    /// a `drive_loop`, or bad sensor settings.
    pub fn on_path(
        world: World,
        config: SimConfig,
        path: RobotPath,
        seed: u64,
    ) -> Result<Self, SimError> {
        match path {
            RobotPath::Default => Self::new(world, config, seed),
            RobotPath::Laps(laps) => {
                if config.robot != RobotKind::DiffDrive {
                    return Err(SimError::InvalidConfig(
                        "a loop path is driven by the ground robot (robot diff_drive)".into(),
                    ));
                }
                let waypoints = world.drive_laps(laps)?;
                let motion = WaypointMotion::diff_drive(&waypoints, &config.diff_drive)?;
                Self::with_motion(world, motion, config, seed)
            }
        }
    }

    /// A robot following a given motion (for paths other than the world's default).
    pub fn with_motion(
        world: World,
        motion: WaypointMotion,
        config: SimConfig,
        seed: u64,
    ) -> Result<Self, SimError> {
        config.lidar.validate()?;
        config.range_finder.validate()?;
        config.attitude.validate()?;
        config.flow.validate()?;
        config.rgbd.validate()?;
        config.stereo.validate()?;
        Ok(Self {
            scene: Scene::new(&world),
            world,
            motion,
            config,
            seed,
        })
    }

    /// Length of the run \[s\].
    pub fn duration_s(&self) -> f64 {
        self.motion.duration_s()
    }

    /// The random stream of sample `index` of a sensor.
    pub fn rng(&self, stream: Stream, index: u64) -> ChaCha8Rng {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(((stream as u64) << 48) ^ index);
        rng
    }

    /// The true state at time `t` \[s\].
    pub fn state_at(&self, t: f64) -> RobotState {
        self.motion.state_at(t)
    }

    /// Sample times of a sensor at `rate_hz` over the run: whole microseconds from 0.
    pub fn sample_times(&self, rate_hz: f64) -> Vec<f64> {
        sample_times(self.duration_s(), rate_hz)
    }

    /// Scan number `index` (at `index / rate`), without odometry.
    pub fn lidar_scan(&self, index: usize, timestamp: f64) -> LaserScan {
        let pose = self.state_at(timestamp).world_from_base;
        let mut rng = self.rng(Stream::Lidar, index as u64);
        self.config
            .lidar
            .scan(&self.scene, &pose, timestamp, &mut rng)
    }

    /// Range finder reading number `index` at `timestamp`.
    pub fn range_reading(&self, index: usize, timestamp: f64) -> RangeReading {
        let pose = self.state_at(timestamp).world_from_base;
        let mut rng = self.rng(Stream::RangeFinder, index as u64);
        self.config
            .range_finder
            .read(&self.scene, &pose, timestamp, &mut rng)
    }

    /// The odometry noise model of the configured robot.
    pub fn odometry_config(&self) -> &OdometryConfig {
        match self.config.robot {
            RobotKind::Drone => &self.config.drone_odometry,
            RobotKind::DiffDrive => &self.config.wheel_odometry,
        }
    }

    /// Scans at `times` (sorted), each with the odometry accumulated up to it.
    pub fn lidar_scans(&self, times: &[f64]) -> Vec<LaserScan> {
        let mut odometry = OdometrySimulator::new(
            self.odometry_config().clone(),
            self.rng(Stream::Odometry, 0),
        );
        times
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                let pose = self.state_at(t).world_from_base;
                let mut scan = self.lidar_scan(i, t);
                scan.odometry = Some(odometry.update(&pose3_to_pose2(&pose)));
                scan
            })
            .collect()
    }

    /// Attitude readings at `times` (sorted), the gyro heading integrated from the first.
    pub fn attitude_readings(&self, times: &[f64]) -> Vec<AttitudeReading> {
        let mut gyro = YawGyro::new(self.config.attitude.gyro.clone(), self.rng(Stream::Gyro, 0));
        let true_yaw = |t: f64| self.state_at(t).world_from_base.rotation.euler_angles().2;
        times
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                let pose = self.state_at(t).world_from_base;
                let yaw = gyro.integrate_to(t, true_yaw);
                let mut rng = self.rng(Stream::Attitude, i as u64);
                self.config.attitude.read(&pose, t, yaw, &mut rng)
            })
            .collect()
    }

    /// Optical-flow readings at `times` (sorted), each over the period since the previous time
    /// (none at the first).
    pub fn flow_readings(&self, times: &[f64]) -> Vec<FlowReading> {
        let config = &self.config.flow;
        let scale = config.scale_factor(&mut self.rng(Stream::Flow, 0));
        times
            .windows(2)
            .enumerate()
            .map(|(k, pair)| {
                let (from, to) = (self.state_at(pair[0]), self.state_at(pair[1]));
                // the flow camera sits beside the down-looking range finder
                let [_, below] = self
                    .config
                    .range_finder
                    .true_ranges(&self.scene, &to.world_from_base);
                let mut rng = self.rng(Stream::Flow, k as u64 + 1);
                config.read(
                    (&from.world_from_base, &to.world_from_base),
                    (pair[0], pair[1]),
                    below,
                    scale,
                    &mut rng,
                )
            })
            .collect()
    }

    /// Range finder readings at `times`.
    pub fn range_readings(&self, times: &[f64]) -> Vec<RangeReading> {
        times
            .iter()
            .enumerate()
            .map(|(i, &t)| self.range_reading(i, t))
            .collect()
    }

    /// The whole run's scans (with odometry), range readings, attitudes (at the scan times),
    /// optical flow and ground truth, each sensor at its own rate.
    pub fn lidar_run(&self) -> LidarRun {
        self.lidar_run_until(self.duration_s())
    }

    /// The first `duration_s` of [`Self::lidar_run`] (the same readings, computed for that
    /// span only).
    pub fn lidar_run_until(&self, duration_s: f64) -> LidarRun {
        let times = |rate_hz| sample_times(duration_s.min(self.duration_s()), rate_hz);
        let scan_times = times(self.config.lidar.rate_hz);
        LidarRun {
            scans: self.lidar_scans(&scan_times),
            ranges: self.range_readings(&times(self.config.range_finder.rate_hz)),
            attitudes: self.attitude_readings(&scan_times),
            flows: self.flow_readings(&times(self.config.flow.rate_hz)),
            ground_truth: self.ground_truth(&scan_times),
        }
    }

    /// True `world_from_base` at each of `times`.
    pub fn ground_truth(&self, times: &[f64]) -> Trajectory {
        let mut traj = Trajectory::new();
        for &t in times {
            traj.push(t, self.state_at(t).world_from_base);
        }
        traj
    }

    /// The pose of a sensor mounted at `base_from_sensor`, at time `t`.
    pub fn world_from_sensor(&self, t: f64, base_from_sensor: &Pose3) -> Pose3 {
        self.state_at(t).world_from_base * base_from_sensor
    }

    /// True `world_from_sensor` at each of `times`, for a sensor mounted at `base_from_sensor`.
    pub fn sensor_ground_truth(&self, times: &[f64], base_from_sensor: &Pose3) -> Trajectory {
        let mut traj = Trajectory::new();
        for &t in times {
            traj.push(t, self.world_from_sensor(t, base_from_sensor));
        }
        traj
    }

    /// RGB-D frame number `index` taken at `timestamp` \[s\] by the camera of
    /// [`SimConfig::rgbd`] (usually at [`Self::sample_times`] of its rate). Each frame's noise
    /// depends only on the seed and `index`, so frames can be rendered in any order.
    pub fn rgbd_frame(&self, index: usize, timestamp: f64) -> RgbdFrame {
        let config = &self.config.rgbd;
        let world_from_camera = self.world_from_sensor(timestamp, &config.mount.base_from_camera());
        let (color, depth_m) = render_rgbd(
            &self.scene,
            config,
            world_from_camera,
            &self.rng(Stream::Image, index as u64),
            &self.rng(Stream::Depth, index as u64),
        );
        RgbdFrame {
            index,
            timestamp,
            color,
            depth_m,
            world_from_camera,
        }
    }

    /// Stereo frame number `index` taken at `timestamp` \[s\] by the pair of
    /// [`SimConfig::stereo`].
    pub fn stereo_frame(&self, index: usize, timestamp: f64) -> StereoFrame {
        let config = &self.config.stereo;
        let world_from_left = self.world_from_sensor(timestamp, &config.mount.base_from_camera());
        let rng = self.rng(Stream::Stereo, index as u64);
        let (left, right) = render_stereo(&self.scene, config, world_from_left, &rng);
        StereoFrame {
            index,
            timestamp,
            left,
            right,
            world_from_left,
        }
    }
}

/// `k / rate` for every k with `k / rate <= duration_s`, rounded to whole microseconds.
pub fn sample_times(duration_s: f64, rate_hz: f64) -> Vec<f64> {
    if !(rate_hz > 0.0 && duration_s >= 0.0) {
        return Vec::new();
    }
    let period_us = (1e6 / rate_hz).round().max(1.0) as u64;
    let end_us = (duration_s * 1e6).floor() as u64;
    (0..=end_us / period_us)
        .map(|k| (k * period_us) as f64 / 1e6)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::BUILTIN_WORLDS;
    use nalgebra::Point3;

    #[test]
    fn default_paths_are_collision_free() {
        for name in BUILTIN_WORLDS {
            for robot in [RobotKind::Drone, RobotKind::DiffDrive] {
                let config = SimConfig {
                    robot,
                    ..SimConfig::default()
                };
                let sim = Simulation::new(World::builtin(name).unwrap(), config, 0).unwrap();
                // drone: 12 cm around the base; ground robot: 15 cm around a point above it
                let (clearance, lift) = match robot {
                    RobotKind::Drone => (0.12, 0.0),
                    RobotKind::DiffDrive => (0.15, 0.1),
                };
                assert_collision_free(&sim, clearance, lift);
            }
        }
        let config = SimConfig {
            robot: RobotKind::DiffDrive,
            ..SimConfig::default()
        };
        let office = World::builtin("office").unwrap();
        let laps = Simulation::on_path(office, config, RobotPath::Laps(1), 0).unwrap();
        assert_collision_free(&laps, 0.15, 0.1);
    }

    /// Samples `sim`'s run at 2 Hz: a sphere of `clearance` \[m\] `lift` above the base never
    /// touches the scene.
    fn assert_collision_free(sim: &Simulation, clearance: f64, lift: f64) {
        for t in sim.sample_times(2.0) {
            let p = sim.state_at(t).world_from_base.translation.vector;
            let centre = Point3::new(p.x, p.y, p.z + lift);
            let (world, robot) = (&sim.world.name, sim.config.robot);
            let collides = sim.scene.collides(&centre, clearance);
            assert!(!collides, "{world} {robot:?} at {t} s: {p}");
        }
    }

    #[test]
    fn loop_paths_need_a_ground_robot_and_a_world_with_a_loop() {
        let office = World::builtin("office").unwrap();
        let drone = Simulation::on_path(office, SimConfig::default(), RobotPath::Laps(3), 0);
        assert!(drone.unwrap_err().to_string().contains("ground robot"));
        let config = SimConfig {
            robot: RobotKind::DiffDrive,
            ..SimConfig::default()
        };
        let small = World::builtin("small").unwrap();
        let err = Simulation::on_path(small, config, RobotPath::Laps(3), 0).unwrap_err();
        assert!(err.to_string().contains("no drive_loop"), "{err}");
    }

    #[test]
    fn same_seed_same_run_other_seed_other_noise() {
        let world = World::builtin("small").unwrap();
        let mut config = SimConfig::default();
        config.drone.hover_s = 0.0;
        let motion = WaypointMotion::drone(&world.flight_path[..2], &config.drone).unwrap();
        let sim = |seed| {
            Simulation::with_motion(world.clone(), motion.clone(), config.clone(), seed).unwrap()
        };
        let (a, b, c) = (sim(5).lidar_run(), sim(5).lidar_run(), sim(6).lidar_run());
        assert_eq!(a, b);
        assert_ne!(a.scans[0].ranges_m, c.scans[0].ranges_m);
        assert_eq!(a.ground_truth, c.ground_truth);
        assert_eq!(a.scans.len(), a.ground_truth.len());
        // one flow reading per period after the first instant, each with its own noise
        assert_eq!(a.flows.len() + 1, sim(5).sample_times(10.0).len());
        assert_ne!(a.flows, c.flows);
        // odometry drifts away from the truth, but not wildly
        let last = a.scans.last().unwrap().odometry.unwrap();
        let truth = pose3_to_pose2(&a.ground_truth.poses.last().unwrap().pose);
        let drift = (last.translation.vector - truth.translation.vector).norm();
        assert!(drift > 1e-3 && drift < 0.5, "{drift}");
    }

    #[test]
    fn sample_times_are_whole_microseconds() {
        let t = sample_times(1.0, 30.0);
        assert_eq!(t.len(), 31);
        assert_eq!(t[30], 0.99999);
        assert_eq!(t[1], 0.033333);
        assert_eq!(format!("{:.6}", t[3]).parse::<f64>().unwrap(), t[3]);
        assert!(sample_times(1.0, 0.0).is_empty());
    }
}
