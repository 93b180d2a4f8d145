//! The simulated drone live on ROS 2 (`slamkit sim --ros2 --robot drone`), so the drone node,
//! RViz or Foxglove can be tried with nothing but slamkit: the drone flies its world's flight
//! path and the node publishes what its sensors read, each reading at its time, as the
//! drivers of a real drone would: the planar lidar's `sensor_msgs/LaserScan` (`/scan`), the
//! up- and down-looking range finders' `sensor_msgs/Range` (`/range_up`, `/range_down`; `+inf`
//! when nothing is in range, REP 117) and the flight controller's `sensor_msgs/Imu` (`/imu`:
//! roll, pitch and the gyro-integrated heading as the orientation, the yaw rate since the
//! previous reading as `angular_velocity.z`, no acceleration: its covariance's first element
//! is -1), with the sensors' mountings on `/tf_static`. The readings are those `slamkit sim
//! --sensors lidar2d,range,imu` writes for the same world and seed
//! ([`slamkit_sim::Simulation::lidar_run_until`]); the optical flow has no standard message
//! and is not published.
//!
//! Stamps: whole seconds of the wall clock at the start plus the simulated time, so a reading
//! of simulated time `t` is stamped `start + t`; `speed` plays the flight faster (or slower)
//! than real time. A reading published later than its due time is counted late.

use crate::dds::{latched_qos, reliable_qos, topic, Discovery};
use crate::msgs::{self, Header, Quaternion, Time, Vector3};
use crate::Ros2Error;
use ros2_client::dds::rustdds::no_key::DataWriterCdr;
use ros2_client::dds::rustdds::{DataWriterStatus, QosPolicies, StatusEvented};
use slamkit_core::observation::{ImuSample, RangePair};
use slamkit_core::{Observation, Pose3, Trajectory};
use slamkit_sim::Simulation;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Settings of the simulated drone's node; the topics default to the drone node's.
#[derive(Debug, Clone, PartialEq)]
pub struct DroneSimNodeConfig {
    /// DDS domain and discovery.
    pub discovery: Discovery,
    /// The node's name.
    pub node_name: String,
    /// Scans out.
    pub scan_topic: String,
    /// The up-looking range finder out.
    pub range_up_topic: String,
    /// The down-looking range finder out.
    pub range_down_topic: String,
    /// The IMU out.
    pub imu_topic: String,
    /// The sensors' mountings out.
    pub tf_static_topic: String,
    /// The drone's frame (the IMU's too: a flight controller's IMU is aligned with it).
    pub base_frame: String,
    /// The lidar's frame.
    pub laser_frame: String,
    /// The up-looking finder's frame (x along its beam).
    pub range_up_frame: String,
    /// The down-looking finder's frame.
    pub range_down_frame: String,
    /// Simulated seconds per wall-clock second.
    pub speed: f64,
    /// Fly this much of the flight \[s of simulated time\] (else all of it).
    pub duration_s: Option<f64>,
    /// Before the first reading, wait at most this long for every topic to have a subscriber
    /// (`None`: start at once).
    pub wait_for_subscribers_s: Option<f64>,
}

impl Default for DroneSimNodeConfig {
    fn default() -> Self {
        let node = crate::DroneNodeConfig::default();
        Self {
            discovery: Discovery::default(),
            node_name: "slamkit_sim".into(),
            scan_topic: node.lidar.scan_topic,
            range_up_topic: node.drone.range_up_topic,
            range_down_topic: node.drone.range_down_topic,
            imu_topic: node.drone.imu_topic.unwrap_or_else(|| "/imu".into()),
            tf_static_topic: node.lidar.tf_static_topic,
            base_frame: node.lidar.base_frame,
            laser_frame: "laser".into(),
            range_up_frame: "range_up".into(),
            range_down_frame: "range_down".into(),
            speed: 1.0,
            duration_s: None,
            wait_for_subscribers_s: None,
        }
    }
}

/// What a run of the simulated drone published.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct DroneSimNodeStats {
    /// Scans published.
    pub scans_published: usize,
    /// Range messages published (two a reading: up and down).
    pub ranges_published: usize,
    /// IMU messages published.
    pub imu_published: usize,
    /// Readings published later than their due time.
    pub late: usize,
    /// Seconds spent waiting for subscribers.
    pub waited_for_subscribers_s: f64,
    /// True `world_from_base` at every scan, stamped as the scan.
    #[serde(skip)]
    pub truth: Trajectory,
}

/// The node's writers.
struct Writers {
    scan: DataWriterCdr<msgs::LaserScan>,
    up: DataWriterCdr<msgs::Range>,
    down: DataWriterCdr<msgs::Range>,
    imu: DataWriterCdr<msgs::Imu>,
}

impl Writers {
    /// Whether each writer has matched a reader since the last call (sticky in `matched`).
    fn update_matched(&self, matched: &mut [bool; 4]) {
        let statuses = [
            self.scan.try_recv_status(),
            self.up.try_recv_status(),
            self.down.try_recv_status(),
            self.imu.try_recv_status(),
        ];
        for (m, s) in matched.iter_mut().zip(statuses) {
            *m |= matches!(s, Some(DataWriterStatus::PublicationMatched { .. }));
        }
    }
}

/// Flies the simulated drone of `sim`, publishing its readings, until the flight (or
/// `duration_s` of it) is over or `stop` is set.
///
/// # Errors
/// DDS could not start, a topic or node name is not valid, or `speed` is not positive.
pub fn run_drone_sim_node(
    config: &DroneSimNodeConfig,
    sim: &Simulation,
    stop: &AtomicBool,
) -> Result<DroneSimNodeStats, Ros2Error> {
    if !(config.speed.is_finite() && config.speed > 0.0) {
        return Err(Ros2Error::Config(format!(
            "speed {} must be a positive number",
            config.speed
        )));
    }
    let run = sim.lidar_run_until(config.duration_s.unwrap_or(f64::INFINITY));
    let participant = config.discovery.participant()?;
    let context = ros2_client::Context::from_domain_participant(participant.clone())
        .map_err(crate::dds::dds("starting DDS"))?;
    let name = ros2_client::NodeName::new("/", &config.node_name)
        .map_err(|e| Ros2Error::Name(format!("{}: {e:?}", config.node_name)))?;
    let options = ros2_client::NodeOptions::new().enable_rosout(false);
    let mut node = context
        .new_node(name, options)
        .map_err(crate::dds::dds("creating the node"))?;
    let publisher = participant
        .create_publisher(&QosPolicies::qos_none())
        .map_err(crate::dds::dds("publisher"))?;
    let qos = reliable_qos(100);
    let n = &mut node;
    let scan_t = topic(n, &config.scan_topic, "sensor_msgs", "LaserScan", &qos)?;
    let up_t = topic(n, &config.range_up_topic, "sensor_msgs", "Range", &qos)?;
    let down_t = topic(n, &config.range_down_topic, "sensor_msgs", "Range", &qos)?;
    let imu_t = topic(n, &config.imu_topic, "sensor_msgs", "Imu", &qos)?;
    let tf_t = topic(
        &mut node,
        &config.tf_static_topic,
        "tf2_msgs",
        "TFMessage",
        &latched_qos(),
    )?;
    let make = crate::dds::dds("writer");
    let writers = Writers {
        scan: publisher
            .create_datawriter_no_key_cdr(&scan_t, None)
            .map_err(&make)?,
        up: publisher
            .create_datawriter_no_key_cdr(&up_t, None)
            .map_err(&make)?,
        down: publisher
            .create_datawriter_no_key_cdr(&down_t, None)
            .map_err(&make)?,
        imu: publisher
            .create_datawriter_no_key_cdr(&imu_t, None)
            .map_err(&make)?,
    };
    let tf_static: DataWriterCdr<msgs::TfMessage> = publisher
        .create_datawriter_no_key_cdr(&tf_t, None)
        .map_err(&make)?;
    let start = crate::sim_node::now();
    let origin = Time {
        sec: start.sec,
        nanosec: 0,
    };
    let _ = tf_static.write(mountings(config, sim, origin), None);
    let mut stats = DroneSimNodeStats::default();
    if let Some(wait) = config.wait_for_subscribers_s {
        let started = Instant::now();
        let mut matched = [false; 4];
        while matched.iter().any(|m| !m)
            && started.elapsed().as_secs_f64() < wait
            && !stop.load(Ordering::Relaxed)
        {
            writers.update_matched(&mut matched);
            std::thread::sleep(Duration::from_millis(20));
        }
        stats.waited_for_subscribers_s = started.elapsed().as_secs_f64();
    }
    let mut publish = Publish::new(config, sim, origin);
    let started = Instant::now();
    let mut truth = run.ground_truth.poses.iter();
    for observation in run.observations() {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        let t = observation.timestamp();
        let due = started + Duration::from_secs_f64(t / config.speed);
        match due.checked_duration_since(Instant::now()) {
            Some(wait) => std::thread::sleep(wait),
            None => stats.late += usize::from(due + Duration::from_millis(5) < Instant::now()),
        }
        let stamp = publish.stamp(t);
        match observation {
            Observation::Scan(scan) => {
                let h = publish.header(t, &config.laser_frame);
                let msg = msgs::LaserScan::from_scan(
                    h,
                    &scan,
                    sim.config.lidar.min_range_m,
                    1.0 / sim.config.lidar.rate_hz,
                );
                let _ = writers.scan.write(msg, None);
                stats.scans_published += 1;
                if let Some(pose) = truth.next() {
                    stats.truth.push(stamp.as_secs_f64(), pose.pose);
                }
            }
            Observation::Range(pair) => {
                let (up, down) = publish.ranges(&pair);
                let _ = writers.up.write(up, None);
                let _ = writers.down.write(down, None);
                stats.ranges_published += 2;
            }
            Observation::Imu(sample) => {
                let _ = writers.imu.write(publish.imu(&sample), None);
                stats.imu_published += 1;
            }
            _ => {}
        }
    }
    // the writers go with the node: give the last samples time to leave
    std::thread::sleep(Duration::from_millis(200));
    Ok(stats)
}

/// `base → laser`, `base → range_up` (x up) and `base → range_down` (x down).
fn mountings(config: &DroneSimNodeConfig, sim: &Simulation, stamp: Time) -> msgs::TfMessage {
    let finder = &sim.config.range_finder;
    let pitch = |angle: f64, z: f64| {
        Pose3::from_parts(
            nalgebra::Translation3::new(0.0, 0.0, z),
            nalgebra::UnitQuaternion::from_euler_angles(0.0, angle, 0.0),
        )
    };
    let half_pi = std::f64::consts::FRAC_PI_2;
    let transforms = [
        (&config.laser_frame, sim.config.lidar.base_from_lidar()),
        (&config.range_up_frame, pitch(-half_pi, finder.up_offset_m)),
        (
            &config.range_down_frame,
            pitch(half_pi, -finder.down_offset_m),
        ),
    ]
    .into_iter()
    .map(|(child, base_from_child)| msgs::TransformStamped {
        header: Header {
            stamp,
            frame_id: config.base_frame.clone(),
        },
        child_frame_id: child.clone(),
        transform: msgs::Pose::from_isometry(&base_from_child),
    })
    .collect();
    msgs::TfMessage { transforms }
}

/// Turns the simulator's readings into messages.
struct Publish<'a> {
    config: &'a DroneSimNodeConfig,
    sim: &'a Simulation,
    origin: Time,
    /// Time and heading of the previous IMU reading.
    last_imu: Option<(f64, f64)>,
}

impl<'a> Publish<'a> {
    fn new(config: &'a DroneSimNodeConfig, sim: &'a Simulation, origin: Time) -> Self {
        Self {
            config,
            sim,
            origin,
            last_imu: None,
        }
    }

    /// The stamp of simulated time `t`: the origin plus `t`, exactly.
    fn stamp(&self, t: f64) -> Time {
        let offset = Time::from_secs_f64(t);
        Time {
            sec: self.origin.sec.saturating_add(offset.sec),
            nanosec: offset.nanosec,
        }
    }

    fn header(&self, t: f64, frame: &str) -> Header {
        Header {
            stamp: self.stamp(t),
            frame_id: frame.to_string(),
        }
    }

    /// The pair as two `Range` messages (up, down).
    fn ranges(&self, pair: &RangePair) -> (msgs::Range, msgs::Range) {
        let max = self.sim.config.range_finder.max_range_m as f32;
        let msg = |frame: &str, reading: Option<f64>| msgs::Range {
            header: self.header(pair.timestamp, frame),
            radiation_type: 1,
            field_of_view: 0.05,
            min_range: 0.0,
            max_range: max,
            range: reading.map_or(f32::INFINITY, |r| r as f32),
        };
        (
            msg(&self.config.range_up_frame, pair.up_m),
            msg(&self.config.range_down_frame, pair.down_m),
        )
    }

    /// The attitude as an `Imu` message: orientation roll, pitch and the gyro's heading, the
    /// yaw rate over the time since the previous reading.
    fn imu(&mut self, sample: &ImuSample) -> msgs::Imu {
        let t = sample.timestamp;
        let yaw = sample.gyro_yaw_rad.unwrap_or(0.0);
        let rate = match self.last_imu {
            Some((t0, yaw0)) if t > t0 => (yaw - yaw0) / (t - t0),
            _ => 0.0,
        };
        self.last_imu = Some((t, yaw));
        let q = nalgebra::UnitQuaternion::from_euler_angles(sample.roll_rad, sample.pitch_rad, yaw);
        let mut linear_acceleration_covariance = [0.0; 9];
        linear_acceleration_covariance[0] = -1.0;
        msgs::Imu {
            header: self.header(t, &self.config.base_frame),
            orientation: Quaternion {
                x: q.i,
                y: q.j,
                z: q.k,
                w: q.w,
            },
            angular_velocity: Vector3 {
                x: 0.0,
                y: 0.0,
                z: rate,
            },
            linear_acceleration_covariance,
            ..msgs::Imu::default()
        }
    }
}
