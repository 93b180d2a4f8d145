//! What every camera dataset reader returns, and [`Dataset`] to open any of them by format
//! name (`slamkit vo --format tum|kitti|7scenes|redwood|euroc`).
//!
//! A reader lists the frames (timestamps and file paths) up front and checks the metadata;
//! images are decoded only when a frame is loaded, so a sequence of thousands of frames opens
//! in milliseconds and a corrupt image costs that frame only (the caller skips and counts it).
//! Every reader follows one rule for missing images (`NumberedFiles`, `trim_to_present`):
//! a frame keeps its own index and time whatever is missing around it, and a missing image is
//! that frame failing to load, never a shift of later frames against the ground truth.
//! [`Dataset::observations`] makes a dataset a source of [`Observation`]s like any other (a
//! bag, a live camera, the simulator), so a session runs the same on all of them.

use std::path::{Path, PathBuf};
use std::str::FromStr;

use slamkit_core::camera::{Distortion, Intrinsics, PinholeCamera};
use slamkit_core::image::{GrayImage, Image, RgbImage};
use slamkit_core::observation::{self, Observation};
use slamkit_core::{Pose3, Trajectory};

use crate::bag::{BagRgbd, RgbdTopics};
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
        let depth_m = self.load_depth(frame)?;
        Ok(RgbdImages { color, depth_m })
    }

    /// Decodes a frame's depth image alone, in metres (0.0 where the sensor gave none): what
    /// a map built after the run from keyframes needs, without decoding colour again.
    pub fn load_depth(&self, frame: &RgbdFrame) -> Result<Image<f32>, IoError> {
        let raw = load_depth(&frame.depth)?;
        Ok(depth_to_metres(
            &raw,
            self.depth_units_per_metre,
            &self.invalid_depth,
        ))
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
    /// A ROS 1 or ROS 2 bag of an RGB-D camera's topics ([`crate::bag::rgbd`]).
    RosBag,
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
    /// An RGB-D camera's recording in a bag.
    RgbdBag(BagRgbd),
}

impl Dataset {
    /// Opens the dataset folder `dir` in the given layout, with default reader settings (a
    /// bag's topics chosen by type: [`BagRgbd::open`] chooses them as asked).
    pub fn open(dir: &Path, format: DatasetFormat) -> Result<Self, IoError> {
        Ok(match format {
            DatasetFormat::Tum => Self::Rgbd(crate::tum_rgbd::open(dir, &Default::default())?),
            DatasetFormat::Kitti => Self::Stereo(crate::kitti::open(dir)?),
            DatasetFormat::SevenScenes => Self::Rgbd(crate::seven_scenes::open(dir)?),
            DatasetFormat::Redwood => Self::Rgbd(crate::redwood::open(dir, &Default::default())?),
            DatasetFormat::Euroc => Self::Stereo(crate::euroc::open(dir)?),
            DatasetFormat::RosBag => Self::open_bag(dir, &RgbdTopics::default())?,
        })
    }

    /// Opens the bag at `path` as an RGB-D camera's recording, its topics chosen as `topics`
    /// asks ([`BagRgbd::open`]).
    pub fn open_bag(path: &Path, topics: &RgbdTopics) -> Result<Self, IoError> {
        BagRgbd::open(path, topics)
            .map(Self::RgbdBag)
            .map_err(|e| IoError::invalid("bag", e.to_string()))
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        match self {
            Self::Rgbd(s) => s.frames.len(),
            Self::Stereo(s) => s.frames.len(),
            Self::RgbdBag(b) => b.frames.len(),
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
            Self::RgbdBag(b) => &b.path,
        }
    }

    /// Frame `index` decoded into an [`Observation`] (`Rgbd` or `Stereo`); `None` past the
    /// last frame. A bag is read from its start up to the frame: [`Dataset::observations`]
    /// reads all frames in one pass.
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
            Self::RgbdBag(b) => b.observations().nth(index)?,
        })
    }

    /// Every frame in order, each decoded when the iterator reaches it (so decoding can run on
    /// its own thread, ahead of the consumer). A frame that cannot be decoded is an `Err` item
    /// and the iteration goes on with the next.
    pub fn observations(
        &self,
    ) -> Box<dyn Iterator<Item = Result<Observation, IoError>> + Send + '_> {
        match self {
            Self::RgbdBag(b) => Box::new(b.observations()),
            _ => Box::new((0..self.len()).map_while(|index| self.observation(index))),
        }
    }

    /// Frame timestamps \[s\], in order.
    pub fn timestamps(&self) -> Vec<f64> {
        match self {
            Self::Rgbd(s) => s.frames.iter().map(|f| f.timestamp).collect(),
            Self::Stereo(s) => s.frames.iter().map(|f| f.timestamp).collect(),
            Self::RgbdBag(b) => b.frames.iter().map(|f| f.timestamp).collect(),
        }
    }

    /// The ground truth (`world_from_camera`, left camera for stereo), when there is one.
    pub fn ground_truth(&self) -> Option<&Trajectory> {
        match self {
            Self::Rgbd(s) => s.ground_truth.as_ref(),
            Self::Stereo(s) => s.ground_truth.as_ref(),
            Self::RgbdBag(_) => None,
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

/// The images of a numbered sequence (`000042.png`, `frame-000042.color.jpg`, `00042.jpg`),
/// found in a folder, by the number in their name (the first run of digits).
///
/// This and [`trim_to_present`] are the one rule every camera dataset reader follows for
/// missing images: the sequence runs from the first image present to the last, one frame per
/// number (or listed row); an image missing in between is a frame at its own index whose
/// loading fails (counted as failed by the caller), never a shift of the frames after it
/// against the ground truth, and never fatal for the dataset.
#[derive(Debug, Clone)]
pub(crate) struct NumberedFiles {
    dir: PathBuf,
    /// Name of the first file: the pattern of a missing one's name.
    template: String,
    files: std::collections::BTreeMap<u64, PathBuf>,
}

impl NumberedFiles {
    /// The files of `paths` whose name holds a number (the first file per number kept).
    pub(crate) fn new(dir: &Path, paths: Vec<PathBuf>) -> Self {
        let mut files = std::collections::BTreeMap::new();
        for path in paths {
            let number = path
                .file_name()
                .and_then(|n| n.to_str())
                .and_then(|n| digit_run(n).and_then(|r| n[r].parse::<u64>().ok()));
            if let Some(number) = number {
                files.entry(number).or_insert(path);
            }
        }
        let template = files
            .values()
            .next()
            .and_then(|p| p.file_name()?.to_str().map(str::to_string))
            .unwrap_or_default();
        Self {
            dir: dir.to_path_buf(),
            template,
            files,
        }
    }

    /// First and last numbers present.
    pub(crate) fn range(&self) -> Option<(u64, u64)> {
        Some((*self.files.keys().next()?, *self.files.keys().next_back()?))
    }

    /// The file of frame `number`: the one on disk, or the name it would have (the first
    /// file's name with its number replaced, zero-padded alike).
    pub(crate) fn path(&self, number: u64) -> PathBuf {
        if let Some(path) = self.files.get(&number) {
            return path.clone();
        }
        let name = match digit_run(&self.template) {
            Some(r) => format!(
                "{}{number:0width$}{}",
                &self.template[..r.start],
                &self.template[r.end..],
                width = r.len()
            ),
            None => number.to_string(),
        };
        self.dir.join(name)
    }
}

/// The frame numbers from the first to the last of `sets` (numbered files of the same
/// frames: colour and depth, left and right), checked: more missing numbers than images
/// present is an error naming `dir` (a folder of unrelated numbers, not a sequence with a few
/// images lost), which also bounds the frame count by the files on disk.
pub(crate) fn frame_numbers(
    dir: &Path,
    sets: &[&NumberedFiles],
) -> Result<std::ops::RangeInclusive<u64>, IoError> {
    let ranges = sets.iter().filter_map(|s| s.range());
    let (Some(first), Some(last)) = (ranges.clone().map(|r| r.0).min(), ranges.map(|r| r.1).max())
    else {
        return Err(IoError::invalid(dir.display(), "no numbered image"));
    };
    let present = sets.iter().map(|s| s.files.len()).max().unwrap_or(0);
    let slots = (last - first).saturating_add(1);
    if slots - present as u64 > present as u64 {
        let msg = format!(
            "images numbered {first} to {last}, but only {present} are present: more than \
             half of the frames would be missing"
        );
        return Err(IoError::invalid(dir.display(), msg));
    }
    Ok(first..=last)
}

/// `rows` without the leading and trailing ones whose image is not on disk (`present` false):
/// trimmed copies of a dataset list every row of the original. Rows in between stay, so a
/// missing image there is a failed frame at its own index (see [`NumberedFiles`]).
pub(crate) fn trim_to_present<T>(mut rows: Vec<T>, present: impl Fn(&T) -> bool) -> Vec<T> {
    let Some(last) = rows.iter().rposition(&present) else {
        return Vec::new();
    };
    rows.truncate(last + 1);
    let first = rows.iter().position(&present).unwrap_or(0);
    rows.drain(..first);
    rows
}

/// Byte range of the first run of ASCII digits in `name`.
fn digit_run(name: &str) -> Option<std::ops::Range<usize>> {
    let start = name.find(|c: char| c.is_ascii_digit())?;
    let len = name[start..]
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(name.len() - start);
    Some(start..start + len)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn numbered(names: &[&str]) -> NumberedFiles {
        let dir = Path::new("/seq");
        NumberedFiles::new(dir, names.iter().map(|n| dir.join(n)).collect())
    }

    #[test]
    fn missing_numbers_get_the_name_their_file_would_have() {
        let files = numbered(&["frame-000007.color.jpg", "frame-000009.color.jpg", "notes"]);
        assert_eq!(files.range(), Some((7, 9)));
        assert_eq!(
            files.path(8),
            Path::new("/seq/frame-000008.color.jpg"),
            "same padding"
        );
        assert_eq!(
            files.path(1234567),
            Path::new("/seq/frame-1234567.color.jpg")
        );
        let numbers = frame_numbers(Path::new("/seq"), &[&files]).unwrap();
        assert_eq!(numbers, 7..=9);
        // left 0..=2, right only 3: the frames of both
        let (left, right) = (numbered(&["0.png", "1.png", "2.png"]), numbered(&["3.png"]));
        assert_eq!(
            frame_numbers(Path::new("/s"), &[&left, &right]).unwrap(),
            0..=3
        );
    }

    #[test]
    fn sparse_or_absent_numbering_is_an_error() {
        let sparse = numbered(&["000000.png", "999999.png"]);
        let err = frame_numbers(Path::new("/seq"), &[&sparse]).unwrap_err();
        assert!(err.to_string().contains("only 2 are present"), "{err}");
        let none = numbered(&["a.png"]);
        assert!(frame_numbers(Path::new("/seq"), &[&none]).is_err());
        // half missing is still a sequence
        let half = numbered(&["0.png", "2.png", "4.png"]);
        assert!(frame_numbers(Path::new("/seq"), &[&half]).is_ok());
    }

    #[test]
    fn only_leading_and_trailing_missing_rows_are_trimmed() {
        let rows = vec![(0, false), (1, true), (2, false), (3, true), (4, false)];
        let kept: Vec<i32> = trim_to_present(rows, |r| r.1).iter().map(|r| r.0).collect();
        assert_eq!(kept, [1, 2, 3]);
        assert!(trim_to_present(vec![false, false], |r| *r).is_empty());
    }
}
