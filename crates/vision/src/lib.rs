//! slamkit-vision: the image kernels of a visual-odometry front end, in pure safe Rust.
//!
//! Images are [`slamkit_core::image::Image`]s: 8-bit grey (`GrayImage`) or RGB, pixel (x, y) at
//! column x (right) and row y (down), pixel centres at integer coordinates (OpenCV's
//! convention). Every kernel works on row slices with fixed-point or `f32` arithmetic, sized for
//! a 30 Hz camera on a small CPU; where OpenCV defines the result (colour conversions, CLAHE,
//! `pyrDown`, Sobel/Scharr, min-eigenvalue corners, ORB's pattern), slamkit reproduces it.
//!
//! * [`color`]: RGB → grey (BT.601), RGB ↔ 8-bit CIELAB.
//! * [`filter`]: Gaussian blur, Sobel and Scharr gradients.
//! * [`pyramid`]: `pyrDown` pyramids and bilinear resize.
//! * [`clahe`]: contrast-limited adaptive histogram equalisation (Zuiderveld 1994).
//! * [`corners`]: Shi–Tomasi corners with grid bucketing (Shi & Tomasi 1994).
//! * [`klt`]: pyramidal Lucas–Kanade tracking (Bouguet 2001) with a forward–backward check.
//! * [`fast`], [`orb`], [`matching`]: FAST-9 (Rosten & Drummond 2006), ORB (Rublee et al.
//!   2011) and Hamming descriptor matching.
//! * [`stereo`]: sparse ZNCC stereo matching along epipolar lines with sub-pixel disparity and
//!   a per-point confidence.
//! * [`error`]: [`VisionError`], bad configuration or images that do not fit together.

mod border;
pub mod clahe;
pub mod color;
pub mod corners;
pub mod error;
pub mod fast;
pub mod filter;
pub mod klt;
pub mod matching;
pub mod orb;
mod orb_pattern;
pub mod pyramid;
mod round;
mod simd;
pub mod stereo;
#[cfg(test)]
mod test_images;

pub use clahe::{Clahe, ClaheConfig};
pub use corners::{shi_tomasi, Corner, ShiTomasiConfig};
pub use error::VisionError;
pub use klt::{KltConfig, KltPyramid, Track};
pub use matching::{match_descriptors, match_within_by, DescriptorMatch, MatchConfig};
pub use orb::{Descriptor, Keypoint, Orb, OrbConfig, OrbFeatures};
pub use slamkit_core::image::{GrayImage, Image, RgbImage};
pub use stereo::{StereoConfig, StereoMatch, StereoPair};
