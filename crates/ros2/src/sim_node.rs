//! The simulated ground robot of `slamkit nav` live on ROS 2 (`slamkit sim --ros2`), so the
//! camera and nav nodes, RViz or Foxglove can be tried with nothing but slamkit: at the
//! camera's rate, in real time, the robot's RGB-D camera renders a frame where the robot
//! stands and the node publishes it as a RealSense driver does (rgb8 colour, 32FC1 depth
//! registered to it, `CameraInfo`, all stamped with the wall clock; `base_footprint →
//! camera_color_optical_frame` on `/tf_static`); between frames the robot drives by the
//! newest `geometry_msgs/Twist` on `/cmd_vel` (`linear.x`, `angular.z`), as a base driver
//! does, stopping when no command came for `cmd_timeout_s`; a move into an obstacle is
//! refused and counted. A frame that takes longer to render than its period is published
//! late and counted; simulated time then runs slower than the wall clock (each frame moves
//! the robot by one period). With `slamkit ros2 nav` on the other side, the navigation loop of
//! `slamkit nav` runs over DDS.

use crate::dds::{advertise, latched_qos, reliable_qos, sensor_qos, subscribe, Discovery};
use crate::msgs::{self, Header, Time};
use crate::Ros2Error;
use slamkit_core::Trajectory;
use slamkit_sim::GroundRobot;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime};

/// Settings of the simulated robot's node; the camera topics default to the RealSense
/// driver's, as the camera and nav nodes expect them.
#[derive(Debug, Clone, PartialEq)]
pub struct SimNodeConfig {
    /// DDS domain and discovery.
    pub discovery: Discovery,
    /// The node's name.
    pub node_name: String,
    /// Colour images out.
    pub rgb_topic: String,
    /// Depth images out (registered to colour).
    pub depth_topic: String,
    /// The camera's calibration out.
    pub camera_info_topic: String,
    /// The camera's mounting out.
    pub tf_static_topic: String,
    /// Velocity commands in.
    pub cmd_vel_topic: String,
    /// The robot's frame on the floor.
    pub base_frame: String,
    /// The camera's optical frame.
    pub optical_frame: String,
    /// The robot stops when no command came for this long \[s\].
    pub cmd_timeout_s: f64,
    /// Radius of the robot's body: moves that bring it into an obstacle are refused \[m\].
    pub robot_radius_m: f64,
    /// Stop after this much time \[s\] (else at `stop`).
    pub duration_s: Option<f64>,
}

impl Default for SimNodeConfig {
    fn default() -> Self {
        let camera = crate::VoNodeConfig::default();
        Self {
            discovery: Discovery::default(),
            node_name: "slamkit_sim".into(),
            rgb_topic: camera.rgb_topic,
            depth_topic: camera.depth_topic,
            camera_info_topic: camera.camera_info_topic,
            tf_static_topic: camera.tf_static_topic,
            cmd_vel_topic: "/cmd_vel".into(),
            base_frame: "base_footprint".into(),
            optical_frame: "camera_color_optical_frame".into(),
            cmd_timeout_s: 0.5,
            robot_radius_m: slamkit_slam::ground_robot::GroundRobotNavConfig::default()
                .robot_radius_m,
            duration_s: None,
        }
    }
}

/// What a run of the simulated robot did.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct SimNodeStats {
    /// Camera frames published.
    pub frames_published: usize,
    /// Commands taken off `/cmd_vel`.
    pub commands_received: usize,
    /// Frame periods driven by a fresh command.
    pub steps_driven: usize,
    /// Moves refused because the body would touch an obstacle.
    pub blocked_steps: usize,
    /// Frames published later than their period allowed (rendering slower than the rate).
    pub late_frames: usize,
    /// True `world_from_base` at every frame, stamped with the frame's time.
    #[serde(skip)]
    pub truth: Trajectory,
}

/// Runs the simulated robot until `stop` is set or `duration_s` has passed.
///
/// # Errors
/// DDS could not start, or a topic or node name is not valid.
pub fn run_sim_node(
    config: &SimNodeConfig,
    robot: &mut GroundRobot,
    stop: &AtomicBool,
) -> Result<SimNodeStats, Ros2Error> {
    let mut node = config.discovery.node(&config.node_name)?;
    let n = &mut node;
    let sensor = reliable_qos(4);
    let image = ("sensor_msgs", "Image");
    let rgb = advertise::<msgs::Image>(n, &config.rgb_topic, image, &sensor)?;
    let depth = advertise::<msgs::Image>(n, &config.depth_topic, image, &sensor)?;
    let info_type = ("sensor_msgs", "CameraInfo");
    let info = advertise::<msgs::CameraInfo>(n, &config.camera_info_topic, info_type, &sensor)?;
    let tf_type = ("tf2_msgs", "TFMessage");
    let tf_static = advertise(n, &config.tf_static_topic, tf_type, &latched_qos())?;
    let twist = ("geometry_msgs", "Twist");
    let commands = subscribe::<msgs::Twist>(n, &config.cmd_vel_topic, twist, &sensor_qos())?;
    let camera = robot.simulation().config.rgbd.clone();
    let header = |stamp, frame: &str| Header {
        stamp,
        frame_id: frame.to_string(),
    };
    let mount = msgs::TransformStamped {
        header: header(now(), &config.base_frame),
        child_frame_id: config.optical_frame.clone(),
        transform: msgs::Pose::from_isometry(&camera.mount.base_from_camera()),
    };
    let _ = tf_static.publish(msgs::TfMessage {
        transforms: vec![mount],
    });
    let period = Duration::from_secs_f64(1.0 / camera.rate_hz);
    let started = Instant::now();
    let mut stats = SimNodeStats::default();
    let mut newest: Option<(msgs::Twist, Instant)> = None;
    for index in 0u32.. {
        let due = started + period * index;
        let elapsed = started.elapsed();
        if stop.load(Ordering::Relaxed)
            || config
                .duration_s
                .is_some_and(|d| elapsed.as_secs_f64() >= d)
        {
            break;
        }
        match due.checked_duration_since(Instant::now()) {
            Some(wait) => std::thread::sleep(wait),
            None if index > 0 => stats.late_frames += 1,
            None => {}
        }
        while let Ok(Some((command, _))) = commands.take() {
            stats.commands_received += 1;
            newest = Some((command, Instant::now()));
        }
        if index > 0 {
            let fresh = newest.filter(|(_, at)| at.elapsed().as_secs_f64() <= config.cmd_timeout_s);
            if let Some((command, _)) = fresh {
                stats.steps_driven += 1;
                let dt = period.as_secs_f64();
                let moved = robot.drive(
                    command.linear.x,
                    command.angular.z,
                    dt,
                    config.robot_radius_m,
                );
                stats.blocked_steps += usize::from(!moved);
            }
        }
        let stamp = now();
        let t = stamp.as_secs_f64();
        let frame = robot.rgbd_frame(index as usize, t);
        let h = header(stamp, &config.optical_frame);
        let _ = info.publish(msgs::CameraInfo::pinhole(h.clone(), &camera.intrinsics));
        let _ = depth.publish(msgs::Image::depth_32fc1(h.clone(), &frame.depth_m));
        let _ = rgb.publish(msgs::Image::rgb8(h, &frame.color));
        stats.frames_published += 1;
        stats.truth.push(t, robot.at_base_height(&robot.truth()));
    }
    Ok(stats)
}

/// The wall clock as a ROS time.
pub(crate) fn now() -> Time {
    let since = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .unwrap_or_default();
    Time::from_secs_f64(since.as_secs_f64())
}
