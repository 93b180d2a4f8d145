//! Writing TUM RGB-D benchmark folders (Sturm et al., IROS 2012), the layout
//! [`crate::tum_rgbd`] reads: `rgb/T.png` (8-bit colour), `depth/T.png` (16-bit, 5000 units per
//! metre, registered to colour), `rgb.txt` and `depth.txt` (`timestamp path` lines after the
//! benchmark's three `#` header lines), `groundtruth.txt` (`t tx ty tz qx qy qz qw` of the colour
//! camera) and `associations.txt`, the output of the benchmark's `associate.py rgb.txt
//! depth.txt` (`t_rgb rgb/T.png t_depth depth/T.png`).
//!
//! Time stamps are written with 6 decimals (microseconds, as the benchmark names its files), so
//! times that are whole microseconds read back exactly.
//!
//! The TUM reader chooses the calibration from the folder name (`freiburg1`/`fr1` …): name the
//! folder after the camera whose intrinsics the images were made with.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use slamkit_core::image::{Image, RgbImage};
use slamkit_core::Trajectory;

use crate::error::IoError;
use crate::image_writer::{save_depth_png, save_rgb_png};
use crate::trajectory_file::write_tum;

/// Writes a TUM RGB-D folder frame by frame (images go to disk at once, so a long sequence
/// never sits in memory); [`TumRgbdWriter::finish`] writes the lists and the ground truth.
#[derive(Debug)]
pub struct TumRgbdWriter {
    dir: PathBuf,
    depth_units_per_metre: f64,
    rgb_list: String,
    depth_list: String,
    associations: String,
    last_timestamp: Option<f64>,
}

impl TumRgbdWriter {
    /// Creates `dir` with its `rgb/` and `depth/` folders; depth will be written at
    /// `depth_units_per_metre` (TUM: 5000).
    pub fn create(dir: &Path, depth_units_per_metre: f64) -> Result<Self, IoError> {
        if !(depth_units_per_metre.is_finite() && depth_units_per_metre > 0.0) {
            let msg = format!("depth scale {depth_units_per_metre} is not positive");
            return Err(IoError::invalid(dir.display(), msg));
        }
        for sub in ["rgb", "depth"] {
            let path = dir.join(sub);
            std::fs::create_dir_all(&path).map_err(|e| IoError::io(&path, e))?;
        }
        let header =
            |what: &str| format!("# {what} images\n# file: 'slamkit sim'\n# timestamp filename\n");
        Ok(Self {
            dir: dir.to_path_buf(),
            depth_units_per_metre,
            rgb_list: header("color"),
            depth_list: header("depth"),
            associations: String::new(),
            last_timestamp: None,
        })
    }

    /// Writes one frame's colour and depth \[m\] (0.0 = no depth) images, both taken at
    /// `timestamp` \[s\]. Time stamps must increase.
    pub fn write_frame(
        &mut self,
        timestamp: f64,
        color: &RgbImage,
        depth_m: &Image<f32>,
    ) -> Result<(), IoError> {
        let name = format!("{timestamp:.6}");
        let increasing = self.last_timestamp.map_or(true, |last| timestamp > last);
        if !(timestamp.is_finite() && timestamp >= 0.0 && increasing) {
            let msg = format!("frame at {name} s: time stamps must be finite and increasing");
            return Err(IoError::invalid(self.dir.display(), msg));
        }
        let (w, h) = (color.width(), color.height());
        if (depth_m.width(), depth_m.height()) != (w, h) {
            let msg = format!("frame at {name} s: depth size differs from colour {w}x{h}");
            return Err(IoError::invalid(self.dir.display(), msg));
        }
        let (rgb, depth) = (format!("rgb/{name}.png"), format!("depth/{name}.png"));
        save_rgb_png(&self.dir.join(&rgb), color)?;
        save_depth_png(&self.dir.join(&depth), depth_m, self.depth_units_per_metre)?;
        let _ = writeln!(self.rgb_list, "{name} {rgb}");
        let _ = writeln!(self.depth_list, "{name} {depth}");
        let _ = writeln!(self.associations, "{name} {rgb} {name} {depth}");
        self.last_timestamp = Some(timestamp);
        Ok(())
    }

    /// Writes `rgb.txt`, `depth.txt`, `associations.txt` and `groundtruth.txt`
    /// (`world_from_camera` of the colour camera); returns the folder.
    pub fn finish(self, ground_truth: &Trajectory) -> Result<PathBuf, IoError> {
        if self.last_timestamp.is_none() {
            return Err(IoError::invalid(self.dir.display(), "no frame written"));
        }
        for (file, text) in [
            ("rgb.txt", &self.rgb_list),
            ("depth.txt", &self.depth_list),
            ("associations.txt", &self.associations),
        ] {
            let path = self.dir.join(file);
            std::fs::write(&path, text).map_err(|e| IoError::io(&path, e))?;
        }
        write_tum(&self.dir.join("groundtruth.txt"), ground_truth)?;
        Ok(self.dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tum_rgbd::{open, TumCamera, TumRgbdConfig};
    use slamkit_core::camera::{Distortion, Intrinsics, PinholeCamera};
    use slamkit_core::Pose3;

    #[test]
    fn the_reader_gives_back_what_was_written() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("seq");
        let mut writer = TumRgbdWriter::create(&root, 5000.0).unwrap();
        let mut truth = Trajectory::new();
        let mut frames = Vec::new();
        for i in 0..3u8 {
            let t = 0.033333 * f64::from(i);
            let color = Image::from_vec(4, 2, (0..8).map(|p| [p * i, 7, 200]).collect()).unwrap();
            let depth = Image::from_vec(4, 2, (0..8u8).map(|p| f32::from(p) * 0.5).collect());
            let depth = depth.unwrap();
            writer.write_frame(t, &color, &depth).unwrap();
            truth.push(t, Pose3::translation(f64::from(i), 0.5, -1.0));
            frames.push((t, color, depth));
        }
        writer.finish(&truth).unwrap();
        let k = PinholeCamera::new(
            Intrinsics::from_array([5.0, 5.0, 2.0, 1.0], 4, 2),
            Distortion::default(),
        );
        let config = TumRgbdConfig {
            camera: TumCamera::Given(k),
            ..TumRgbdConfig::default()
        };
        let seq = open(&root, &config).unwrap();
        assert_eq!(seq.frames.len(), 3);
        for (frame, (t, color, depth)) in seq.frames.iter().zip(&frames) {
            assert_eq!(frame.timestamp, *t);
            let images = seq.load(frame).unwrap();
            assert_eq!(&images.color, color);
            assert_eq!(&images.depth_m, depth);
        }
        let gt = seq.ground_truth.unwrap();
        assert_eq!(gt.len(), 3);
        assert!(gt.max_difference(&truth).unwrap() < 1e-9);
        let assoc = std::fs::read_to_string(root.join("associations.txt")).unwrap();
        assert_eq!(
            assoc.lines().nth(1),
            Some("0.033333 rgb/0.033333.png 0.033333 depth/0.033333.png")
        );
    }

    #[test]
    fn bad_frames_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let mut writer = TumRgbdWriter::create(dir.path(), 5000.0).unwrap();
        let color = Image::filled(2, 2, [0u8; 3]);
        let depth = Image::filled(2, 2, 1.0f32);
        writer.write_frame(1.0, &color, &depth).unwrap();
        assert!(writer.write_frame(1.0, &color, &depth).is_err());
        assert!(writer.write_frame(f64::NAN, &color, &depth).is_err());
        let small = Image::filled(1, 2, 1.0f32);
        assert!(writer.write_frame(2.0, &color, &small).is_err());
        assert!(TumRgbdWriter::create(dir.path(), 0.0).is_err());
        let empty = TumRgbdWriter::create(&dir.path().join("e"), 5000.0).unwrap();
        assert!(empty.finish(&Trajectory::new()).is_err());
    }
}
