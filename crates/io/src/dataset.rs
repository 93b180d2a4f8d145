//! What every camera dataset reader returns, and [`Dataset`] to open any of them by format
//! name (`slamkit vo --format tum|kitti|7scenes|redwood|euroc`).
//!
//! A reader lists the frames (timestamps and file paths) up front and checks the metadata;
//! images are decoded only when a frame is loaded, so a sequence of thousands of frames opens
//! in milliseconds and a corrupt image costs that frame only (the caller skips and counts it).
//! [`Dataset::observations`] makes a dataset a source of [`Observation`]s like any other (a
//! bag, a live camera, the simulator), so a session runs the same on all of them.

use std::path::{Path, PathBuf};
use std::str::FromStr;

use slamkit_core::camera::{Distortion, Intrinsics, PinholeCamera};
use slamkit_core::image::{GrayImage, Image, RgbImage};
use slamkit_core::observation::{self, Observation};
use slamkit_core::{Pose3, Trajectory};

use crate::error::IoError;
use crate::image_io::{depth_to_metres, load_depth, load_gray, load_rgb};
use crate::trajectory_file::write_tum;

/// One RGB-D frame: when it was taken and where its images are.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdFrame {
    /// Position in the sequence, from 0.
    pub index: usize,
    /// Time of the colour image \[s\].
    pub timestamp: f64,
    /// Colour image file.
    pub color: PathBuf,
    /// Depth image file (16-bit).
    pub depth: PathBuf,
}

/// One stereo frame: when it was taken and where its two images are.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoFrame {
    /// Position in the sequence, from 0.
    pub index: usize,
    /// Time of the left image \[s\].
    pub timestamp: f64,
    /// Left image file.
    pub left: PathBuf,
    /// Right image file.
    pub right: PathBuf,
}

/// The decoded images of an [`RgbdFrame`].
#[derive(Debug, Clone)]
pub struct RgbdImages {
    /// Colour image.
    pub color: RgbImage,
    /// Depth \[m\]; 0.0 where the sensor gave no depth.
    pub depth_m: Image<f32>,
}

/// The decoded images of a [`StereoFrame`], both 8-bit grayscale.
#[derive(Debug, Clone)]
pub struct StereoImages {
    /// Left image.
    pub left: GrayImage,
    /// Right image.
    pub right: GrayImage,
}

/// An RGB-D sequence: frames, calibration and (when the dataset has it) ground truth.
#[derive(Debug, Clone)]
pub struct RgbdSequence {
    /// The dataset folder.
    pub root: PathBuf,
    /// Frames in time order.
    pub frames: Vec<RgbdFrame>,
    /// PinholeCamera of the colour camera.
    pub color_camera: PinholeCamera,
    /// PinholeCamera of the depth camera (equal to the colour ones when depth is registered).
    pub depth_camera: PinholeCamera,
    /// Raw depth units per metre (TUM 5000, millimetre datasets 1000).
    pub depth_units_per_metre: f64,
    /// Raw depth values meaning "no depth" besides 0 (7-Scenes: 65535).
    pub invalid_depth: Vec<u16>,
    /// `world_from_camera` ground truth, when the dataset has it.
    pub ground_truth: Option<Trajectory>,
}

/// A stereo sequence: frames, calibration of both cameras and (when known) ground truth.
#[derive(Debug, Clone)]
pub struct StereoSequence {
    /// The dataset folder.
    pub root: PathBuf,
    /// Frames in time order.
    pub frames: Vec<StereoFrame>,
    /// PinholeCamera of the left camera.
    pub left_camera: PinholeCamera,
    /// PinholeCamera of the right camera.
    pub right_camera: PinholeCamera,
    /// Maps points from the left camera frame into the right one.
    pub right_from_left: Pose3,
    /// True when the images are already rectified (KITTI); false for raw images (EuRoC).
    pub rectified: bool,
    /// `world_from_left_camera` ground truth, when the dataset has it.
    pub ground_truth: Option<Trajectory>,
}

impl RgbdSequence {
    /// A sequence whose depth is registered to colour (one camera for both) and whose only
    /// "no depth" value is 0, as TUM RGB-D and Redwood store it.
    pub fn registered(
        root: &Path,
        frames: Vec<RgbdFrame>,
        camera: PinholeCamera,
        depth_units_per_metre: f64,
        ground_truth: Option<Trajectory>,
    ) -> Self {
        Self {
            root: root.to_path_buf(),
            frames,
            color_camera: camera,
            depth_camera: camera,
            depth_units_per_metre,
            invalid_depth: Vec::new(),
            ground_truth,
        }
    }

    /// Decodes a frame's colour and depth images, depth converted to metres.
    pub fn load(&self, frame: &RgbdFrame) -> Result<RgbdImages, IoError> {
        let color = load_rgb(&frame.color)?;
        let raw = load_depth(&frame.depth)?;
        let depth_m = depth_to_metres(&raw, self.depth_units_per_metre, &self.invalid_depth);
        Ok(RgbdImages { color, depth_m })
    }
}

impl StereoSequence {
    /// Distance between the two optical centres \[m\].
    pub fn baseline_m(&self) -> f64 {
        self.right_from_left.translation.vector.norm()
    }

    /// Decodes a frame's left and right images.
    pub fn load(&self, frame: &StereoFrame) -> Result<StereoImages, IoError> {
        Ok(StereoImages {
            left: load_gray(&frame.left)?,
            right: load_gray(&frame.right)?,
        })
    }
}

/// Names of the dataset layouts [`Dataset::open`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DatasetFormat {
    /// TUM RGB-D (`rgb.txt`, `depth.txt`, `groundtruth.txt`).
    Tum,
    /// KITTI odometry stereo (`image_0/`, `image_1/`, `calib.txt`).
    Kitti,
    /// Microsoft 7-Scenes (`frame-NNNNNN.{color,depth,pose}.*`).
    SevenScenes,
    /// Open3D / Redwood RGB-D (`color/`, `depth/`, `trajectory.log`).
    Redwood,
    /// EuRoC MAV stereo (`cam0/`, `cam1/`).
    Euroc,
}

impl FromStr for DatasetFormat {
    type Err = IoError;

    /// Parses the CLI names `tum`, `kitti`, `7scenes`, `redwood`, `euroc`.
    fn from_str(s: &str) -> Result<Self, IoError> {
        match s {
            "tum" => Ok(Self::Tum),
            "kitti" => Ok(Self::Kitti),
            "7scenes" => Ok(Self::SevenScenes),
            "redwood" => Ok(Self::Redwood),
            "euroc" => Ok(Self::Euroc),
            other => Err(IoError::invalid(
                "--format",
                format!(
                    "unknown dataset format {other:?}: use tum, kitti, 7scenes, redwood or euroc"
                ),
            )),
        }
    }
}

/// Any camera dataset, opened with its reader's default configuration.
#[derive(Debug, Clone)]
pub enum Dataset {
    /// An RGB-D sequence (TUM, 7-Scenes, Redwood).
    Rgbd(RgbdSequence),
    /// A stereo sequence (KITTI, EuRoC).
    Stereo(StereoSequence),
}

impl Dataset {
    /// Opens the dataset folder `dir` in the given layout, with default reader settings.
    pub fn open(dir: &Path, format: DatasetFormat) -> Result<Self, IoError> {
        Ok(match format {
            DatasetFormat::Tum => Self::Rgbd(crate::tum_rgbd::open(dir, &Default::default())?),
            DatasetFormat::Kitti => Self::Stereo(crate::kitti::open(dir)?),
            DatasetFormat::SevenScenes => Self::Rgbd(crate::seven_scenes::open(dir)?),
            DatasetFormat::Redwood => Self::Rgbd(crate::redwood::open(dir, &Default::default())?),
            DatasetFormat::Euroc => Self::Stereo(crate::euroc::open(dir)?),
        })
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        match self {
            Self::Rgbd(s) => s.frames.len(),
            Self::Stereo(s) => s.frames.len(),
        }
    }

    /// True when the sequence has no frame.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The dataset folder.
    pub fn root(&self) -> &Path {
        match self {
            Self::Rgbd(s) => &s.root,
            Self::Stereo(s) => &s.root,
        }
    }

    /// Frame `index` decoded into an [`Observation`] (`Rgbd` or `Stereo`); `None` past the
    /// last frame.
    ///
    /// # Errors
    /// The [`IoError`] of an image that cannot be read or decoded, naming the file.
    pub fn observation(&self, index: usize) -> Option<Result<Observation, IoError>> {
        Some(match self {
            Self::Rgbd(s) => {
                let frame = s.frames.get(index)?;
                s.load(frame).map(|i| {
                    Observation::Rgbd(observation::RgbdFrame {
                        timestamp: frame.timestamp,
                        color: i.color,
                        depth_m: i.depth_m,
                    })
                })
            }
            Self::Stereo(s) => {
                let frame = s.frames.get(index)?;
                s.load(frame).map(|i| {
                    Observation::Stereo(observation::StereoFrame {
                        timestamp: frame.timestamp,
                        left: i.left,
                        right: i.right,
                    })
                })
            }
        })
    }

    /// Every frame in order, each decoded when the iterator reaches it (so decoding can run on
    /// its own thread, ahead of the consumer). A frame that cannot be decoded is an `Err` item
    /// and the iteration goes on with the next.
    pub fn observations(&self) -> impl Iterator<Item = Result<Observation, IoError>> + Send + '_ {
        (0..self.len()).map_while(|index| self.observation(index))
    }

    /// Frame timestamps \[s\], in order.
    pub fn timestamps(&self) -> Vec<f64> {
        match self {
            Self::Rgbd(s) => s.frames.iter().map(|f| f.timestamp).collect(),
            Self::Stereo(s) => s.frames.iter().map(|f| f.timestamp).collect(),
        }
    }

    /// The ground truth (`world_from_camera`, left camera for stereo), when there is one.
    pub fn ground_truth(&self) -> Option<&Trajectory> {
        match self {
            Self::Rgbd(s) => s.ground_truth.as_ref(),
            Self::Stereo(s) => s.ground_truth.as_ref(),
        }
    }

    /// Writes the ground truth as a TUM trajectory file; an error when there is none.
    pub fn write_ground_truth_tum(&self, path: &Path) -> Result<(), IoError> {
        let gt = self.ground_truth().ok_or_else(|| {
            IoError::invalid(self.root().display(), "the dataset has no ground truth")
        })?;
        write_tum(path, gt)
    }
}

/// The entries of `dir` whose file name satisfies `keep`, sorted by name.
pub(crate) fn sorted_files(
    dir: &Path,
    keep: impl Fn(&str) -> bool,
) -> Result<Vec<PathBuf>, IoError> {
    let entries = std::fs::read_dir(dir).map_err(|e| IoError::io(dir, e))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| IoError::io(dir, e))?.path();
        if path.file_name().and_then(|n| n.to_str()).is_some_and(&keep) {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// True for file names ending in an extension of `exts` (lower case, without the dot).
pub(crate) fn has_extension(name: &str, exts: &[&str]) -> bool {
    name.rsplit_once('.')
        .is_some_and(|(_, ext)| exts.contains(&ext.to_ascii_lowercase().as_str()))
}

/// A pinhole camera from `[fx, fy, cx, cy]` \[px\], `(width, height)` \[px\] and OpenCV
/// distortion `[k1, k2, p1, p2, k3]`.
pub(crate) fn camera(k: [f64; 4], size: (usize, usize), distortion: [f64; 5]) -> PinholeCamera {
    PinholeCamera::new(
        Intrinsics::from_array(k, size.0, size.1),
        Distortion::from_opencv(distortion),
    )
}

/// [`camera`] for values read from `file`: rejects non-positive focal lengths, a zero image
/// size and non-finite values.
pub(crate) fn checked_camera(
    file: impl std::fmt::Display,
    k: [f64; 4],
    size: (usize, usize),
    distortion: [f64; 5],
) -> Result<PinholeCamera, IoError> {
    let cam = camera(k, size, distortion);
    cam.intrinsics
        .validate()
        .map_err(|e| IoError::invalid(&file, format!("camera: {e}")))?;
    if distortion.iter().any(|d| !d.is_finite()) {
        return Err(IoError::invalid(file, "camera: non-finite distortion"));
    }
    Ok(cam)
}
