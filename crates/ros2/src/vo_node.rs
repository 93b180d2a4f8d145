//! The RGB-D camera node (`slamkit ros2 vo`): colour and depth `sensor_msgs/Image`s (depth
//! registered to colour; `sensor_msgs/CompressedImage` on `image_transport`'s `.../compressed`
//! and `.../compressedDepth` topics) and the colour camera's `sensor_msgs/CameraInfo` in
//! (sensor-data QoS),
//! `/tf_static` for the camera's mounting; a [`VisualSlam`] session, the one `slamkit vo` runs
//! on a bag, through the same pipeline ([`slamkit_slam::visual::run`]); out, for every tracked
//! frame: the `map → base` transform on `/tf`, `geometry_msgs/PoseWithCovarianceStamped` on
//! `/pose` (covariance zero: the session does not estimate one) and `nav_msgs/Path` on `/path`.
//!
//! Frames (REP 105, REP 103): a camera alone has no odometry, so the node publishes
//! `map → base_frame` (default `camera_link`, the RealSense driver's body frame) and leaves
//! `base_frame → camera_color_optical_frame` to the driver's static transforms. The session's
//! world is the optical frame of its first camera pose (z forward, y down); the map frame is
//! the base frame at that pose (x forward, z up): `map_from_base = B · world_from_camera · B⁻¹`
//! with `B = base_from_camera` from `/tf_static` (else the REP 103 rotation of an `_optical`
//! frame, or the identity when the images are stamped in the base frame itself), fixed when
//! the first pose is published. Localising in a saved map, the map frame is the base frame at
//! the map's origin.
//!
//! Threads: the input's (`camera_input`: readers, pairing, a bounded frame queue),
//! and the caller's, which runs the visual pipeline (its own decoding, preparation and mapping
//! threads) and publishes. The session is made once the first `CameraInfo` came.

use crate::camera_input::{run_camera_input, Pair, Shared};
use crate::dds::{Discovery, PoseTopics, PoseWriters, Refusals};
use crate::msgs::Time;
use crate::Ros2Error;
use crossbeam_channel::{unbounded, Receiver};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use slamkit_core::camera::PinholeCamera;
use slamkit_core::{Observation, Pose3, StageTimings};
use slamkit_slam::record::VisualRecording;
use slamkit_slam::visual::{self, RunOptions, VisualRun, VisualUpdate};
use slamkit_slam::{SlamError, VisualSlam};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// The stage of [`VoNodeStats::latency`]: a colour image from its reader to its published pose.
pub const LATENCY_STAGE: &str = "image_receive_to_publish";

/// Settings of the camera node; the topic defaults are the RealSense ROS 2 driver's
/// (`realsense2_camera` 4.x with `align_depth.enable:=true`).
#[derive(Debug, Clone, PartialEq)]
pub struct VoNodeConfig {
    /// DDS domain and discovery.
    pub discovery: Discovery,
    /// The node's name.
    pub node_name: String,
    /// Colour images (`sensor_msgs/Image`: rgb8, bgr8, mono8).
    pub rgb_topic: String,
    /// Depth images registered to colour (16UC1 mm, 32FC1 m).
    pub depth_topic: String,
    /// The colour camera's calibration.
    pub camera_info_topic: String,
    /// Static transforms (the camera's mounting).
    pub tf_static_topic: String,
    /// Transforms out.
    pub tf_topic: String,
    /// The pose out.
    pub pose_topic: String,
    /// The path out.
    pub path_topic: String,
    /// The map frame (REP 105).
    pub map_frame: String,
    /// The robot's (or the camera's body) frame, the child of `map` on `/tf`.
    pub base_frame: String,
    /// Paired frames waiting for the session at most; more are dropped.
    pub frame_queue: usize,
    /// Stop once no message came for this long after the first image \[s\].
    pub idle_exit_s: Option<f64>,
    /// Record what the camera node processed to this MCAP file ([`VisualRecording`]: each
    /// frame's image and pose, the path now and then, the final path and point map), as
    /// `slamkit vo --record` records a dataset; the ground robot node does not record.
    pub record: Option<PathBuf>,
}

impl Default for VoNodeConfig {
    fn default() -> Self {
        Self {
            discovery: Discovery::default(),
            node_name: "slamkit".into(),
            rgb_topic: "/camera/camera/color/image_raw".into(),
            depth_topic: "/camera/camera/aligned_depth_to_color/image_raw".into(),
            camera_info_topic: "/camera/camera/color/camera_info".into(),
            tf_static_topic: "/tf_static".into(),
            tf_topic: "/tf".into(),
            pose_topic: "/pose".into(),
            path_topic: "/path".into(),
            map_frame: "map".into(),
            base_frame: "camera_link".into(),
            frame_queue: visual::pipeline::REALTIME_QUEUE,
            idle_exit_s: None,
            record: None,
        }
    }
}

/// Counters and timings of a camera node run.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct VoNodeStats {
    /// Colour images received.
    pub colour_received: usize,
    /// Depth images received.
    pub depth_received: usize,
    /// Calibration messages received.
    pub camera_info_received: usize,
    /// Static transform messages received.
    pub tf_static_received: usize,
    /// Colour and depth pairs queued for the session.
    pub frames_queued: usize,
    /// Pairs dropped because `frame_queue` pairs were waiting.
    pub frames_dropped: usize,
    /// Colour and depth images left without a partner within the pairing gap.
    pub unpaired: (usize, usize),
    /// Messages that did not convert (the first few with why).
    pub undecodable: Refusals,
    /// Poses published.
    pub poses_published: usize,
    /// `base_from_camera` used (translation, quaternion x y z w), and where it came from.
    pub mounting: Option<([f64; 3], [f64; 4], String)>,
    /// Per frame, [`LATENCY_STAGE`].
    #[serde(skip)]
    pub latency: StageTimings,
}

/// What a camera node run leaves.
pub struct VoNodeRun {
    /// The session, to save its map.
    pub session: VisualSlam,
    /// The pipeline's trajectory, frame statuses and counts, as `slamkit vo` gets them.
    pub run: VisualRun,
    /// The camera the session was made for.
    pub camera: PinholeCamera,
    /// Counters.
    pub stats: VoNodeStats,
    /// The recording, to be finished with the final path and map ([`VoNodeRun::finish`](
    /// crate::vo_run)).
    pub recording: Option<VisualRecording>,
}

/// Whether `topic` is an `image_transport` compressed one (`.../compressed`,
/// `.../compressedDepth`), which carries `sensor_msgs/CompressedImage`.
///
/// ```
/// use slamkit_ros2::vo_node::is_compressed;
/// assert!(is_compressed("/camera/camera/color/image_raw/compressed"));
/// assert!(is_compressed("/camera/camera/aligned_depth_to_color/image_raw/compressedDepth"));
/// assert!(!is_compressed("/camera/camera/color/image_raw"));
/// ```
pub fn is_compressed(topic: &str) -> bool {
    topic.ends_with("/compressed") || topic.ends_with("/compressedDepth")
}

/// Runs the camera node until `stop` is set (or the input has been idle `idle_exit_s`).
/// `make_session` builds the session for the camera of the first `CameraInfo`.
///
/// # Errors
/// DDS could not start, a topic or node name is not valid, no `CameraInfo` came before the
/// node stopped, or the session could not be made or failed.
pub fn run_vo_node(
    config: &VoNodeConfig,
    make_session: impl FnOnce(&PinholeCamera) -> Result<VisualSlam, SlamError>,
    stop: &AtomicBool,
) -> Result<VoNodeRun, Ros2Error> {
    let mut node = config.discovery.node(&config.node_name)?;
    let topics = PoseTopics {
        tf: &config.tf_topic,
        pose: &config.pose_topic,
        path: Some(&config.path_topic),
    };
    let mut writers = PoseWriters::open(&mut node, &topics)?;
    let recording = config
        .record
        .as_deref()
        .map(VisualRecording::live)
        .transpose()?;
    let ((session, run, camera, recording), stats) =
        run_camera_input(&mut node, config, stop, |camera, frames, shared| {
            let session = make_session(&camera)?;
            let mut publisher = PosePublisher::new(config, shared, &mut writers);
            let (session, run, recording) = track(session, frames, &mut publisher, recording)?;
            Ok((session, run, camera, recording))
        })?;
    Ok(VoNodeRun {
        session,
        run,
        camera,
        stats,
        recording,
    })
}

/// The decoded frames the pipeline reads.
type Frames<'a> = Box<dyn Iterator<Item = Result<Observation, String>> + Send + 'a>;

/// Runs the visual pipeline on the queued pairs, decoding them on its read thread (and
/// encoding their images there for the recording).
fn track(
    mut session: VisualSlam,
    frames: &Receiver<Pair>,
    publisher: &mut PosePublisher,
    mut recording: Option<VisualRecording>,
) -> Result<(VisualSlam, VisualRun, Option<VisualRecording>), Ros2Error> {
    let (meta_tx, meta_rx) = unbounded();
    let source = frames.iter().enumerate().map(move |(index, pair)| {
        let _ = meta_tx.send((index, pair.stamp, pair.received));
        pair.frame()
    });
    let source: Frames = match &recording {
        Some(r) => Box::new(r.tap(source)),
        None => Box::new(source),
    };
    let mut recording_error = None;
    let run = visual::run(&mut session, source, RunOptions::default(), |u| {
        publisher.publish(u, &meta_rx);
        if let Some(Err(e)) = recording.as_mut().map(|r| r.push(u)) {
            recording_error.get_or_insert(e);
        }
    })?;
    if let Some(e) = recording_error {
        return Err(e.into());
    }
    Ok((session, run, recording))
}

/// Publishes each tracked frame's pose at its colour image's stamp.
struct PosePublisher<'a> {
    config: &'a VoNodeConfig,
    shared: &'a Shared,
    writers: &'a mut PoseWriters,
    /// `base_from_camera`, fixed at the first pose.
    mounting: Option<Pose3>,
}

impl<'a> PosePublisher<'a> {
    fn new(config: &'a VoNodeConfig, shared: &'a Shared, writers: &'a mut PoseWriters) -> Self {
        Self {
            config,
            shared,
            writers,
            mounting: None,
        }
    }

    fn publish(&mut self, u: &VisualUpdate, meta: &Receiver<(usize, Time, Instant)>) {
        // the pipeline answers frames in order; skipped (undecodable) ones have no answer
        let found = meta.try_iter().find(|(index, _, _)| *index == u.index);
        let (Some((_, stamp, received)), Some(world_from_camera)) = (found, u.tracked_pose())
        else {
            return;
        };
        let b = match self.mounting {
            Some(b) => b,
            None => {
                let (pose, source) = self.shared.base_from_camera(&self.config.base_frame);
                if let Ok(mut stats) = self.shared.stats.lock() {
                    let (t, q) = (pose.translation.vector, pose.rotation.quaternion());
                    stats.mounting = Some(([t.x, t.y, t.z], [q.i, q.j, q.k, q.w], source));
                }
                *self.mounting.insert(pose)
            }
        };
        let map_from_base = b * world_from_camera * b.inverse();
        let (map, base) = (&self.config.map_frame, &self.config.base_frame);
        let tf = (map.as_str(), base.as_str(), &map_from_base);
        self.writers.publish(tf, map, &map_from_base, stamp);
        if let Ok(mut stats) = self.shared.stats.lock() {
            stats.poses_published += 1;
            stats.latency.record_since(LATENCY_STAGE, received);
        }
    }
}

/// `body_from_optical` of REP 103: an optical frame (x right, y down, z forward) in its
/// body frame (x forward, y left, z up), no offset.
///
/// ```
/// use nalgebra::Point3;
/// let forward = slamkit_ros2::vo_node::optical_mounting() * Point3::new(0.0, 0.0, 1.0);
/// assert!((forward - Point3::new(1.0, 0.0, 0.0)).norm() < 1e-12);
/// ```
pub fn optical_mounting() -> Pose3 {
    let m = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
    Pose3::from_parts(nalgebra::Translation3::identity(), rotation)
}
