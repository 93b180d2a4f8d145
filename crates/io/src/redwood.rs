//! Open3D / Redwood RGB-D folders (Choi, Zhou and Koltun, "Robust Reconstruction of Indoor
//! Scenes", CVPR 2015): `color/*.{jpg,png}` and `depth/*.png` (16-bit millimetres, 0 invalid)
//! paired by the number in their names (a missing one is a frame that fails to load at its
//! own number), optional `trajectory.log` and an optional Open3D camera JSON
//! (`camera_primesense.json` or `camera_intrinsic.json`; PrimeSense defaults 525 / 525 /
//! 319.5 / 239.5 when absent).
//!
//! `trajectory.log` holds one block per frame, in frame order: a metadata line of three
//! integers (`id id n`), then a 4×4 `world_from_camera` matrix on four lines. There are no
//! timestamps: frame (and image number) i is stamped i / `frame_rate_hz`.

use std::path::Path;

use serde::{Deserialize, Serialize};
use slamkit_core::camera::PinholeCamera;
use slamkit_core::Trajectory;

use crate::dataset::{
    camera, checked_camera, frame_numbers, has_extension, sorted_files, NumberedFiles, RgbdFrame,
    RgbdSequence,
};
use crate::error::{read_text, IoError};
use crate::image_io::image_size;
use crate::trajectory_file::pose_from_rows;

/// Settings of the Redwood reader.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RedwoodConfig {
    /// Raw depth units per metre (Redwood: millimetres, 1000).
    pub depth_units_per_metre: f64,
    /// Rate used to stamp frames \[Hz\] (PrimeSense / Kinect: 30).
    pub frame_rate_hz: f64,
}

impl Default for RedwoodConfig {
    fn default() -> Self {
        Self {
            depth_units_per_metre: 1000.0,
            frame_rate_hz: 30.0,
        }
    }
}

/// Camera JSON names Open3D writes, tried in order.
const CAMERA_FILES: [&str; 2] = ["camera_primesense.json", "camera_intrinsic.json"];

/// Opens a Redwood / Open3D RGB-D folder.
pub fn open(dir: &Path, config: &RedwoodConfig) -> Result<RgbdSequence, IoError> {
    if !(config.frame_rate_hz > 0.0 && config.depth_units_per_metre > 0.0) {
        return Err(IoError::invalid(
            dir.display(),
            "frame rate and depth scale must be positive",
        ));
    }
    let numbered = |folder: &str, exts: &[&str]| -> Result<NumberedFiles, IoError> {
        let dir = dir.join(folder);
        let files = sorted_files(&dir, |n| has_extension(n, exts))?;
        Ok(NumberedFiles::new(&dir, files))
    };
    let colors = numbered("color", &["jpg", "jpeg", "png"])?;
    let depths = numbered("depth", &["png"])?;
    let Some((first_depth, _)) = depths.range() else {
        return Err(IoError::invalid(
            dir.join("depth").display(),
            "no numbered depth image",
        ));
    };
    let size = image_size(&depths.path(first_depth))?;
    let frames: Vec<RgbdFrame> = frame_numbers(dir, &[&colors, &depths])?
        .enumerate()
        .map(|(index, number)| RgbdFrame {
            index,
            timestamp: number as f64 / config.frame_rate_hz,
            color: colors.path(number),
            depth: depths.path(number),
        })
        .collect();
    let log = dir.join("trajectory.log");
    let ground_truth = if log.exists() {
        Some(parse_log(
            &read_text(&log)?,
            &log.display().to_string(),
            config.frame_rate_hz,
        )?)
    } else {
        None
    };
    let k = read_camera(dir, size)?;
    Ok(RgbdSequence::registered(
        dir,
        frames,
        k,
        config.depth_units_per_metre,
        ground_truth,
    ))
}

/// Parses a Redwood / Open3D `.log` trajectory; pose i is stamped i / `frame_rate_hz`.
/// Errors name the file (`file`) and line.
pub fn parse_log(text: &str, file: &str, frame_rate_hz: f64) -> Result<Trajectory, IoError> {
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
        .collect();
    let mut traj = Trajectory::new();
    for block in lines.chunks(5) {
        let Some((&(no, header), rows)) = block.split_first() else {
            continue;
        };
        let ids: Vec<&str> = header.split_whitespace().collect();
        if ids.len() != 3 || ids.iter().any(|t| t.parse::<i64>().is_err()) {
            return Err(IoError::parse(
                file,
                no,
                "expected a block header of 3 integers",
            ));
        }
        if rows.len() != 4 {
            return Err(IoError::parse(
                file,
                no,
                "block truncated: a 4x4 matrix must follow",
            ));
        }
        let pose = pose_from_rows(rows, file)?;
        traj.push(traj.len() as f64 / frame_rate_hz, pose);
    }
    if traj.is_empty() {
        return Err(IoError::Empty {
            file: file.to_string(),
            what: "no pose block".into(),
        });
    }
    Ok(traj)
}

/// Open3D `PinholeCameraIntrinsic` JSON: `width`, `height`, column-major `intrinsic_matrix`.
#[derive(Deserialize)]
struct CameraJson {
    width: usize,
    height: usize,
    intrinsic_matrix: [f64; 9],
}

/// Reads the camera JSON when there is one, else PrimeSense defaults at the depth image size.
fn read_camera(dir: &Path, size: (usize, usize)) -> Result<PinholeCamera, IoError> {
    let Some(path) = CAMERA_FILES
        .iter()
        .map(|n| dir.join(n))
        .find(|p| p.is_file())
    else {
        return Ok(camera([525.0, 525.0, 319.5, 239.5], size, [0.0; 5]));
    };
    let text = read_text(&path)?;
    let cam: CameraJson = serde_json::from_str(&text).map_err(|e| IoError::Parse {
        file: path.display().to_string(),
        line: e.line(),
        message: e.to_string(),
    })?;
    let [fx, _, _, _, fy, _, cx, cy, _] = cam.intrinsic_matrix;
    let size = (cam.width, cam.height);
    checked_camera(path.display(), [fx, fy, cx, cy], size, [0.0; 5])
}

#[cfg(test)]
mod tests {
    use super::*;

    const BLOCK: &str = "0 0 1\n1 0 0 0.5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";

    #[test]
    fn log_blocks_become_poses() {
        let text = format!("{BLOCK}{}", BLOCK.replace("0 0 1\n1", "1 1 2\n1"));
        let traj = parse_log(&text, "t.log", 30.0).unwrap();
        assert_eq!(traj.len(), 2);
        assert!((traj.poses[1].timestamp - 1.0 / 30.0).abs() < 1e-15);
        assert_eq!(traj.poses[0].pose.translation.x, 0.5);
    }

    #[test]
    fn broken_logs_name_the_line() {
        let truncated = &BLOCK[..BLOCK.len() - 8];
        assert!(matches!(
            parse_log(truncated, "t", 30.0),
            Err(IoError::Parse { line: 1, .. })
        ));
        let bad_header = BLOCK.replace("0 0 1\n1", "a b\n1");
        assert!(matches!(
            parse_log(&bad_header, "t", 30.0),
            Err(IoError::Parse { line: 1, .. })
        ));
        let bad_row = BLOCK.replace("0 1 0 0", "0 1 0 nan");
        assert!(matches!(
            parse_log(&bad_row, "t", 30.0),
            Err(IoError::Parse { line: 3, .. })
        ));
        let bad_last = BLOCK.replace("0 0 0 1", "0 0 1 1");
        assert!(matches!(
            parse_log(&bad_last, "t", 30.0),
            Err(IoError::Parse { line: 5, .. })
        ));
        assert!(matches!(
            parse_log("", "t", 30.0),
            Err(IoError::Empty { .. })
        ));
    }
}
