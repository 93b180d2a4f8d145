//! Writing KITTI odometry stereo folders (Geiger et al., CVPR 2012), the layout [`crate::kitti`]
//! reads: `image_0/NNNNNN.png` (left) and `image_1/NNNNNN.png` (right), rectified 8-bit grey;
//! `calib.txt` with `P0: K [I | 0]` and `P1: K [I | (−b, 0, 0)ᵀ]` (scaled by fx, as KITTI
//! stores it); `times.txt` (seconds, one a line); `poses.txt` (3×4 `world_from_cam0` a line,
//! the world being cam0 at the first frame).
//!
//! Calibration numbers are written in Rust's shortest round-trip form, so they read back bit
//! for bit; time stamps get 6 decimals, poses 12.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Matrix3x4;
use slamkit_core::camera::Intrinsics;
use slamkit_core::image::GrayImage;
use slamkit_core::Trajectory;

use crate::error::IoError;
use crate::image_writer::save_gray_png;
use crate::kitti::KittiCalib;
use crate::trajectory_file::write_kitti;

impl KittiCalib {
    /// The projection matrices of a rectified pair with intrinsics `k` whose right camera is
    /// `baseline_m` along the left one's x axis.
    pub fn rectified(k: &Intrinsics, baseline_m: f64) -> Self {
        let p0 = Matrix3x4::new(
            k.fx, 0.0, k.cx, 0.0, //
            0.0, k.fy, k.cy, 0.0, //
            0.0, 0.0, 1.0, 0.0,
        );
        let mut p1 = p0;
        p1[(0, 3)] = -k.fx * baseline_m;
        Self { p0, p1 }
    }
}

/// Writes a KITTI odometry folder frame by frame; [`KittiWriter::finish`] writes the times and
/// the poses.
#[derive(Debug)]
pub struct KittiWriter {
    dir: PathBuf,
    times: String,
    frames: usize,
    last_timestamp: Option<f64>,
}

impl KittiWriter {
    /// Creates `dir` with `image_0/`, `image_1/` and `calib.txt`.
    pub fn create(dir: &Path, calib: &KittiCalib) -> Result<Self, IoError> {
        let b = calib.baseline_m();
        if !(b.is_finite() && b > 0.0) || calib.p0.iter().any(|v| !v.is_finite()) {
            let msg = format!("calibration with baseline {b} m cannot be written");
            return Err(IoError::invalid(dir.display(), msg));
        }
        for sub in ["image_0", "image_1"] {
            let path = dir.join(sub);
            std::fs::create_dir_all(&path).map_err(|e| IoError::io(&path, e))?;
        }
        let mut text = String::new();
        for (label, p) in [("P0", &calib.p0), ("P1", &calib.p1)] {
            let values: Vec<String> = (0..3)
                .flat_map(|r| (0..4).map(move |c| p[(r, c)].to_string()))
                .collect();
            let _ = writeln!(text, "{label}: {}", values.join(" "));
        }
        let path = dir.join("calib.txt");
        std::fs::write(&path, text).map_err(|e| IoError::io(&path, e))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            times: String::new(),
            frames: 0,
            last_timestamp: None,
        })
    }

    /// Writes the next frame's left and right images, taken at `timestamp` \[s\] (increasing).
    pub fn write_frame(
        &mut self,
        timestamp: f64,
        left: &GrayImage,
        right: &GrayImage,
    ) -> Result<(), IoError> {
        let index = self.frames;
        let increasing = self.last_timestamp.map_or(true, |last| timestamp > last);
        if !(timestamp.is_finite() && timestamp >= 0.0 && increasing) {
            let msg = format!("frame {index}: time stamps must be finite and increasing");
            return Err(IoError::invalid(self.dir.display(), msg));
        }
        if (left.width(), left.height()) != (right.width(), right.height()) {
            let msg = format!("frame {index}: left and right sizes differ");
            return Err(IoError::invalid(self.dir.display(), msg));
        }
        let name = format!("{index:06}.png");
        save_gray_png(&self.dir.join("image_0").join(&name), left)?;
        save_gray_png(&self.dir.join("image_1").join(&name), right)?;
        let _ = writeln!(self.times, "{timestamp:.6}");
        self.frames += 1;
        self.last_timestamp = Some(timestamp);
        Ok(())
    }

    /// Writes `times.txt` and `poses.txt` (the given `world_from_left` poses, one per frame,
    /// re-expressed relative to the first as KITTI does); returns the folder.
    pub fn finish(self, world_from_left: &Trajectory) -> Result<PathBuf, IoError> {
        if world_from_left.len() != self.frames || self.frames == 0 {
            let msg = format!("{} poses for {} frames", world_from_left.len(), self.frames);
            return Err(IoError::invalid(self.dir.display(), msg));
        }
        let path = self.dir.join("times.txt");
        std::fs::write(&path, &self.times).map_err(|e| IoError::io(&path, e))?;
        let mut relative = Trajectory::new();
        if let Some(first) = world_from_left.poses.first() {
            let first_inverse = first.pose.inverse();
            for p in &world_from_left.poses {
                relative.push(p.timestamp, first_inverse * p.pose);
            }
        }
        write_kitti(&self.dir.join("poses.txt"), &relative)?;
        Ok(self.dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kitti::open;
    use slamkit_core::image::Image;
    use slamkit_core::Pose3;

    #[test]
    fn the_reader_gives_back_what_was_written() {
        let dir = tempfile::tempdir().unwrap();
        let k = Intrinsics::from_array([517.306408, 516.469215, 318.64304, 255.313989], 5, 3);
        let calib = KittiCalib::rectified(&k, 0.12);
        let mut writer = KittiWriter::create(dir.path(), &calib).unwrap();
        let mut truth = Trajectory::new();
        let mut images = Vec::new();
        for i in 0..3u8 {
            let t = 0.1 * f64::from(i) + 5.0;
            let left = Image::from_vec(5, 3, (0..15).map(|p| p * 10 + i).collect()).unwrap();
            let right = left.map(|v| 255 - v);
            writer.write_frame(t, &left, &right).unwrap();
            let pose = Pose3::new(
                nalgebra::Vector3::new(f64::from(i), 2.0, 1.0),
                nalgebra::Vector3::new(0.0, 0.1 * f64::from(i), 0.0),
            );
            truth.push(t, pose);
            images.push((t, left, right));
        }
        writer.finish(&truth).unwrap();
        let seq = open(dir.path()).unwrap();
        assert_eq!(seq.left_camera.intrinsics, k);
        assert_eq!(seq.right_camera.intrinsics, k);
        assert_eq!(seq.baseline_m(), 0.12);
        assert!(seq.rectified);
        for (frame, (t, left, right)) in seq.frames.iter().zip(&images) {
            assert_eq!(frame.timestamp, *t);
            let loaded = seq.load(frame).unwrap();
            assert_eq!((&loaded.left, &loaded.right), (left, right));
        }
        let gt = seq.ground_truth.unwrap();
        let first = truth.poses[0].pose.inverse();
        for (read, made) in gt.poses.iter().zip(&truth.poses) {
            assert_eq!(read.timestamp, made.timestamp);
            let diff = (first * made.pose).inverse() * read.pose;
            assert!(diff.translation.vector.norm() < 1e-9 && diff.rotation.angle() < 1e-9);
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let k = Intrinsics::from_array([5.0, 5.0, 2.0, 1.0], 4, 2);
        assert!(KittiWriter::create(dir.path(), &KittiCalib::rectified(&k, 0.0)).is_err());
        let mut writer = KittiWriter::create(dir.path(), &KittiCalib::rectified(&k, 0.1)).unwrap();
        let image = Image::filled(4, 2, 9u8);
        writer.write_frame(1.0, &image, &image).unwrap();
        assert!(writer.write_frame(0.5, &image, &image).is_err());
        assert!(writer
            .write_frame(2.0, &image, &Image::filled(2, 2, 0))
            .is_err());
        assert!(writer.finish(&Trajectory::new()).is_err());
    }
}
