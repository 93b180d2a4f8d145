//! KITTI odometry stereo sequences (Geiger et al., "Are we ready for Autonomous Driving? The
//! KITTI Vision Benchmark Suite", CVPR 2012): `image_0/` (left) and `image_1/` (right)
//! rectified grayscale PNGs named `NNNNNN.png`, `calib.txt` with the projection matrices
//! `P0`, `P1`, optional `times.txt` (seconds, one a line; 10 Hz when absent) and optional
//! `poses.txt` (3×4 `world_from_cam0` a line, world = cam0 at frame 0).
//!
//! After rectification both cameras share K, and `P1 = K [I | (−b, 0, 0)ᵀ]`, so the baseline is
//! `b = −P1[0,3] / P1[0,0]`.
//!
//! Frame `NNNNNN` is stamped from line `NNNNNN` of `times.txt` (or `NNNNNN` × 0.1 s) and
//! `poses.txt` line `NNNNNN` is its ground truth, so a missing image (left or right) is a frame
//! that fails to load at its own number, never a shift of the frames after it.

use std::path::Path;

use nalgebra::{Matrix3x4, Translation3};
use slamkit_core::camera::PinholeCamera;
use slamkit_core::{Pose3, Trajectory};

use crate::dataset::{
    camera, frame_numbers, has_extension, sorted_files, NumberedFiles, StereoFrame, StereoSequence,
};
use crate::error::{read_text, IoError};
use crate::image_io::image_size;
use crate::trajectory_file::{parse_numbers, read_trajectory, TrajectoryFormat};

/// Frame period when `times.txt` is absent \[s\] (KITTI records at 10 Hz).
const NOMINAL_PERIOD_S: f64 = 0.1;

/// The rectified projection matrices of the two grayscale cameras.
#[derive(Debug, Clone, PartialEq)]
pub struct KittiCalib {
    /// Left (cam0) projection matrix `K [I | 0]` \[px\].
    pub p0: Matrix3x4<f64>,
    /// Right (cam1) projection matrix `K [I | (−b, 0, 0)ᵀ]` \[px\].
    pub p1: Matrix3x4<f64>,
}

impl KittiCalib {
    /// Stereo baseline `−P1[0,3] / P1[0,0]` \[m\].
    pub fn baseline_m(&self) -> f64 {
        -self.p1[(0, 3)] / self.p1[(0, 0)]
    }

    /// Left camera (pinhole, no distortion) for images of `width × height` pixels (no distortion).
    pub fn left_camera(&self, width: usize, height: usize) -> PinholeCamera {
        camera_of(&self.p0, width, height)
    }

    /// Right camera (pinhole, no distortion) for images of `width × height` pixels (no distortion).
    pub fn right_camera(&self, width: usize, height: usize) -> PinholeCamera {
        camera_of(&self.p1, width, height)
    }
}

fn camera_of(p: &Matrix3x4<f64>, width: usize, height: usize) -> PinholeCamera {
    camera(
        [p[(0, 0)], p[(1, 1)], p[(0, 2)], p[(1, 2)]],
        (width, height),
        [0.0; 5],
    )
}

/// Parses a KITTI `calib.txt`: lines `P0: 12 numbers`, `P1: …` (other labels such as `P2`,
/// `Tr` are ignored); unlabelled 12-number lines are taken as P0, P1, … in order.
///
/// Fails, naming the line, on a malformed line, and when P0/P1 are missing, have a
/// non-positive focal length or give a non-positive baseline.
pub fn parse_calib(text: &str) -> Result<KittiCalib, IoError> {
    parse_calib_named(text, "<input>")
}

fn parse_calib_named(text: &str, file: &str) -> Result<KittiCalib, IoError> {
    let (mut p0, mut p1) = (None, None);
    let mut unlabelled = 0;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (label, numbers) = match line.split_once(':') {
            Some((label, rest)) => (label.trim().to_string(), rest),
            None => {
                unlabelled += 1;
                (format!("P{}", unlabelled - 1), line)
            }
        };
        let slot = match label.as_str() {
            "P0" => &mut p0,
            "P1" => &mut p1,
            _ => continue,
        };
        let v = parse_numbers(numbers, file, i + 1)?;
        if v.len() != 12 {
            let msg = format!("{label} has {} numbers, need 12", v.len());
            return Err(IoError::parse(file, i + 1, msg));
        }
        *slot = Some((i + 1, Matrix3x4::from_row_slice(&v)));
    }
    let (Some((line0, p0)), Some((line1, p1))) = (p0, p1) else {
        return Err(IoError::invalid(file, "P0 and P1 are both needed"));
    };
    for (line, p) in [(line0, &p0), (line1, &p1)] {
        if !(p[(0, 0)] > 0.0 && p[(1, 1)] > 0.0) {
            return Err(IoError::parse(file, line, "focal length must be positive"));
        }
    }
    let calib = KittiCalib { p0, p1 };
    let b = calib.baseline_m();
    if !(b.is_finite() && b > 0.0) {
        return Err(IoError::parse(
            file,
            line1,
            format!("baseline {b} m is not positive"),
        ));
    }
    Ok(calib)
}

/// Opens a KITTI odometry sequence folder (`image_0/`, `image_1/`, `calib.txt`, optional
/// `times.txt` and `poses.txt`).
pub fn open(dir: &Path) -> Result<StereoSequence, IoError> {
    let calib_path = dir.join("calib.txt");
    let calib = parse_calib_named(&read_text(&calib_path)?, &calib_path.display().to_string())?;
    let images = |folder: &str| -> Result<NumberedFiles, IoError> {
        let dir = dir.join(folder);
        let files = sorted_files(&dir, |n| has_extension(n, &["png"]))?;
        Ok(NumberedFiles::new(&dir, files))
    };
    let (lefts, rights) = (images("image_0")?, images("image_1")?);
    let Some((first, _)) = lefts.range() else {
        return Err(IoError::invalid(
            dir.join("image_0").display(),
            "no PNG image",
        ));
    };
    let (width, height) = image_size(&lefts.path(first))?;
    let numbers = frame_numbers(dir, &[&lefts, &rights])?;
    let times = read_times(dir, usize::try_from(*numbers.end()).unwrap_or(usize::MAX))?;
    let mut frames = Vec::new();
    for (index, number) in numbers.enumerate() {
        frames.push(StereoFrame {
            index,
            timestamp: times.at(number),
            left: lefts.path(number),
            right: rights.path(number),
        });
    }
    let ground_truth = read_poses(dir)?;
    Ok(StereoSequence {
        root: dir.to_path_buf(),
        frames,
        left_camera: calib.left_camera(width, height),
        right_camera: calib.right_camera(width, height),
        right_from_left: Pose3::from_parts(
            Translation3::new(-calib.baseline_m(), 0.0, 0.0),
            Default::default(),
        ),
        rectified: true,
        ground_truth,
    })
}

/// Frame times: `times.txt`, or the nominal rate when there is none.
enum Times {
    Listed(Vec<f64>),
    Nominal,
}

impl Times {
    /// Time of frame `number` \[s\] (listed times cover every frame read).
    fn at(&self, number: u64) -> f64 {
        match self {
            Self::Listed(times) => usize::try_from(number)
                .ok()
                .and_then(|i| times.get(i))
                .copied()
                .unwrap_or(f64::NAN),
            Self::Nominal => number as f64 * NOMINAL_PERIOD_S,
        }
    }
}

/// Times of frames 0 to `last` (and beyond, for poses): `times.txt` when present (it must
/// cover them all), else frame number × 0.1 s.
fn read_times(dir: &Path, last: usize) -> Result<Times, IoError> {
    let path = dir.join("times.txt");
    if !path.exists() {
        return Ok(Times::Nominal);
    }
    let file = path.display().to_string();
    let mut times = Vec::new();
    for (i, line) in read_text(&path)?.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        match parse_numbers(line, &file, i + 1)?[..] {
            [t] => times.push(t),
            _ => return Err(IoError::parse(&file, i + 1, "expected one timestamp")),
        }
    }
    if times.len() <= last {
        let msg = format!("{} timestamps for frames 0 to {last}", times.len());
        return Err(IoError::invalid(file, msg));
    }
    Ok(Times::Listed(times))
}

/// `poses.txt` as a trajectory stamped with `times.txt` (or index × 0.1 s), when present.
fn read_poses(dir: &Path) -> Result<Option<Trajectory>, IoError> {
    let path = dir.join("poses.txt");
    if !path.exists() {
        return Ok(None);
    }
    let (mut traj, format) = read_trajectory(&path)?;
    if format != TrajectoryFormat::Kitti {
        return Err(IoError::invalid(path.display(), "not in KITTI 3x4 format"));
    }
    let times = read_times(dir, traj.len().saturating_sub(1))?;
    for (number, pose) in (0u64..).zip(traj.poses.iter_mut()) {
        pose.timestamp = times.at(number);
    }
    Ok(Some(traj))
}

#[cfg(test)]
mod tests {
    use super::*;

    const CALIB: &str = "P0: 7.070912e+02 0 6.018873e+02 0 0 7.070912e+02 1.831104e+02 0 0 0 1 0\n\
                         P1: 7.070912e+02 0 6.018873e+02 -3.798145e+02 0 7.070912e+02 1.831104e+02 0 0 0 1 0\n";

    #[test]
    fn calib_gives_baseline_and_intrinsics() {
        let c = parse_calib(CALIB).unwrap();
        assert!((c.baseline_m() - 379.8145 / 707.0912).abs() < 1e-12);
        let k = c.left_camera(1226, 370).intrinsics;
        assert_eq!(
            (k.fx, k.fy, k.cx, k.cy),
            (707.0912, 707.0912, 601.8873, 183.1104)
        );
    }

    #[test]
    fn unlabelled_calib_lines_are_p0_p1() {
        let text: String = CALIB.lines().map(|l| format!("{}\n", &l[3..])).collect();
        assert_eq!(parse_calib(&text).unwrap(), parse_calib(CALIB).unwrap());
    }

    #[test]
    fn bad_calibs_are_errors() {
        let only_p0 = CALIB.lines().next().unwrap();
        assert!(matches!(parse_calib(only_p0), Err(IoError::Invalid { .. })));
        let short = "P0: 1 2 3\nP1: 1 2 3\n";
        assert!(matches!(
            parse_calib(short),
            Err(IoError::Parse { line: 1, .. })
        ));
        let no_baseline = CALIB.replace("-3.798145e+02", "0");
        assert!(matches!(
            parse_calib(&no_baseline),
            Err(IoError::Parse { line: 2, .. })
        ));
        let nan = CALIB.replace("7.070912e+02 0 6", "nan 0 6");
        assert!(parse_calib(&nan).is_err());
        let zero_f = CALIB.replace("P0: 7.070912e+02", "P0: 0");
        assert!(matches!(
            parse_calib(&zero_f),
            Err(IoError::Parse { line: 1, .. })
        ));
        for garbage in ["", ":", "P0:", "P1: x", "\u{0}\u{1}:::", "P0 1 2"] {
            assert!(parse_calib(garbage).is_err(), "{garbage:?}");
        }
    }
}
