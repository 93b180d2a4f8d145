//! An RGB-D camera's recording in a bag (ROS 1 or ROS 2) as a source of
//! [`Observation::Rgbd`] frames, the ones a dataset folder gives ([`crate::Dataset`]), so a
//! visual session runs the same on both.
//!
//! Choices, and why:
//! * Colour and depth are both `sensor_msgs/Image` (or `sensor_msgs/CompressedImage`, JPEG or
//!   PNG, [`super::camera_image`]), so a topic is told by its first message's encoding: colour
//!   is `rgb8`, `bgr8` or `mono8` (a grey image taken as colour with equal channels), depth is
//!   `16UC1` (millimetres, as REP 118 and every depth driver store it) or `32FC1` (metres; NaN,
//!   infinite or non-positive is no depth). Each is chosen when there is one topic of its kind
//!   (`--rgb-topic`, `--depth-topic` otherwise).
//! * The camera is the first `sensor_msgs/CameraInfo` of its topic: the only one, else the one
//!   beside the colour topic (`/camera/rgb/camera_info` for `/camera/rgb/image_color`), else
//!   `--camera-info-topic`. Depth must be registered to colour (RealSense's
//!   `aligned_depth_to_color`, openni's `depth_registered`): one camera serves both.
//! * Colour and depth are paired by their `header.stamp`s with the TUM benchmark's rule
//!   ([`crate::tum_rgbd::associate`]: closest first, each image once, at most
//!   [`MAX_PAIR_GAP_S`]); a frame's time is its colour image's.
//! * [`BagRgbd::open`] reads the bag once for the topics, stamps and camera; the images are
//!   decoded in a second read, on a thread of its own, as the consumer takes frames
//!   ([`BagRgbd::observations`]), so memory does not grow with the bag. A frame whose image
//!   does not decode is an `Err` item, and the frames after it still come.

use super::camera_image::CameraImage;
use super::connection::Connection;
use super::messages::{is_type, CameraInfoMsg, CompressedImageMsg, ImageMsg, Pixels, RosMessage};
use super::scans::{choose_topic, topic_list};
use super::BagError;
use crate::dataset::checked_camera;
use crate::error::IoError;
use crate::image_io::depth_to_metres;
use slamkit_core::camera::PinholeCamera;
use slamkit_core::image::{Image, RgbImage};
use slamkit_core::observation::{self, Observation};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// Largest gap between the stamps of a colour image and its depth image \[s\] (TUM's
/// `associate.py`).
pub const MAX_PAIR_GAP_S: f64 = 0.02;

/// The topics to read; `None` chooses as the module documentation says.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RgbdTopics {
    /// Colour images (`sensor_msgs/Image`).
    pub rgb: Option<String>,
    /// Depth images registered to colour (`sensor_msgs/Image`).
    pub depth: Option<String>,
    /// The colour camera's calibration (`sensor_msgs/CameraInfo`).
    pub camera_info: Option<String>,
}

/// One frame of a bag: its time and which messages make it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BagRgbdFrame {
    /// Time of the colour image \[s\].
    pub timestamp: f64,
    /// The colour image's number among its topic's messages (storage order, from 0).
    pub rgb: usize,
    /// The depth image's number among its topic's messages.
    pub depth: usize,
}

/// An RGB-D recording in a bag, its frames paired (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct BagRgbd {
    /// The bag.
    pub path: PathBuf,
    /// The colour topic read.
    pub rgb_topic: String,
    /// The depth topic read.
    pub depth_topic: String,
    /// The calibration topic read.
    pub camera_info_topic: String,
    /// The camera of colour and depth.
    pub camera: PinholeCamera,
    /// Frames in colour time order.
    pub frames: Vec<BagRgbdFrame>,
    /// Colour images without a depth image within [`MAX_PAIR_GAP_S`], and depth images
    /// without a colour one.
    pub unpaired: (usize, usize),
}

/// What the first read keeps of a `sensor_msgs/Image` topic.
#[derive(Default)]
struct ImageTopic {
    encoding: Option<String>,
    size: Option<(u32, u32)>,
    /// Stamp and number of each message whose header decoded.
    stamps: Vec<(f64, usize)>,
    messages: usize,
}

/// Colour encodings read, and depth ones.
const COLOUR: &[&str] = &["rgb8", "bgr8", "mono8", "8UC1"];
const DEPTH: &[&str] = &["16UC1", "32FC1"];

impl BagRgbd {
    /// Reads the bag at `path` once: chooses the topics, reads the camera, pairs the frames.
    ///
    /// # Errors
    /// [`BagError`] for a bag that does not open or read, missing or ambiguous topics, a
    /// camera that is not valid, or no frame paired.
    pub fn open(path: &Path, topics: &RgbdTopics) -> Result<Self, BagError> {
        let mut bag = super::open(path)?;
        let bag = bag.as_mut();
        bag.find_connections()?;
        let file = bag.bag_name().to_string();
        let err = |message: String| BagError::Topics {
            file: file.clone(),
            message,
        };
        let asked = [
            (&topics.rgb, "--rgb-topic"),
            (&topics.depth, "--depth-topic"),
            (&topics.camera_info, "--camera-info-topic"),
        ];
        for (i, (topic, flag)) in asked.into_iter().enumerate() {
            if let Some(topic) = topic.as_deref() {
                if i < 2 {
                    // either kind of image message
                    choose_topic::<ImageMsg, _>(bag, Some(topic), flag).or_else(|e| {
                        choose_topic::<CompressedImageMsg, _>(bag, Some(topic), flag).or(Err(e))
                    })?;
                } else {
                    choose_topic::<CameraInfoMsg, _>(bag, Some(topic), flag)?;
                }
            }
        }
        let mut images: BTreeMap<String, ImageTopic> = BTreeMap::new();
        let mut infos: BTreeMap<String, Option<CameraInfoMsg>> = BTreeMap::new();
        bag.read_stored(&mut |conn, msg| {
            if CameraImage::is_image(conn) {
                let topic = images.entry(conn.topic.clone()).or_default();
                if let Ok(Some(m)) = CameraImage::decode_from(conn, msg.data) {
                    if topic.encoding.is_none() {
                        topic.encoding = m.encoding().ok();
                    }
                    if topic.size.is_none() {
                        topic.size = m.size().ok();
                    }
                    let t = m.header().stamp.as_secs_f64();
                    topic.stamps.push((t, topic.messages));
                }
                topic.messages += 1;
            } else if is_type::<CameraInfoMsg>(conn) {
                let first = infos.entry(conn.topic.clone()).or_default();
                if first.is_none() {
                    *first = CameraInfoMsg::decode_from(conn, msg.data).ok();
                }
            }
        })?;
        let rgb_topic = pick(
            &images,
            topics.rgb.as_deref(),
            COLOUR,
            "colour",
            "--rgb-topic",
        )
        .map_err(&err)?;
        let depth_topic = pick(
            &images,
            topics.depth.as_deref(),
            DEPTH,
            "depth",
            "--depth-topic",
        )
        .map_err(&err)?;
        let camera_info_topic = pick_info(&infos, topics.camera_info.as_deref(), &rgb_topic)
            .map_err(|m| err(format!("{m} (topics: {})", topic_list(bag))))?;
        let info = infos
            .get(&camera_info_topic)
            .and_then(Option::as_ref)
            .ok_or_else(|| err(format!("no readable CameraInfo on {camera_info_topic}")))?;
        let size = images.get(&rgb_topic).and_then(|t| t.size);
        let camera = camera_of(info, size).map_err(|e| err(format!("{camera_info_topic}: {e}")))?;
        let stamps = |topic: &str| {
            images
                .get(topic)
                .map(|t| t.stamps.as_slice())
                .unwrap_or_default()
        };
        let (rgb, depth) = (stamps(&rgb_topic), stamps(&depth_topic));
        let pairs = crate::tum_rgbd::associate(rgb, depth, MAX_PAIR_GAP_S);
        if pairs.is_empty() {
            return Err(err(format!(
                "no colour image of {rgb_topic} ({} readable) has a depth image of \
                 {depth_topic} ({} readable) within {MAX_PAIR_GAP_S} s",
                rgb.len(),
                depth.len()
            )));
        }
        let frames: Vec<BagRgbdFrame> = pairs
            .iter()
            .map(|(c, d)| BagRgbdFrame {
                timestamp: c.0,
                rgb: c.1,
                depth: d.1,
            })
            .collect();
        Ok(Self {
            path: path.to_path_buf(),
            unpaired: (rgb.len() - frames.len(), depth.len() - frames.len()),
            rgb_topic,
            depth_topic,
            camera_info_topic,
            camera,
            frames,
        })
    }

    /// One line on what was read: the topics, the frames paired, the images left unpaired.
    pub fn describe(&self) -> String {
        format!(
            "colour {}, depth {}, camera {} (fx {:.1}, {}×{}); {} frames, {} colour and {} \
             depth images unpaired",
            self.rgb_topic,
            self.depth_topic,
            self.camera_info_topic,
            self.camera.intrinsics.fx,
            self.camera.intrinsics.width,
            self.camera.intrinsics.height,
            self.frames.len(),
            self.unpaired.0,
            self.unpaired.1
        )
    }

    /// The frames in order, each decoded as the iterator reaches it (by a thread reading the
    /// bag a second time, a few frames ahead). A frame whose image does not decode, or a bag
    /// that stops reading, is an `Err` item naming the bag and the frame.
    pub fn observations(&self) -> impl Iterator<Item = Result<Observation, IoError>> + Send {
        let (tx, rx) = std::sync::mpsc::sync_channel(2);
        let this = self.clone();
        std::thread::spawn(move || this.stream(&tx));
        rx.into_iter()
    }

    /// The second read: decodes the frames' images and sends the frames in order.
    fn stream(&self, tx: &std::sync::mpsc::SyncSender<Result<Observation, IoError>>) {
        let wanted = |pick: fn(&BagRgbdFrame) -> usize| -> HashMap<usize, usize> {
            self.frames
                .iter()
                .enumerate()
                .map(|(i, f)| (pick(f), i))
                .collect()
        };
        let (want_rgb, want_depth) = (wanted(|f| f.rgb), wanted(|f| f.depth));
        let mut pending: BTreeMap<usize, Halves> = BTreeMap::new();
        let (mut seen_rgb, mut seen_depth, mut next, mut open) = (0, 0, 0, true);
        let read = super::open(&self.path).and_then(|mut bag| {
            bag.find_connections()?;
            bag.read_stored(&mut |conn: &Connection, msg| {
                // Counted as the first read counted them: images of the topic.
                let (seen, want, colour) = if !CameraImage::is_image(conn) {
                    return;
                } else if conn.topic == self.rgb_topic {
                    (&mut seen_rgb, &want_rgb, true)
                } else if conn.topic == self.depth_topic {
                    (&mut seen_depth, &want_depth, false)
                } else {
                    return;
                };
                let number = *seen;
                *seen += 1;
                let Some(&frame) = want.get(&number).filter(|_| open) else {
                    return;
                };
                let image = CameraImage::decode_from(conn, msg.data)
                    .and_then(|m| m.ok_or_else(|| "not an image".to_string()));
                let halves = pending.entry(frame).or_default();
                if colour {
                    halves.0 = Some(image.and_then(|m| m.colour()));
                } else {
                    halves.1 = Some(image.and_then(|m| m.depth()));
                }
                while let Some((Some(_), Some(_))) = pending.get(&next) {
                    let Some((Some(c), Some(d))) = pending.remove(&next) else {
                        break;
                    };
                    open &= tx.send(self.frame(next, c, d)).is_ok();
                    next += 1;
                }
            })
        });
        let why = match read {
            Ok(_) => "its images were not found on the second read".to_string(),
            Err(e) => e.to_string(),
        };
        for index in next..self.frames.len() {
            if !open || tx.send(Err(self.frame_error(index, &why))).is_err() {
                return;
            }
        }
    }

    /// Frame `index` from its decoded halves.
    fn frame(
        &self,
        index: usize,
        color: Result<RgbImage, String>,
        depth_m: Result<Image<f32>, String>,
    ) -> Result<Observation, IoError> {
        let timestamp = self.frames.get(index).map_or(f64::NAN, |f| f.timestamp);
        color
            .and_then(|c| depth_m.and_then(|d| rgbd_frame(timestamp, c, d)))
            .map_err(|why| self.frame_error(index, &why))
    }

    fn frame_error(&self, index: usize, why: &str) -> IoError {
        let t = self.frames.get(index).map_or(f64::NAN, |f| f.timestamp);
        let file = self.path.display();
        IoError::invalid(format!("{file}: frame {index} ({t:.6} s)"), why)
    }
}

/// The decoded colour and depth images of a frame, as they come.
type Halves = (
    Option<Result<RgbImage, String>>,
    Option<Result<Image<f32>, String>>,
);

/// The image topic of a kind: the one asked for (its encoding checked), else the only one
/// whose first message has an encoding of `kind`.
fn pick(
    images: &BTreeMap<String, ImageTopic>,
    asked: Option<&str>,
    encodings: &[&str],
    kind: &str,
    flag: &str,
) -> Result<String, String> {
    let of_kind = |t: &ImageTopic| {
        t.encoding
            .as_deref()
            .is_some_and(|e| encodings.contains(&e))
    };
    if let Some(topic) = asked {
        let found = images.get(topic);
        return match found.map(|t| (of_kind(t), t.encoding.as_deref())) {
            Some((true, _)) => Ok(topic.to_string()),
            Some((false, Some(e))) => Err(format!(
                "{topic} holds {e} images, not {kind} ({})",
                encodings.join(", ")
            )),
            _ => Err(format!("{topic} holds no readable image")),
        };
    }
    let found: Vec<&String> = images
        .iter()
        .filter(|(_, t)| of_kind(t))
        .map(|(n, _)| n)
        .collect();
    match found.as_slice() {
        [one] => Ok((*one).clone()),
        [] => Err(format!(
            "no {kind} image topic (sensor_msgs/Image in {}; image topics: {})",
            encodings.join(", "),
            describe(images)
        )),
        many => Err(format!(
            "several {kind} image topics ({}): choose one with {flag}",
            many.iter()
                .map(|s| s.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

fn describe(images: &BTreeMap<String, ImageTopic>) -> String {
    if images.is_empty() {
        return "none".into();
    }
    let each = images
        .iter()
        .map(|(name, t)| format!("{name} [{}]", t.encoding.as_deref().unwrap_or("unreadable")));
    each.collect::<Vec<_>>().join(", ")
}

/// The calibration topic: the one asked for, the only one, or the only one in the colour
/// topic's namespace.
fn pick_info(
    infos: &BTreeMap<String, Option<CameraInfoMsg>>,
    asked: Option<&str>,
    rgb_topic: &str,
) -> Result<String, String> {
    if let Some(topic) = asked {
        return Ok(topic.to_string());
    }
    let namespace = |t: &str| t.rsplit_once('/').map(|(ns, _)| ns.to_string());
    let beside: Vec<&String> = infos
        .keys()
        .filter(|t| namespace(t) == namespace(rgb_topic))
        .collect();
    match (infos.len(), beside.as_slice()) {
        (1, _) => Ok(infos.keys().next().cloned().unwrap_or_default()),
        (0, _) => Err(format!(
            "no {} topic: the camera's calibration is needed",
            CameraInfoMsg::TYPE
        )),
        (_, [one]) => Ok((*one).clone()),
        _ => Err(format!(
            "several {} topics, none alone beside {rgb_topic}: choose one with \
             --camera-info-topic",
            CameraInfoMsg::TYPE
        )),
    }
}

/// An RGB-D frame of a colour image and the depth image registered to it.
///
/// # Errors
/// Images of different sizes (depth not registered to colour).
pub fn rgbd_frame(
    timestamp: f64,
    color: RgbImage,
    depth_m: Image<f32>,
) -> Result<Observation, String> {
    if (color.width(), color.height()) != (depth_m.width(), depth_m.height()) {
        return Err(format!(
            "colour is {}×{}, depth {}×{}: depth must be registered to colour",
            color.width(),
            color.height(),
            depth_m.width(),
            depth_m.height()
        ));
    }
    Ok(Observation::Rgbd(observation::RgbdFrame {
        timestamp,
        color,
        depth_m,
    }))
}

/// The camera of a `CameraInfo`: `K`'s fx, fy, cx, cy, the image size (the colour images'
/// when the message leaves it 0), and `plumb_bob` / `rational_polynomial` distortion's k1, k2,
/// p1, p2, k3.
///
/// # Errors
/// A calibration for another image size, a distortion model that is not read, or
/// intrinsics that do not make a camera.
pub fn camera_of(
    info: &CameraInfoMsg,
    image_size: Option<(u32, u32)>,
) -> Result<PinholeCamera, String> {
    let k = [info.k[0], info.k[4], info.k[2], info.k[5]];
    let size = match (info.width, info.height, image_size) {
        (0, 0, Some(size)) => size,
        (w, h, Some((iw, ih))) if (w, h) != (iw, ih) => {
            return Err(format!(
                "calibrated for {w}×{h} images, the images are {iw}×{ih}"
            ));
        }
        (w, h, _) => (w, h),
    };
    let model = info.distortion_model.as_str();
    let read = matches!(model, "plumb_bob" | "rational_polynomial" | "");
    if !read && info.d.iter().any(|&d| d != 0.0) {
        return Err(format!(
            "distortion model {model:?} is not read: record rectified images"
        ));
    }
    let mut distortion = [0.0; 5];
    if read {
        for (slot, d) in distortion.iter_mut().zip(&info.d) {
            *slot = *d;
        }
    }
    checked_camera(
        "the camera",
        k,
        (size.0 as usize, size.1 as usize),
        distortion,
    )
    .map_err(|e| e.to_string())
}

/// A colour image message as RGB (`mono8` with three equal channels).
///
/// # Errors
/// Another encoding, or pixels that do not fit the size.
pub fn colour_image(msg: &ImageMsg) -> Result<RgbImage, String> {
    let (w, h) = (msg.width as usize, msg.height as usize);
    let pixels = match msg.pixels()? {
        Pixels::Rgb8(p) => p,
        Pixels::Mono8(p) => p.into_iter().map(|g| [g, g, g]).collect(),
        _ => return Err(format!("{} is not a colour encoding", msg.encoding)),
    };
    Image::from_vec(w, h, pixels).ok_or_else(|| "image size does not match its pixels".into())
}

/// A depth image message in metres, 0.0 where there is no depth.
///
/// # Errors
/// Another encoding, or pixels that do not fit the size.
pub fn depth_image(msg: &ImageMsg) -> Result<Image<f32>, String> {
    let (w, h) = (msg.width as usize, msg.height as usize);
    let size_error = || "image size does not match its pixels".to_string();
    match msg.pixels()? {
        Pixels::Depth16(mm) => {
            let raw = Image::from_vec(w, h, mm).ok_or_else(size_error)?;
            Ok(depth_to_metres(&raw, 1000.0, &[]))
        }
        Pixels::Depth32F(m) => {
            let m = m
                .into_iter()
                .map(|d| if d.is_finite() && d > 0.0 { d } else { 0.0 });
            Image::from_vec(w, h, m.collect()).ok_or_else(size_error)
        }
        _ => Err(format!("{} is not a depth encoding", msg.encoding)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bag::messages::Header;
    use crate::bag::record::RosTime;

    fn image(encoding: &str, width: u32, data: Vec<u8>) -> ImageMsg {
        let header = Header {
            seq: None,
            stamp: RosTime { sec: 1, nsec: 0 },
            frame_id: "cam".into(),
        };
        let bytes_per_pixel = data.len() as u32 / width;
        ImageMsg {
            header,
            height: 1,
            width,
            encoding: encoding.into(),
            is_bigendian: 0,
            step: bytes_per_pixel * width,
            data,
        }
    }

    #[test]
    fn images_convert_to_colour_and_metres() {
        let bgr = colour_image(&image("bgr8", 1, vec![3, 2, 1])).unwrap();
        assert_eq!(bgr.get(0, 0), Some(&[1, 2, 3]));
        let mono = colour_image(&image("mono8", 2, vec![7, 9])).unwrap();
        assert_eq!(mono.get(1, 0), Some(&[9, 9, 9]));
        let mm = image(
            "16UC1",
            2,
            [1500u16, 0].iter().flat_map(|v| v.to_le_bytes()).collect(),
        );
        let d = depth_image(&mm).unwrap();
        assert_eq!((d.get(0, 0), d.get(1, 0)), (Some(&1.5), Some(&0.0)));
        let m: Vec<u8> = [2.25f32, f32::NAN, -1.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let d = depth_image(&image("32FC1", 3, m)).unwrap();
        assert_eq!(
            [d.get(0, 0), d.get(1, 0), d.get(2, 0)],
            [Some(&2.25), Some(&0.0), Some(&0.0)]
        );
        assert!(colour_image(&mm).unwrap_err().contains("not a colour"));
        assert!(depth_image(&image("rgb8", 1, vec![1, 2, 3])).is_err());
    }

    fn topics(encodings: &[(&str, &str)]) -> BTreeMap<String, ImageTopic> {
        let each = encodings.iter().map(|(name, e)| {
            let t = ImageTopic {
                encoding: Some(e.to_string()),
                ..ImageTopic::default()
            };
            (name.to_string(), t)
        });
        each.collect()
    }

    #[test]
    fn image_topics_are_told_by_encoding() {
        let two = topics(&[("/rgb", "bgr8"), ("/depth", "16UC1")]);
        assert_eq!(
            pick(&two, None, COLOUR, "colour", "--rgb-topic").unwrap(),
            "/rgb"
        );
        assert_eq!(
            pick(&two, None, DEPTH, "depth", "--depth-topic").unwrap(),
            "/depth"
        );
        let e = pick(&two, Some("/depth"), COLOUR, "colour", "--rgb-topic").unwrap_err();
        assert!(e.contains("/depth holds 16UC1 images, not colour"), "{e}");
        let three = topics(&[("/a", "rgb8"), ("/b", "mono8"), ("/d", "32FC1")]);
        let e = pick(&three, None, COLOUR, "colour", "--rgb-topic").unwrap_err();
        assert!(e.contains("several colour image topics (/a, /b): choose one with --rgb-topic"));
        let e = pick(&topics(&[]), None, DEPTH, "depth", "--depth-topic").unwrap_err();
        assert!(e.contains("no depth image topic"), "{e}");
    }

    fn info(width: u32, model: &str, d: Vec<f64>) -> CameraInfoMsg {
        CameraInfoMsg {
            header: image("mono8", 1, vec![0]).header,
            height: 480,
            width,
            distortion_model: model.into(),
            d,
            k: [585.0, 0.0, 320.0, 0.0, 586.0, 240.0, 0.0, 0.0, 1.0],
            r: [0.0; 9],
            p: [0.0; 12],
            binning_x: 0,
            binning_y: 0,
            roi: [0; 4],
            roi_do_rectify: false,
        }
    }

    #[test]
    fn the_camera_comes_from_camera_info_beside_the_colour_topic() {
        let infos: BTreeMap<String, Option<CameraInfoMsg>> = [
            ("/cam/depth/camera_info".to_string(), None),
            ("/cam/rgb/camera_info".to_string(), None),
        ]
        .into_iter()
        .collect();
        let chosen = pick_info(&infos, None, "/cam/rgb/image_color").unwrap();
        assert_eq!(chosen, "/cam/rgb/camera_info");
        assert!(pick_info(&infos, None, "/other/image").is_err());
        let cam = camera_of(
            &info(640, "plumb_bob", vec![0.1, 0.0, 0.0, 0.0, 0.0]),
            Some((640, 480)),
        )
        .unwrap();
        assert_eq!(
            (cam.intrinsics.fx, cam.intrinsics.fy, cam.intrinsics.cy),
            (585.0, 586.0, 240.0)
        );
        assert_eq!((cam.intrinsics.width, cam.intrinsics.height), (640, 480));
        let e = camera_of(&info(320, "plumb_bob", vec![]), Some((640, 480))).unwrap_err();
        assert!(
            e.contains("calibrated for 320×480 images, the images are 640×480"),
            "{e}"
        );
        let e = camera_of(&info(640, "equidistant", vec![0.1]), None).unwrap_err();
        assert!(e.contains("\"equidistant\" is not read"), "{e}");
    }
}
