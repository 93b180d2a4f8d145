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
//! Threads: one takes samples off the DDS readers, one pairs colour with depth
//! ([`crate::rgbd_pairing`]) and queues the pairs (at most `frame_queue`: a camera driver's
//! buffer ring; a pair arriving at a full queue is dropped and counted, so the node keeps up
//! with the camera), and the caller's runs the visual pipeline (its own decoding, preparation
//! and mapping threads) and publishes. The session is made once the first `CameraInfo` came.

use crate::dds::{
    drain, latched_qos, sensor_qos, subscribe, Discovery, PoseTopics, PoseWriters, Refusals,
};
use crate::msgs::{self, Time};
use crate::rgbd_pairing::RgbdPairing;
use crate::Ros2Error;
use crossbeam_channel::{bounded, unbounded, Receiver, RecvTimeoutError, Sender, TrySendError};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::qos::History;
use ros2_client::Subscription;
use slamkit_core::camera::PinholeCamera;
use slamkit_core::{Pose3, StageTimings};
use slamkit_io::bag::camera_image::CameraImage;
use slamkit_io::bag::rgbd::{camera_of, rgbd_frame};
use slamkit_io::bag::scans::{add_static_transforms, lookup, StaticTree};
use slamkit_slam::visual::{self, RunOptions, VisualRun, VisualUpdate};
use slamkit_slam::{SlamError, VisualSlam};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

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
}

/// A sample taken off a reader.
enum Incoming {
    Colour(Instant, Result<CameraImage, String>),
    Depth(Result<CameraImage, String>),
    Info(Box<msgs::CameraInfo>),
    TfStatic(msgs::TfMessage),
    ReadError(String),
}

/// A colour image paired with its depth image, not yet decoded.
struct Pair {
    colour: CameraImage,
    depth: CameraImage,
    stamp: Time,
    received: Instant,
}

/// The node's DDS readers.
struct Readers {
    colour: ImageReader,
    depth: ImageReader,
    info: Subscription<msgs::CameraInfo>,
    tf_static: Subscription<msgs::TfMessage>,
}

/// A reader of raw or compressed images (`image_transport`'s `.../compressed` and
/// `.../compressedDepth` topics carry `sensor_msgs/CompressedImage`).
enum ImageReader {
    Raw(Subscription<msgs::Image>),
    Compressed(Subscription<msgs::CompressedImage>),
}

impl ImageReader {
    fn open(node: &mut ros2_client::Node, topic: &str) -> Result<Self, Ros2Error> {
        let qos = sensor_qos();
        Ok(if is_compressed(topic) {
            let ty = ("sensor_msgs", "CompressedImage");
            Self::Compressed(subscribe(node, topic, ty, &qos)?)
        } else {
            Self::Raw(subscribe(node, topic, ("sensor_msgs", "Image"), &qos)?)
        })
    }

    fn register(
        &mut self,
        registry: &ros2_client::dds::rustdds::mio1::Registry,
        token: Token,
    ) -> Result<(), Ros2Error> {
        let registered = match self {
            Self::Raw(r) => registry.register(r, token, Interest::READABLE),
            Self::Compressed(r) => registry.register(r, token, Interest::READABLE),
        };
        registered.map_err(crate::dds::dds("poll"))
    }

    /// Takes every waiting image into `tx`, each wrapped by `wrap`; false once `tx` is closed.
    fn drain(
        &self,
        tx: &Sender<Incoming>,
        wrap: impl Fn(Result<CameraImage, String>) -> Incoming,
    ) -> bool {
        match self {
            Self::Raw(r) => drain(
                r,
                tx,
                |m: msgs::Image, _| wrap(m.into_bag().map(CameraImage::Raw)),
                Incoming::ReadError,
            ),
            Self::Compressed(r) => drain(
                r,
                tx,
                |m: msgs::CompressedImage, _| wrap(m.into_bag().map(CameraImage::Compressed)),
                Incoming::ReadError,
            ),
        }
    }
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

/// What the pairing thread shares with the publishing one.
#[derive(Default)]
struct Shared {
    statics: Mutex<StaticTree>,
    optical_frame: Mutex<Option<String>>,
    stats: Mutex<VoNodeStats>,
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
    let n = &mut node;
    let sensor = sensor_qos();
    let readers = Readers {
        colour: ImageReader::open(n, &config.rgb_topic)?,
        depth: ImageReader::open(n, &config.depth_topic)?,
        info: subscribe(
            n,
            &config.camera_info_topic,
            ("sensor_msgs", "CameraInfo"),
            &sensor,
        )?,
        tf_static: subscribe(
            n,
            &config.tf_static_topic,
            ("tf2_msgs", "TFMessage"),
            &latched_qos().history(History::KeepLast { depth: 100 }),
        )?,
    };
    let topics = PoseTopics {
        tf: &config.tf_topic,
        pose: &config.pose_topic,
        path: Some(&config.path_topic),
    };
    let mut writers = PoseWriters::open(n, &topics)?;
    let (in_tx, in_rx) = unbounded();
    let (camera_tx, camera_rx) = bounded(1);
    let (frame_tx, frame_rx) = bounded(config.frame_queue.max(1));
    let shared = Shared::default();
    let readers_done = AtomicBool::new(false);
    let (shared_ref, done) = (&shared, &readers_done);
    let result = std::thread::scope(|scope| {
        let reader = scope.spawn(move || read_loop(readers, &in_tx, done));
        let pairer = scope.spawn(move || {
            pair_loop(config, &in_rx, (camera_tx, frame_tx), shared_ref, stop);
            done.store(true, Ordering::Relaxed);
        });
        let result = camera_rx
            .recv()
            .map_err(|_| {
                let topic = &config.camera_info_topic;
                Ros2Error::Config(format!(
                    "stopped before a usable CameraInfo came on {topic}"
                ))
            })
            .and_then(|camera| {
                let session = make_session(&camera)?;
                let mut publisher = PosePublisher::new(config, shared_ref, &mut writers);
                track(session, &frame_rx, &mut publisher)
                    .map(|(session, run)| (session, run, camera))
            });
        // the pipeline ended (the input did, or it failed): let the other threads end
        done.store(true, Ordering::Relaxed);
        drop(frame_rx);
        let _ = pairer.join();
        let read_result = reader
            .join()
            .unwrap_or_else(|_| Err(Ros2Error::Dds("the reader thread panicked".into())));
        let (session, run, camera) = result?;
        read_result?;
        Ok::<_, Ros2Error>((session, run, camera))
    });
    let (session, run, camera) = result?;
    let stats = shared.stats.into_inner().unwrap_or_default();
    Ok(VoNodeRun {
        session,
        run,
        camera,
        stats,
    })
}

/// Runs the visual pipeline on the queued pairs, decoding them on its read thread.
fn track(
    mut session: VisualSlam,
    frames: &Receiver<Pair>,
    publisher: &mut PosePublisher,
) -> Result<(VisualSlam, VisualRun), Ros2Error> {
    let (meta_tx, meta_rx) = unbounded();
    let source = frames.iter().enumerate().map(move |(index, pair)| {
        let _ = meta_tx.send((index, pair.stamp, pair.received));
        let timestamp = pair.stamp.as_secs_f64();
        let (colour, depth) = (pair.colour.colour(), pair.depth.depth());
        colour
            .and_then(|c| depth.and_then(|d| rgbd_frame(timestamp, c, d)))
            .map_err(|why| format!("{timestamp:.6} s: {why}"))
    });
    let run = visual::run(&mut session, source, RunOptions::default(), |u| {
        publisher.publish(u, &meta_rx);
    })?;
    Ok((session, run))
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
                let (pose, source) = self.base_from_camera();
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

    /// `base_from_camera` and where it came from (see the module documentation).
    fn base_from_camera(&self) -> (Pose3, String) {
        let base = self.config.base_frame.as_str();
        let optical = self
            .shared
            .optical_frame
            .lock()
            .ok()
            .and_then(|f| f.clone())
            .unwrap_or_default();
        let from_tf = self
            .shared
            .statics
            .lock()
            .ok()
            .and_then(|s| lookup(&s, base, &optical));
        match from_tf {
            Some(pose) => (pose, format!("/tf_static: {base} -> {optical}")),
            None if optical == base => (Pose3::identity(), "images in the base frame".into()),
            None => (optical_mounting(), "REP 103 optical frame".into()),
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

/// The reader thread: waits on the readers, forwards each sample, ends when `done` is set.
fn read_loop(
    mut readers: Readers,
    tx: &Sender<Incoming>,
    done: &AtomicBool,
) -> Result<(), Ros2Error> {
    let mut poll = Poll::new().map_err(crate::dds::dds("poll"))?;
    let registry = poll.registry();
    let poll_error = crate::dds::dds("poll");
    readers.colour.register(registry, Token(0))?;
    readers.depth.register(registry, Token(1))?;
    registry
        .register(&mut readers.info, Token(2), Interest::READABLE)
        .map_err(&poll_error)?;
    registry
        .register(&mut readers.tf_static, Token(3), Interest::READABLE)
        .map_err(&poll_error)?;
    let mut events = Events::with_capacity(16);
    while !done.load(Ordering::Relaxed) {
        poll.poll(&mut events, Some(Duration::from_millis(50)))
            .map_err(&poll_error)?;
        // Edge-triggered: every reader is drained whatever woke the poll.
        let error = Incoming::ReadError;
        let info = |m, _: &_| Incoming::Info(Box::new(m));
        let tf = |m, _: &_| Incoming::TfStatic(m);
        let colour = |m| Incoming::Colour(Instant::now(), m);
        let open = drain(&readers.info, tx, info, error)
            && drain(&readers.tf_static, tx, tf, error)
            && readers.depth.drain(tx, Incoming::Depth)
            && readers.colour.drain(tx, colour);
        if !open {
            break;
        }
    }
    Ok(())
}

/// The pairing thread: converts and pairs the images, sends the camera once and the pairs;
/// ends at `stop`, at the idle timeout, or when the pipeline is gone.
fn pair_loop(
    config: &VoNodeConfig,
    incoming: &Receiver<Incoming>,
    (camera_tx, frame_tx): (Sender<PinholeCamera>, Sender<Pair>),
    shared: &Shared,
    stop: &AtomicBool,
) {
    let mut pairing = RgbdPairing::<(CameraImage, Time, Instant), CameraImage>::new();
    let mut camera: Option<msgs::CameraInfo> = None;
    let mut colour_size = None;
    let mut sent_camera = false;
    let mut last_message: Option<Instant> = None;
    let idle = config.idle_exit_s.map(Duration::from_secs_f64);
    let stats = |f: &mut dyn FnMut(&mut VoNodeStats)| {
        if let Ok(mut s) = shared.stats.lock() {
            f(&mut s);
        }
    };
    let mut open = true;
    while open && !stop.load(Ordering::Relaxed) {
        let msg = match incoming.recv_timeout(Duration::from_millis(20)) {
            Ok(msg) => msg,
            Err(RecvTimeoutError::Timeout) => {
                let idle_for = last_message.map(|t| t.elapsed());
                if idle
                    .zip(idle_for)
                    .is_some_and(|(limit, idle)| idle >= limit)
                {
                    break;
                }
                continue;
            }
            Err(RecvTimeoutError::Disconnected) => break,
        };
        let mut pairs = Vec::new();
        match msg {
            Incoming::Colour(received, m) => {
                last_message = Some(Instant::now());
                stats(&mut |s| s.colour_received += 1);
                match m {
                    Ok(m) => {
                        if colour_size.is_none() {
                            colour_size = m.size().ok();
                        }
                        let header = m.header();
                        if let Ok(mut f) = shared.optical_frame.lock() {
                            f.get_or_insert_with(|| header.frame_id.clone());
                        }
                        let t = header.stamp.as_secs_f64();
                        let stamp = Time {
                            sec: header.stamp.sec as i32,
                            nanosec: header.stamp.nsec,
                        };
                        pairs = pairing.add_colour(t, (m, stamp, received));
                    }
                    Err(why) => stats(&mut |s| s.undecodable.add(format!("colour: {why}"))),
                }
            }
            Incoming::Depth(m) => {
                last_message = Some(Instant::now());
                stats(&mut |s| s.depth_received += 1);
                match m {
                    Ok(m) => pairs = pairing.add_depth(m.header().stamp.as_secs_f64(), m),
                    Err(why) => stats(&mut |s| s.undecodable.add(format!("depth: {why}"))),
                }
            }
            Incoming::Info(m) => {
                stats(&mut |s| s.camera_info_received += 1);
                camera.get_or_insert(*m);
            }
            Incoming::TfStatic(m) => {
                stats(&mut |s| s.tf_static_received += 1);
                let added = m.to_bag().and_then(|m| {
                    let mut statics = shared.statics.lock().map_err(|e| e.to_string())?;
                    add_static_transforms(&mut statics, m)
                });
                if let Err(why) = added {
                    stats(&mut |s| s.undecodable.add(format!("tf_static: {why}")));
                }
            }
            Incoming::ReadError(why) => {
                stats(&mut |s| s.undecodable.add(format!("DDS read: {why}")));
            }
        }
        if !sent_camera {
            if let (Some(info), Some(size)) = (&camera, colour_size) {
                match info.to_bag().and_then(|i| camera_of(&i, Some(size))) {
                    Ok(cam) => {
                        sent_camera = true;
                        open = camera_tx.send(cam).is_ok();
                    }
                    Err(why) => {
                        let topic = &config.camera_info_topic;
                        stats(&mut |s| s.undecodable.add(format!("{topic}: {why}")));
                        camera = None;
                    }
                }
            }
        }
        open &= queue(pairs, &frame_tx, &stats);
        let unpaired = pairing.unpaired();
        stats(&mut |s| s.unpaired = unpaired);
    }
    let rest = pairing.finish();
    if sent_camera {
        queue(rest, &frame_tx, &stats);
    }
    let unpaired = pairing.unpaired();
    stats(&mut |s| s.unpaired = unpaired);
}

/// Queues pairs for the session, dropping what does not fit; false once the session is gone.
fn queue(
    pairs: Vec<((CameraImage, Time, Instant), CameraImage)>,
    tx: &Sender<Pair>,
    stats: &impl Fn(&mut dyn FnMut(&mut VoNodeStats)),
) -> bool {
    for ((colour, stamp, received), depth) in pairs {
        let pair = Pair {
            colour,
            depth,
            stamp,
            received,
        };
        match tx.try_send(pair) {
            Ok(()) => stats(&mut |s| s.frames_queued += 1),
            Err(TrySendError::Full(_)) => stats(&mut |s| s.frames_dropped += 1),
            Err(TrySendError::Disconnected(_)) => return false,
        }
    }
    true
}
