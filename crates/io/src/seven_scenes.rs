//! Microsoft 7-Scenes RGB-D folders (Shotton et al., "Scene Coordinate Regression Forests for
//! Camera Relocalization in RGB-D Images", CVPR 2013), flat as in 7-Scenes and 3DMatch:
//! `frame-NNNNNN.color.{png,jpg}`, `frame-NNNNNN.depth.png` (16-bit millimetres, 0 and 65535
//! invalid), `frame-NNNNNN.pose.txt` (4×4 `world_from_camera`) and optionally
//! `camera-intrinsics.txt` (3×3 K; 585 / 585 / 320 / 240 when absent).
//!
//! The numbering may start anywhere. There are no timestamps: frame N is stamped N / 30 s
//! (Kinect v1 rate). The ground-truth rotations (KinectFusion) are slightly non-orthonormal
//! (|R Rᵀ − I| up to 4e−4) and are re-orthonormalised by SVD. Colour and depth come from two
//! unregistered Kinect cameras; the poses and intrinsics are the depth camera's.

use std::path::Path;

use slamkit_core::camera::PinholeCamera;
use slamkit_core::Trajectory;

use crate::dataset::{
    camera, checked_camera, frame_numbers, sorted_files, NumberedFiles, RgbdFrame, RgbdSequence,
};
use crate::error::{read_text, IoError};
use crate::image_io::image_size;
use crate::trajectory_file::{parse_numbers, pose_from_rows};

/// Frame rate used to stamp frames \[Hz\].
pub const FRAME_RATE_HZ: f64 = 30.0;
/// Raw depth units per metre (millimetres).
const DEPTH_UNITS_PER_METRE: f64 = 1000.0;
/// Raw depth marking "no depth" in the original dataset (3DMatch copies use 0).
const INVALID_DEPTH: u16 = 65535;

/// Opens a 7-Scenes sequence folder. Frames run from the first numbered colour or depth
/// image to the last; one missing (colour or depth) is a frame that fails to load at its own
/// number. Frames without a `.pose.txt` simply have no ground truth.
pub fn open(dir: &Path) -> Result<RgbdSequence, IoError> {
    let numbered = |kind: &str| -> Result<NumberedFiles, IoError> {
        let files = sorted_files(dir, |n| frame_number(n).is_some_and(|f| f.1 == kind))?;
        Ok(NumberedFiles::new(dir, files))
    };
    let (colors, depths) = (numbered("color")?, numbered("depth")?);
    if colors.range().is_none() {
        return Err(IoError::invalid(
            dir.display(),
            "no frame-NNNNNN.color.{png,jpg} file",
        ));
    }
    let mut frames = Vec::new();
    let mut gt = Trajectory::new();
    for (index, number) in frame_numbers(dir, &[&colors, &depths])?.enumerate() {
        let timestamp = number as f64 / FRAME_RATE_HZ;
        let depth = depths.path(number);
        let pose_path = depth.with_file_name(
            depth
                .file_name()
                .and_then(|n| n.to_str())
                .unwrap_or_default()
                .replace(".depth.png", ".pose.txt"),
        );
        if pose_path.is_file() {
            gt.push(timestamp, read_pose(&pose_path)?);
        }
        frames.push(RgbdFrame {
            index,
            timestamp,
            color: colors.path(number),
            depth,
        });
    }
    let Some(first) = frames.iter().find(|f| f.depth.is_file()) else {
        return Err(IoError::invalid(dir.display(), "no depth image"));
    };
    let size = image_size(&first.depth)?;
    let k = read_intrinsics(&dir.join("camera-intrinsics.txt"), size)?;
    Ok(RgbdSequence {
        root: dir.to_path_buf(),
        frames,
        color_camera: k,
        depth_camera: k,
        depth_units_per_metre: DEPTH_UNITS_PER_METRE,
        invalid_depth: vec![INVALID_DEPTH],
        ground_truth: (!gt.is_empty()).then_some(gt),
    })
}

/// For `frame-NNNNNN.color.png|jpg` and `frame-NNNNNN.depth.png`: the number and the kind
/// (`color` or `depth`).
fn frame_number(name: &str) -> Option<(u64, &'static str)> {
    let (stem, kind) = if let Some(stem) = name.strip_suffix(".depth.png") {
        (stem, "depth")
    } else {
        let stem = name
            .strip_suffix(".color.png")
            .or_else(|| name.strip_suffix(".color.jpg"))?;
        (stem, "color")
    };
    let digits = stem.strip_prefix("frame-")?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    Some((digits.parse().ok()?, kind))
}

/// Reads a `.pose.txt`: four lines of four numbers, `world_from_camera`.
pub fn read_pose(path: &Path) -> Result<slamkit_core::Pose3, IoError> {
    let text = read_text(path)?;
    let rows: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
        .collect();
    pose_from_rows(&rows, &path.display().to_string())
}

/// Reads `camera-intrinsics.txt` (3×3 K, row-major), or the dataset's nominal values when the
/// file is absent.
fn read_intrinsics(path: &Path, size: (usize, usize)) -> Result<PinholeCamera, IoError> {
    if !path.exists() {
        return Ok(camera([585.0, 585.0, 320.0, 240.0], size, [0.0; 5]));
    }
    let file = path.display().to_string();
    let mut k = Vec::with_capacity(9);
    for (i, line) in read_text(path)?.lines().enumerate() {
        k.extend(parse_numbers(line, &file, i + 1)?);
    }
    if let [fx, skew, cx, r10, fy, cy, r20, r21, r22] = k[..] {
        let structured = [skew, r10, r20, r21].iter().all(|v| *v == 0.0) && r22 == 1.0;
        if structured {
            return checked_camera(file, [fx, fy, cx, cy], size, [0.0; 5]);
        }
    }
    Err(IoError::invalid(
        file,
        "expected a 3x3 camera matrix [fx 0 cx; 0 fy cy; 0 0 1]",
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_names_are_recognised() {
        assert_eq!(frame_number("frame-000123.color.jpg"), Some((123, "color")));
        assert_eq!(frame_number("frame-7.color.png"), Some((7, "color")));
        assert_eq!(frame_number("frame-000123.depth.png"), Some((123, "depth")));
        assert_eq!(frame_number("frame-000123.pose.txt"), None);
        assert_eq!(frame_number("frame-.color.png"), None);
        assert_eq!(frame_number("frame-1a.color.png"), None);
        assert_eq!(
            frame_number("frame-99999999999999999999999.color.png"),
            None
        );
    }
}
