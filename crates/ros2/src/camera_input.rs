//! The input side of a camera node, whatever it does with the frames (`slamkit ros2 vo`,
//! `slamkit ros2 nav`): colour and depth `sensor_msgs/Image`s (or `sensor_msgs/CompressedImage`
//! on `image_transport`'s `.../compressed` and `.../compressedDepth` topics), the colour
//! camera's `sensor_msgs/CameraInfo` (sensor-data QoS) and `/tf_static` for the camera's
//! mounting.
//!
//! Threads: one takes samples off the DDS readers, one pairs colour with depth
//! ([`crate::rgbd_pairing`]) and queues the pairs (at most `frame_queue`: a camera driver's
//! buffer ring; a pair arriving at a full queue is dropped and counted, so the node keeps up
//! with the camera), and the caller's ([`run_camera_input`]) consumes them once the first
//! usable `CameraInfo` came.

use crate::dds::{drain, latched_qos, sensor_qos, subscribe};
use crate::msgs::{self, Time};
use crate::rgbd_pairing::RgbdPairing;
use crate::vo_node::{is_compressed, optical_mounting, VoNodeConfig, VoNodeStats};
use crate::Ros2Error;
use crossbeam_channel::{bounded, unbounded, Receiver, RecvTimeoutError, Sender, TrySendError};
use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::qos::History;
use ros2_client::{Node, Subscription};
use slamkit_core::camera::PinholeCamera;
use slamkit_core::observation::Observation;
use slamkit_core::Pose3;
use slamkit_io::bag::camera_image::CameraImage;
use slamkit_io::bag::rgbd::{camera_of, rgbd_frame};
use slamkit_io::bag::scans::{add_static_transforms, lookup, StaticTree};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// A sample taken off a reader.
pub(crate) enum Incoming {
    Colour(Instant, Result<CameraImage, String>),
    Depth(Result<CameraImage, String>),
    Info(Box<msgs::CameraInfo>),
    TfStatic(msgs::TfMessage),
    ReadError(String),
}

/// A colour image paired with its depth image, not yet decoded.
pub(crate) struct Pair {
    colour: CameraImage,
    depth: CameraImage,
    /// The colour image's stamp.
    pub(crate) stamp: Time,
    /// When the colour image was taken off its reader.
    pub(crate) received: Instant,
}

/// The node's DDS readers.
struct Readers {
    colour: ImageReader,
    depth: ImageReader,
    info: Subscription<msgs::CameraInfo>,
    tf_static: Subscription<msgs::TfMessage>,
}

impl Readers {
    /// The readers of `config`'s topics: images and calibration with the sensor-data QoS,
    /// `/tf_static` transient local.
    fn open(n: &mut Node, config: &VoNodeConfig) -> Result<Self, Ros2Error> {
        let sensor = sensor_qos();
        Ok(Self {
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
        })
    }
}

/// A reader of raw or compressed images (`image_transport`'s `.../compressed` and
/// `.../compressedDepth` topics carry `sensor_msgs/CompressedImage`).
enum ImageReader {
    Raw(Subscription<msgs::Image>),
    Compressed(Subscription<msgs::CompressedImage>),
}

impl ImageReader {
    fn open(node: &mut Node, topic: &str) -> Result<Self, Ros2Error> {
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

/// What the pairing thread shares with the consuming one.
#[derive(Default)]
pub(crate) struct Shared {
    statics: Mutex<StaticTree>,
    optical_frame: Mutex<Option<String>>,
    /// The node's counters.
    pub(crate) stats: Mutex<VoNodeStats>,
}

impl Shared {
    /// Updates the counters (a poisoned lock leaves them as they are).
    pub(crate) fn count(&self, f: impl FnOnce(&mut VoNodeStats)) {
        if let Ok(mut stats) = self.stats.lock() {
            f(&mut stats);
        }
    }

    /// `base_from_camera` and where it came from: `/tf_static` from `base_frame` to the
    /// images' optical frame, else the identity when the images are stamped in the base frame
    /// itself, else the REP 103 rotation of an optical frame.
    pub(crate) fn base_from_camera(&self, base: &str) -> (Pose3, String) {
        let optical = self
            .optical_frame
            .lock()
            .ok()
            .and_then(|f| f.clone())
            .unwrap_or_default();
        let from_tf = self
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

impl Pair {
    /// The decoded RGB-D frame, stamped with the colour image's time.
    ///
    /// # Errors
    /// An image that does not decode, or depth not registered to colour.
    pub(crate) fn frame(&self) -> Result<Observation, String> {
        let timestamp = self.stamp.as_secs_f64();
        let (colour, depth) = (self.colour.colour(), self.depth.depth());
        colour
            .and_then(|c| depth.and_then(|d| rgbd_frame(timestamp, c, d)))
            .map_err(|why| format!("{timestamp:.6} s: {why}"))
    }
}

/// Opens the camera's readers on `node` and runs the input threads until `stop` (or the
/// idle timeout); once a usable `CameraInfo` came, `consume` runs on this thread with the
/// camera and the queued pairs, and its result is returned with the counters.
///
/// # Errors
/// A reader could not be made or failed, no `CameraInfo` came before the input stopped, or
/// `consume` failed.
pub(crate) fn run_camera_input<R>(
    node: &mut Node,
    config: &VoNodeConfig,
    stop: &AtomicBool,
    consume: impl FnOnce(PinholeCamera, &Receiver<Pair>, &Shared) -> Result<R, Ros2Error>,
) -> Result<(R, VoNodeStats), Ros2Error> {
    let readers = Readers::open(node, config)?;
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
            .and_then(|camera| consume(camera, &frame_rx, shared_ref));
        // the consumer ended (the input did, or it failed): let the other threads end
        done.store(true, Ordering::Relaxed);
        drop(frame_rx);
        let _ = pairer.join();
        let read_result = reader
            .join()
            .unwrap_or_else(|_| Err(Ros2Error::Dds("the reader thread panicked".into())));
        let consumed = result?;
        read_result?;
        Ok::<_, Ros2Error>(consumed)
    });
    let consumed = result?;
    Ok((consumed, shared.stats.into_inner().unwrap_or_default()))
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
