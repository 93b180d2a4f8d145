//! TUM RGB-D benchmark folders (Sturm et al., "A Benchmark for the Evaluation of RGB-D SLAM
//! Systems", IROS 2012): `rgb.txt` and `depth.txt` list `timestamp path` lines, `depth/*.png`
//! is 16-bit at 5000 units per metre, `groundtruth.txt` is a TUM trajectory of the colour
//! camera (`world_from_camera`, 100 Hz motion capture).
//!
//! Colour and depth are paired like the benchmark's `associate.py`: every pair closer than
//! `max_time_diff_s` is a candidate, and candidates are taken greedily, closest first, each
//! image used at most once.

use std::path::Path;

use serde::{Deserialize, Serialize};
use slamkit_core::camera::PinholeCamera;

use crate::dataset::{camera, trim_to_present, RgbdFrame, RgbdSequence};
use crate::error::{read_text, IoError};
use crate::trajectory_file::read_trajectory;

/// Which calibration to use for a TUM sequence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TumCamera {
    /// Chosen from the folder name (`freiburg1`/`fr1` …), the Kinect default otherwise.
    Auto,
    /// Freiburg 1 (ORB-SLAM2 `TUM1.yaml`, with distortion).
    Fr1,
    /// Freiburg 2 (ORB-SLAM2 `TUM2.yaml`, with distortion).
    Fr2,
    /// Freiburg 3 (no distortion: the images were undistorted by the benchmark).
    Fr3,
    /// ROS default Kinect values 525 / 525 / 319.5 / 239.5, uncalibrated.
    Kinect,
    /// A camera given by the user.
    Given(PinholeCamera),
}

/// Settings of the TUM RGB-D reader.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TumRgbdConfig {
    /// Largest timestamp difference for a colour–depth pair \[s\] (`associate.py`: 0.02).
    pub max_time_diff_s: f64,
    /// Raw depth units per metre (benchmark: 5000; ORB-SLAM2 uses 5208 for fr2).
    pub depth_units_per_metre: f64,
    /// Calibration to use.
    pub camera: TumCamera,
}

impl Default for TumRgbdConfig {
    fn default() -> Self {
        Self {
            max_time_diff_s: 0.02,
            depth_units_per_metre: 5000.0,
            camera: TumCamera::Auto,
        }
    }
}

impl TumCamera {
    /// The intrinsics (640×480) of this camera; `folder` resolves [`TumCamera::Auto`].
    ///
    /// Values of ORB-SLAM2 `Examples/RGB-D/TUM{1,2,3}.yaml`, distortion k1 k2 p1 p2 k3.
    pub fn camera(&self, folder: &Path) -> PinholeCamera {
        match self {
            Self::Auto => Self::from_folder_name(folder).camera(folder),
            Self::Fr1 => camera(
                [517.306408, 516.469215, 318.643040, 255.313989],
                (640, 480),
                [0.262383, -0.953104, -0.005358, 0.002628, 1.163314],
            ),
            Self::Fr2 => camera(
                [520.908620, 521.007327, 325.141442, 249.701764],
                (640, 480),
                [0.231222, -0.784899, -0.003257, -0.000105, 0.917205],
            ),
            Self::Fr3 => camera([535.4, 539.2, 320.1, 247.6], (640, 480), [0.0; 5]),
            Self::Kinect => camera([525.0, 525.0, 319.5, 239.5], (640, 480), [0.0; 5]),
            Self::Given(k) => *k,
        }
    }

    /// The Freiburg camera named in a folder name such as
    /// `rgbd_dataset_freiburg1_xyz`, or [`TumCamera::Kinect`].
    pub fn from_folder_name(folder: &Path) -> Self {
        let name = folder
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default()
            .to_ascii_lowercase();
        let named =
            |n: char| name.contains(&format!("freiburg{n}")) || name.contains(&format!("fr{n}"));
        if named('1') {
            Self::Fr1
        } else if named('2') {
            Self::Fr2
        } else if named('3') {
            Self::Fr3
        } else {
            Self::Kinect
        }
    }
}

/// Opens a TUM RGB-D folder: pairs colour and depth frames, reads `groundtruth.txt` when
/// present. Frames run from the first pair with an image on disk to the last; a listed image
/// missing in between is a frame that fails to load at its own index.
pub fn open(dir: &Path, config: &TumRgbdConfig) -> Result<RgbdSequence, IoError> {
    let rgb = parse_file_list(&dir.join("rgb.txt"))?;
    let depth = parse_file_list(&dir.join("depth.txt"))?;
    let pairs = associate(&rgb, &depth, config.max_time_diff_s);
    if pairs.is_empty() {
        return Err(IoError::invalid(
            dir.display(),
            format!("no colour/depth pair within {} s", config.max_time_diff_s),
        ));
    }
    let listed = pairs.len();
    let frames: Vec<RgbdFrame> = trim_to_present(pairs, |(c, d)| {
        dir.join(&c.1).is_file() || dir.join(&d.1).is_file()
    })
    .into_iter()
    .enumerate()
    .map(|(index, (c, d))| RgbdFrame {
        index,
        timestamp: c.0,
        color: dir.join(&c.1),
        depth: dir.join(&d.1),
    })
    .collect();
    if frames.is_empty() {
        let msg = format!("none of the images of the {listed} listed frames is on disk");
        return Err(IoError::invalid(dir.display(), msg));
    }
    let gt_path = dir.join("groundtruth.txt");
    let ground_truth = if gt_path.exists() {
        Some(read_trajectory(&gt_path)?.0)
    } else {
        None
    };
    let k = config.camera.camera(dir);
    Ok(RgbdSequence::registered(
        dir,
        frames,
        k,
        config.depth_units_per_metre,
        ground_truth,
    ))
}

/// A `timestamp path` entry of `rgb.txt` / `depth.txt`.
type Stamped = (f64, String);

/// Reads `rgb.txt` or `depth.txt`: `timestamp path` lines, `#` comments.
pub fn parse_file_list(path: &Path) -> Result<Vec<Stamped>, IoError> {
    let text = read_text(path)?;
    let file = path.display().to_string();
    let mut list = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut tokens = line.split_whitespace();
        let (Some(t), Some(name), None) = (tokens.next(), tokens.next(), tokens.next()) else {
            return Err(IoError::parse(&file, i + 1, "expected `timestamp path`"));
        };
        match t.parse::<f64>() {
            Ok(t) if t.is_finite() => list.push((t, name.to_string())),
            _ => return Err(IoError::parse(&file, i + 1, format!("bad timestamp {t:?}"))),
        }
    }
    if list.is_empty() {
        return Err(IoError::Empty {
            file,
            what: "no `timestamp path` line".into(),
        });
    }
    Ok(list)
}

/// An entry of each list, paired.
pub type Pair<'a, A, B> = (&'a (f64, A), &'a (f64, B));

/// Pairs entries of `a` and `b` (a timestamp and what it stamps) whose timestamps differ by
/// at most `max_diff_s`, closest first, each used once (TUM `associate.py`); the pairs come
/// back in `a`'s time order. The bag reader pairs images with it too
/// ([`crate::bag::rgbd`]).
pub fn associate<'a, A, B>(
    a: &'a [(f64, A)],
    b: &'a [(f64, B)],
    max_diff_s: f64,
) -> Vec<Pair<'a, A, B>> {
    let mut b_order: Vec<usize> = (0..b.len()).collect();
    b_order.sort_by(|&i, &j| b[i].0.total_cmp(&b[j].0));
    let b_times: Vec<f64> = b_order.iter().map(|&i| b[i].0).collect();
    let mut candidates = Vec::new();
    for (ia, (ta, _)) in a.iter().enumerate() {
        let start = b_times.partition_point(|&t| t < ta - max_diff_s);
        for (k, tb) in b_times.iter().enumerate().skip(start) {
            if *tb > ta + max_diff_s {
                break;
            }
            candidates.push(((ta - tb).abs(), ia, b_order[k]));
        }
    }
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0));
    let (mut used_a, mut used_b) = (vec![false; a.len()], vec![false; b.len()]);
    let mut pairs = Vec::new();
    for (_, ia, ib) in candidates {
        if !used_a[ia] && !used_b[ib] {
            used_a[ia] = true;
            used_b[ib] = true;
            pairs.push((ia, ib));
        }
    }
    pairs.sort_by(|x, y| a[x.0].0.total_cmp(&a[y.0].0));
    pairs.into_iter().map(|(ia, ib)| (&a[ia], &b[ib])).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stamped(ts: &[f64]) -> Vec<Stamped> {
        ts.iter().map(|&t| (t, format!("{t}.png"))).collect()
    }

    #[test]
    fn association_is_greedy_closest_first_and_one_to_one() {
        let rgb = stamped(&[1.00, 1.03, 1.10, 2.00]);
        let depth = stamped(&[1.015, 1.035, 1.5]);
        let pairs = associate(&rgb, &depth, 0.02);
        let got: Vec<(f64, f64)> = pairs.iter().map(|(a, b)| (a.0, b.0)).collect();
        // 1.03↔1.035 (5 ms) is taken first, so 1.00 gets 1.015 (15 ms); 1.10 and 2.00 have none.
        assert_eq!(got, vec![(1.00, 1.015), (1.03, 1.035)]);
    }

    #[test]
    fn camera_is_chosen_from_the_folder_name() {
        let fr1 = Path::new("/d/rgbd_dataset_freiburg1_xyz");
        assert_eq!(TumCamera::from_folder_name(fr1), TumCamera::Fr1);
        let fr3 = Path::new("/d/tum_fr3_long_office_household_samples");
        assert_eq!(TumCamera::from_folder_name(fr3), TumCamera::Fr3);
        assert_eq!(
            TumCamera::from_folder_name(Path::new("/d/x")),
            TumCamera::Kinect
        );
        let k = TumCamera::Auto.camera(fr1).intrinsics;
        assert_eq!((k.fx, k.cy), (517.306408, 255.313989));
    }
}
