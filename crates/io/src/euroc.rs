//! EuRoC MAV stereo folders in the ASL layout (Burri et al., "The EuRoC micro aerial vehicle
//! datasets", IJRR 2016), with or without the `mav0/` level: `cam0/` and `cam1/` each hold
//! `data.csv` (`#timestamp \[ns\],filename`), `data/<t_ns>.png` (raw, distorted, unrectified
//! grayscale) and `sensor.yaml` (`T_BS` = `body_from_camera`, pinhole `intrinsics`
//! fu fv cu cv, radial-tangential `distortion_coefficients` k1 k2 p1 p2, `resolution`).
//!
//! A frame is a cam0 row of `data.csv`, from the first row whose PNG exists to the last
//! (trimmed copies list rows without images); the right image is cam1's row of the same stamp
//! (`cam1/data/<t_ns>.png` when it has none). A missing image in between is a frame that fails
//! to load at its own index. Ground truth, when `state_groundtruth_estimate0/data.csv`
//! exists, is `world_from_body`; it is returned as `world_from_cam0 = world_from_body ·
//! body_from_cam0`, the pose stereo odometry estimates.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::Matrix3x4;
use slamkit_core::camera::PinholeCamera;
use slamkit_core::Pose3;

use crate::dataset::{checked_camera, trim_to_present, StereoFrame, StereoSequence};
use crate::error::{read_text, IoError};
use crate::trajectory_file::{ns_to_s, parse_numbers, pose_from_matrix, read_trajectory};

/// Calibration of one EuRoC camera, from its `sensor.yaml`.
#[derive(Debug, Clone)]
pub struct EurocCamera {
    /// Pinhole intrinsics with radial-tangential distortion.
    pub camera: PinholeCamera,
    /// `T_BS`: maps camera points into the body (IMU) frame.
    pub body_from_camera: Pose3,
}

/// Opens a EuRoC folder (the `mav0/` folder, or its parent).
pub fn open(dir: &Path) -> Result<StereoSequence, IoError> {
    let root = if dir.join("mav0").is_dir() {
        dir.join("mav0")
    } else {
        dir.to_path_buf()
    };
    let cam0 = read_sensor_yaml(&root.join("cam0/sensor.yaml"))?;
    let cam1 = read_sensor_yaml(&root.join("cam1/sensor.yaml"))?;
    let left_rows = read_image_list(&root.join("cam0"))?;
    let right_rows: HashMap<u64, PathBuf> =
        read_image_list(&root.join("cam1"))?.into_iter().collect();
    let right_of = |ns: u64| {
        right_rows
            .get(&ns)
            .cloned()
            .unwrap_or_else(|| root.join("cam1/data").join(format!("{ns}.png")))
    };
    let frames: Vec<StereoFrame> = trim_to_present(left_rows, |(_, left)| left.is_file())
        .into_iter()
        .enumerate()
        .map(|(index, (ns, left))| StereoFrame {
            index,
            timestamp: ns_to_s(ns),
            right: right_of(ns),
            left,
        })
        .collect();
    if frames.is_empty() {
        return Err(IoError::invalid(root.display(), "no cam0 image on disk"));
    }
    let gt_path = root.join("state_groundtruth_estimate0/data.csv");
    let ground_truth = if gt_path.exists() {
        let (mut gt, _) = read_trajectory(&gt_path)?;
        for p in &mut gt.poses {
            p.pose *= cam0.body_from_camera;
        }
        Some(gt)
    } else {
        None
    };
    Ok(StereoSequence {
        root,
        frames,
        right_from_left: cam1.body_from_camera.inverse() * cam0.body_from_camera,
        left_camera: cam0.camera,
        right_camera: cam1.camera,
        rectified: false,
        ground_truth,
    })
}

/// Rows of `<cam>/data.csv`: (timestamp \[ns\], path of the image in `<cam>/data/`).
fn read_image_list(cam_dir: &Path) -> Result<Vec<(u64, PathBuf)>, IoError> {
    let csv = cam_dir.join("data.csv");
    let file = csv.display().to_string();
    let mut rows = Vec::new();
    for (i, line) in read_text(&csv)?.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let Some((ts, name)) = line.split_once(',') else {
            return Err(IoError::parse(
                &file,
                i + 1,
                "expected `timestamp,filename`",
            ));
        };
        let ns: u64 = ts.trim().parse().map_err(|_| {
            IoError::parse(&file, i + 1, format!("bad timestamp {ts:?} (integer ns)"))
        })?;
        rows.push((ns, cam_dir.join("data").join(name.trim())));
    }
    Ok(rows)
}

/// Reads a camera `sensor.yaml` (the few keys needed, so no YAML library is pulled in).
pub fn read_sensor_yaml(path: &Path) -> Result<EurocCamera, IoError> {
    let text = read_text(path)?;
    parse_sensor_yaml(&text, &path.display().to_string())
}

/// Parses a camera `sensor.yaml` given as text; `file` names it in errors.
pub fn parse_sensor_yaml(text: &str, file: &str) -> Result<EurocCamera, IoError> {
    let t_bs = yaml_list(text, file, "T_BS", "data", 16)?;
    let k = yaml_list(text, file, "", "intrinsics", 4)?;
    let d = yaml_list(text, file, "", "distortion_coefficients", 4)?;
    let res = yaml_list(text, file, "", "resolution", 2)?;
    if t_bs[12..] != [0.0, 0.0, 0.0, 1.0] {
        return Err(IoError::invalid(file, "T_BS last row must be 0 0 0 1"));
    }
    let body_from_camera = pose_from_matrix(&Matrix3x4::from_row_slice(&t_bs[..12]))
        .map_err(|m| IoError::invalid(file, format!("T_BS: {m}")))?;
    let [w, h] = [res[0], res[1]];
    let whole = |v: f64| v >= 1.0 && v.fract() == 0.0 && v < 1e6;
    if !(whole(w) && whole(h)) {
        return Err(IoError::invalid(
            file,
            "resolution must be two positive integers",
        ));
    }
    let size = (w as usize, h as usize);
    let distortion = [d[0], d[1], d[2], d[3], 0.0];
    Ok(EurocCamera {
        camera: checked_camera(file, [k[0], k[1], k[2], k[3]], size, distortion)?,
        body_from_camera,
    })
}

/// The `[a, b, …]` list of `key:`, looked for after the line `section:` when `section` is not
/// empty; it must hold exactly `len` numbers. Lists may span lines, as `T_BS` data does.
fn yaml_list(
    text: &str,
    file: &str,
    section: &str,
    key: &str,
    len: usize,
) -> Result<Vec<f64>, IoError> {
    let start = if section.is_empty() {
        0
    } else {
        find_key(text, section, 0)
            .ok_or_else(|| IoError::invalid(file, format!("no `{section}:` key")))?
    };
    let at = find_key(text, key, start)
        .ok_or_else(|| IoError::invalid(file, format!("no `{key}:` key")))?;
    let line_no = text[..at].lines().count().max(1);
    let rest = &text[at..];
    let list = rest
        .split_once('[')
        .and_then(|(_, r)| r.split_once(']'))
        .map(|(inside, _)| inside)
        .ok_or_else(|| IoError::parse(file, line_no, format!("`{key}` is not a [..] list")))?;
    let values = parse_numbers(list, file, line_no)?;
    if values.len() != len {
        let msg = format!("`{key}` has {} values, need {len}", values.len());
        return Err(IoError::parse(file, line_no, msg));
    }
    Ok(values)
}

/// Byte offset of the line whose content starts with `key:`, at or after `from`.
fn find_key(text: &str, key: &str, from: usize) -> Option<usize> {
    let mut offset = 0;
    for line in text.split_inclusive('\n') {
        let trimmed = line.trim_start();
        if offset >= from
            && trimmed
                .strip_prefix(key)
                .is_some_and(|r| r.trim_start().starts_with(':'))
        {
            return Some(offset + (line.len() - trimmed.len()));
        }
        offset += line.len();
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    const YAML: &str = "%YAML:1.0\nsensor_type: camera\nT_BS:\n  cols: 4\n  rows: 4\n  \
        data: [0.0, -1.0, 0.0, 0.1,\n         1.0, 0.0, 0.0, 0.2,\n 0.0, 0.0, 1.0, 0.3,\n  \
        0.0, 0.0, 0.0, 1.0]\nrate_hz: 20\nresolution: [752, 480]\n\
        intrinsics: [458.654, 457.296, 367.215, 248.375] #fu, fv, cu, cv\n\
        distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]\n";

    #[test]
    fn sensor_yaml_is_parsed() {
        let cam = parse_sensor_yaml(YAML, "s.yaml").unwrap();
        let k = &cam.camera.intrinsics;
        assert_eq!(
            (k.fx, k.fy, k.cx, k.cy),
            (458.654, 457.296, 367.215, 248.375)
        );
        assert_eq!((k.width, k.height), (752, 480));
        let t = cam.body_from_camera.translation.vector;
        assert_eq!((t.x, t.y, t.z), (0.1, 0.2, 0.3));
        let x_cam_in_body = cam.body_from_camera.rotation * nalgebra::Vector3::x();
        assert!((x_cam_in_body - nalgebra::Vector3::y()).norm() < 1e-12);
    }

    #[test]
    fn broken_sensor_yaml_is_an_error() {
        for (from, to) in [
            ("intrinsics: [458.654, ", "intrinsics: [nan, "),
            ("resolution: [752, 480]", "resolution: [752]"),
            ("resolution: [752, 480]", "resolution: [752.5, 480]"),
            ("0.0, 0.0, 0.0, 1.0]", "0.0, 0.0, 0.0, 2.0]"),
            ("0.0, -1.0, 0.0, 0.1", "0.0, -3.0, 0.0, 0.1"),
            ("distortion_coefficients", "distortion"),
            ("data: [", "data: "),
        ] {
            let broken = YAML.replace(from, to);
            assert!(parse_sensor_yaml(&broken, "s.yaml").is_err(), "{to}");
        }
    }
}
