//! The ground robot node (`slamkit ros2 nav`): the camera input of `slamkit ros2 vo` (colour,
//! registered depth, `CameraInfo`, the mounting from `/tf_static`) and a goal, either given at
//! start or a `geometry_msgs/PoseStamped` on `/goal_pose` (as RViz's "2D Goal Pose" and Nav2
//! publish it); the [`GroundRobotNav`] session `slamkit nav` runs in the simulator (RGB-D
//! visual odometry, a floor grid from the depth, A* re-planning, the carrot tracker); out,
//! for every frame: `geometry_msgs/Twist` on `/cmd_vel` (zero while VO has lost the frame,
//! once the goal is reached, and when the node stops), and for every tracked frame
//! `map → base_frame` on `/tf`, `/pose` and `/path` as the camera node publishes them; each new
//! plan as a `nav_msgs/Path` on `/plan` (Nav2's topic), and the floor grid as a
//! `nav_msgs/OccupancyGrid` on `/map` (reliable, transient local) every `map_period_s` of
//! sensor time.
//!
//! Frames (REP 105, REP 120): the base frame (default `base_footprint`) lies on the floor
//! under the robot's centre, x forward, z up; the camera's mounting is `base_frame → optical
//! frame` from `/tf_static`. The map frame is the base frame where the robot stood at the
//! first frame after the goal was known; a goal on `/goal_pose` is read in the map frame (its
//! `frame_id` must be the map frame, or empty). The session starts with the first frame that
//! has a goal; frames before it are counted and left. A later goal re-plans at once; the
//! floor grid covers the start and the first goal widened by
//! [`slamkit_slam::ground_robot::MAP_MARGIN_M`].
//!
//! The robot is not told to move before the session has a pose; a command answers each frame,
//! integrated over the time since the previous frame's stamp.

use crate::camera_input::{run_camera_input, Shared};
use crate::dds::{
    advertise, latched_qos, reliable_qos, sensor_qos, subscribe, PoseTopics, PoseWriters, Refusals,
};
use crate::grid_msg::image_msg;
use crate::msgs::{self, Header, Time, Twist, Vector3};
use crate::vo_node::{VoNodeConfig, VoNodeStats};
use crate::Ros2Error;
use crossbeam_channel::RecvTimeoutError;
use nalgebra::Point2;
use ros2_client::{Publisher, Subscription};
use serde_json::{json, Value};
use slamkit_core::camera::PinholeCamera;
use slamkit_core::pose::pose2_to_pose3;
use slamkit_core::{Pose3, Trajectory};
use slamkit_map::grid_io::tri_grid_image;
use slamkit_nav::{TrackerCommand, TrackerStatus};
use slamkit_slam::ground_robot::{GroundRobotNavConfig, MountedCamera};
use slamkit_slam::GroundRobotNav;
use slamkit_slam::{Session, SlamError};
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

/// The stage of the latency in [`VoNodeStats::latency`]: a colour image from its reader to
/// its `/cmd_vel` command.
pub const LATENCY_STAGE: &str = "image_receive_to_cmd_vel";

/// How long the writers stay after the stop command, for it to be delivered.
pub const STOP_LINGER: Duration = Duration::from_millis(300);

/// Settings of the ground robot node.
#[derive(Debug, Clone, PartialEq)]
pub struct NavNodeConfig {
    /// The camera's topics, the pose's topics and frames, the frame queue and the idle
    /// timeout, as for the camera node (its `base_frame` default here is `base_footprint`).
    pub camera: VoNodeConfig,
    /// Goals in (`geometry_msgs/PoseStamped`).
    pub goal_topic: String,
    /// Velocity commands out (`geometry_msgs/Twist`).
    pub cmd_vel_topic: String,
    /// The floor grid out (`nav_msgs/OccupancyGrid`).
    pub map_topic: String,
    /// Each plan out (`nav_msgs/Path`).
    pub plan_topic: String,
    /// Publish the map this often, in sensor time \[s\].
    pub map_period_s: f64,
}

impl Default for NavNodeConfig {
    fn default() -> Self {
        Self {
            camera: VoNodeConfig {
                base_frame: "base_footprint".into(),
                ..VoNodeConfig::default()
            },
            goal_topic: "/goal_pose".into(),
            cmd_vel_topic: "/cmd_vel".into(),
            map_topic: "/map".into(),
            plan_topic: "/plan".into(),
            map_period_s: 1.0,
        }
    }
}

/// Counters of a ground robot node run.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct NavNodeStats {
    /// The camera input's counters (its latency stage is [`LATENCY_STAGE`]).
    pub camera: VoNodeStats,
    /// Frames that came before a goal was known (not used).
    pub frames_before_goal: usize,
    /// Goals taken off `/goal_pose`.
    pub goals_received: usize,
    /// Goals refused (another frame, not finite), the first few with why.
    pub goals_refused: Refusals,
    /// Velocity commands published (one a frame the session took, one at the stop).
    pub commands_published: usize,
    /// Maps published.
    pub maps_published: usize,
    /// The tracker's status at the last frame.
    pub last_status: Option<TrackerStatus>,
}

/// What a ground robot node run leaves.
pub struct NavNodeRun {
    /// The session (`None`: no frame came with a goal), to save its map.
    pub session: Option<GroundRobotNav>,
    /// The camera the images came from.
    pub camera: PinholeCamera,
    /// `map_from_base` of every tracked frame, at its colour stamp.
    pub trajectory: Trajectory,
    /// Every command published for a frame, with the frame's stamp \[s\].
    pub commands: Vec<(f64, TrackerCommand)>,
    /// Counters.
    pub stats: NavNodeStats,
}

impl NavNodeRun {
    /// The files of a run: what [`NavNodeRun::finish`] and the caller's `report.json` write.
    pub const OUTPUTS: &'static [&'static str] = &["trajectory.tum", "map.skmap", "report.json"];

    /// Writes `trajectory.tum` (`map_from_base` of every tracked frame) and, when the session
    /// ran, `map.skmap` (the camera's keyframes and the floor grid, as `slamkit nav` saves
    /// them) into `dir`, and returns `report.json`: the goal, the session's counters and the
    /// node's, its receive-to-command latency and the settings.
    ///
    /// # Errors
    /// [`Ros2Error::Slam`] when a file cannot be written.
    pub fn finish(&self, nav: &GroundRobotNavConfig, dir: &Path) -> Result<Value, Ros2Error> {
        slamkit_io::write_tum(&dir.join("trajectory.tum"), &self.trajectory)
            .map_err(SlamError::from)?;
        if let Some(session) = &self.session {
            Session::save(session, &dir.join("map.skmap"))?;
        }
        let s = self.session.as_ref();
        let c = self.camera.intrinsics;
        Ok(json!({
            "input": "ros2",
            "localisation": "RGB-D visual odometry",
            "goal_m": s.map(|s| [s.goal().x, s.goal().y]),
            "camera": { "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy,
                        "width": c.width, "height": c.height },
            "frames": s.map(GroundRobotNav::camera_stats),
            "plans": s.map_or(0, |s| s.plans().len()),
            "plan_failures": s.map_or(0, GroundRobotNav::plan_failures),
            "timings_ms": s.map(|s| s.timings().summary()),
            "config": nav,
            "node": self.stats,
            "node_latency_ms": self.stats.camera.latency.summary(),
        }))
    }
}

/// The node's writers besides the pose's.
struct NavWriters {
    pose: PoseWriters,
    cmd_vel: Publisher<Twist>,
    map: Publisher<msgs::OccupancyGrid>,
    plan: Publisher<msgs::Path>,
}

/// Runs the ground robot node until `stop` is set (or the input has been idle), heading for
/// `goal` (map x, y) if given, else for the first goal on `/goal_pose`.
///
/// # Errors
/// DDS could not start, a topic or node name is not valid, no `CameraInfo` came before the
/// node stopped, or the session could not be made.
pub fn run_nav_node(
    config: &NavNodeConfig,
    nav: &GroundRobotNavConfig,
    goal: Option<Point2<f64>>,
    stop: &AtomicBool,
) -> Result<NavNodeRun, Ros2Error> {
    nav.validate()?;
    let c = &config.camera;
    let mut node = c.discovery.node(&c.node_name)?;
    let n = &mut node;
    let topics = PoseTopics {
        tf: &c.tf_topic,
        pose: &c.pose_topic,
        path: Some(&c.path_topic),
    };
    let mut writers = NavWriters {
        pose: PoseWriters::open(n, &topics)?,
        cmd_vel: advertise(
            n,
            &config.cmd_vel_topic,
            ("geometry_msgs", "Twist"),
            &reliable_qos(10),
        )?,
        map: advertise(
            n,
            &config.map_topic,
            ("nav_msgs", "OccupancyGrid"),
            &latched_qos(),
        )?,
        plan: advertise(n, &config.plan_topic, ("nav_msgs", "Path"), &latched_qos())?,
    };
    // best effort: matches RViz's reliable writer and any other
    let goals = subscribe(
        n,
        &config.goal_topic,
        ("geometry_msgs", "PoseStamped"),
        &sensor_qos(),
    )?;
    let mut stats = NavNodeStats::default();
    let ((session, camera, trajectory, commands), camera_stats) =
        run_camera_input(n, c, stop, |camera, frames, shared| {
            let mut driver = Driver {
                config,
                nav,
                camera,
                goal,
                session: None,
                last_stamp: None,
                next_map_s: f64::NEG_INFINITY,
                plans: 0,
                trajectory: Trajectory::default(),
                commands: Vec::new(),
                stats: &mut stats,
                writers: &mut writers,
            };
            loop {
                driver.take_goals(&goals);
                let pair = match frames.recv_timeout(Duration::from_millis(50)) {
                    Ok(pair) => pair,
                    Err(RecvTimeoutError::Timeout) => continue,
                    Err(RecvTimeoutError::Disconnected) => break,
                };
                match pair.frame() {
                    Ok(observation) => driver.frame(observation, pair.stamp, shared)?,
                    Err(why) => shared.count(|s| s.undecodable.add(why)),
                }
                shared.count(|s| s.latency.record_since(LATENCY_STAGE, pair.received));
            }
            driver.stop();
            let d = driver;
            Ok((d.session, d.camera, d.trajectory, d.commands))
        })?;
    stats.camera = camera_stats;
    Ok(NavNodeRun {
        session,
        camera,
        trajectory,
        commands,
        stats,
    })
}

/// The consuming side: the session, made at the first frame with a goal, and what it
/// publishes.
struct Driver<'a> {
    config: &'a NavNodeConfig,
    nav: &'a GroundRobotNavConfig,
    camera: PinholeCamera,
    goal: Option<Point2<f64>>,
    session: Option<GroundRobotNav>,
    last_stamp: Option<f64>,
    next_map_s: f64,
    plans: usize,
    trajectory: Trajectory,
    commands: Vec<(f64, TrackerCommand)>,
    stats: &'a mut NavNodeStats,
    writers: &'a mut NavWriters,
}

impl Driver<'_> {
    /// Takes the goals waiting on `/goal_pose`; the newest good one is the goal.
    fn take_goals(&mut self, reader: &Subscription<msgs::PoseStamped>) {
        loop {
            let goal = match reader.take() {
                Ok(Some((msg, _))) => msg,
                Ok(None) => return,
                Err(e) => {
                    self.stats.goals_refused.add(format!("DDS read: {e:?}"));
                    continue;
                }
            };
            self.stats.goals_received += 1;
            match goal_of(&goal, &self.config.camera.map_frame) {
                Ok(goal) => {
                    self.goal = Some(goal);
                    if let Some(session) = &mut self.session {
                        session.set_goal(goal);
                    }
                }
                Err(why) => self.stats.goals_refused.add(why),
            }
        }
    }

    /// Runs the session on one frame and publishes what it gives.
    fn frame(
        &mut self,
        observation: slamkit_core::Observation,
        stamp: Time,
        shared: &Shared,
    ) -> Result<(), Ros2Error> {
        let Some(goal) = self.goal else {
            self.stats.frames_before_goal += 1;
            return Ok(());
        };
        let session = match &mut self.session {
            Some(session) => session,
            None => {
                let base = &self.config.camera.base_frame;
                let (base_from_camera, source) = shared.base_from_camera(base);
                shared.count(|s| {
                    let (t, q) = (
                        base_from_camera.translation.vector,
                        base_from_camera.rotation.quaternion(),
                    );
                    s.mounting = Some(([t.x, t.y, t.z], [q.i, q.j, q.k, q.w], source));
                });
                let mounted = MountedCamera {
                    intrinsics: self.camera.intrinsics,
                    base_from_camera,
                };
                let start = Pose3::identity();
                self.session
                    .insert(GroundRobotNav::new(self.nav, mounted, &start, goal)?)
            }
        };
        let t = stamp.as_secs_f64();
        let Some(outcome) = session.process(observation) else {
            return Ok(());
        };
        let dt = self.last_stamp.map_or(0.0, |t0| t - t0);
        self.last_stamp = Some(t);
        let command = session.command(dt);
        let _ = self.writers.cmd_vel.publish(twist(&command));
        self.stats.commands_published += 1;
        self.stats.last_status = Some(command.status);
        self.commands.push((t, command));
        let camera = &self.config.camera;
        let (map, base) = (camera.map_frame.as_str(), camera.base_frame.as_str());
        if let Some(pose) = outcome.world_from_base {
            let map_from_base = pose2_to_pose3(&pose);
            self.writers
                .pose
                .publish((map, base, &map_from_base), map, &map_from_base, stamp);
            self.trajectory.push(t, map_from_base);
            shared.count(|s| s.poses_published += 1);
        }
        if session.plans().len() != self.plans {
            self.plans = session.plans().len();
            let header = Header {
                stamp,
                frame_id: map.to_string(),
            };
            let poses = session.path().iter().map(|p| msgs::PoseStamped {
                header: header.clone(),
                pose: msgs::Pose::from_isometry(&pose2_to_pose3(&slamkit_core::Pose2::new(
                    p.coords, 0.0,
                ))),
            });
            let poses = poses.collect();
            let _ = self.writers.plan.publish(msgs::Path { header, poses });
        }
        if t >= self.next_map_s {
            self.next_map_s = t + self.config.map_period_s;
            self.publish_map(stamp);
        }
        Ok(())
    }

    /// The floor grid on `/map`.
    fn publish_map(&mut self, stamp: Time) {
        if let Some(session) = &self.session {
            let grid = session.grid();
            let map = &self.config.camera.map_frame;
            let msg = image_msg(&tri_grid_image(&grid), grid.resolution_m(), map, stamp);
            let _ = self.writers.map.publish(msg);
            self.stats.maps_published += 1;
        }
    }

    /// The robot stops (a zero command), and the last map goes out. The writers then stay
    /// [`STOP_LINGER`] for the readers to take them: `ros2-client` offers no wait for
    /// acknowledgements, and a writer gone before its reliable sample was acknowledged
    /// leaves the robot driving on its last command.
    fn stop(&mut self) {
        let _ = self.writers.cmd_vel.publish(Twist::default());
        self.stats.commands_published += 1;
        if let Some(t) = self.last_stamp {
            self.publish_map(Time::from_secs_f64(t));
        }
        std::thread::sleep(STOP_LINGER);
    }
}

/// A tracker command as a `geometry_msgs/Twist` (forward speed along x, yaw rate about z).
fn twist(command: &TrackerCommand) -> Twist {
    Twist {
        linear: Vector3 {
            x: command.speed_m_s,
            ..Vector3::default()
        },
        angular: Vector3 {
            z: command.yaw_rate_rad_s,
            ..Vector3::default()
        },
    }
}

/// The goal (x, y) of a `PoseStamped` in `map_frame` (or in no frame).
///
/// ```
/// use slamkit_ros2::msgs::{Header, PoseStamped};
/// use slamkit_ros2::nav_node::goal_of;
/// let mut goal = PoseStamped::default();
/// goal.pose.position.x = 2.5;
/// goal.header.frame_id = "map".into();
/// assert_eq!(goal_of(&goal, "map").unwrap(), nalgebra::Point2::new(2.5, 0.0));
/// goal.header.frame_id = "odom".into();
/// assert!(goal_of(&goal, "map").is_err());
/// ```
///
/// # Errors
/// A goal in another frame, or not finite.
pub fn goal_of(goal: &msgs::PoseStamped, map_frame: &str) -> Result<Point2<f64>, String> {
    let frame = goal.header.frame_id.trim_start_matches('/');
    if !frame.is_empty() && frame != map_frame {
        return Err(format!(
            "a goal in frame {frame:?}: goals are taken in {map_frame:?}"
        ));
    }
    let p = goal.pose.position;
    if !(p.x.is_finite() && p.y.is_finite()) {
        return Err(format!("a goal at ({}, {}): not finite", p.x, p.y));
    }
    Ok(Point2::new(p.x, p.y))
}
