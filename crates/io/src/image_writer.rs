//! Writing camera images as PNG (8-bit grey, 8-bit RGB, 16-bit depth) through the `image`
//! crate, the inverse of [`crate::image_io`]: what is written loads back pixel for pixel.
//!
//! PNG encoding is deterministic (fixed compression settings, no time stamp chunk), so the same
//! image always gives the same bytes.

use std::path::Path;

use image::{ExtendedColorType, ImageEncoder};
use slamkit_core::image::{GrayImage, Image, RgbImage};

use crate::error::IoError;

/// Writes an 8-bit grayscale PNG.
pub fn save_gray_png(path: &Path, image: &GrayImage) -> Result<(), IoError> {
    encode(path, image, image.data(), ExtendedColorType::L8)
}

/// Writes an 8-bit RGB PNG.
pub fn save_rgb_png(path: &Path, image: &RgbImage) -> Result<(), IoError> {
    let bytes: Vec<u8> = image.data().iter().flatten().copied().collect();
    encode(path, image, &bytes, ExtendedColorType::Rgb8)
}

/// Writes depth in metres as a 16-bit PNG of `round(depth · units_per_metre)` (TUM: 5000);
/// 0.0 (no depth), negative and non-finite values are written as 0.
///
/// A depth too large for 16 bits is an error naming the pixel.
pub fn save_depth_png(
    path: &Path,
    depth_m: &Image<f32>,
    units_per_metre: f64,
) -> Result<(), IoError> {
    let max = f64::from(u16::MAX);
    let mut bytes = Vec::with_capacity(depth_m.data().len() * 2);
    for (i, &z) in depth_m.data().iter().enumerate() {
        let units = f64::from(z) * units_per_metre;
        let raw = if units.is_finite() && units > 0.0 {
            let rounded = units.round();
            if rounded > max {
                let (x, y) = (i % depth_m.width(), i / depth_m.width());
                let msg = format!("depth {z} m at pixel ({x}, {y}) does not fit 16 bits");
                return Err(IoError::invalid(path.display(), msg));
            }
            rounded as u16
        } else {
            0
        };
        // the `image` crate takes 16-bit samples in native byte order and writes PNG big-endian
        bytes.extend_from_slice(&raw.to_ne_bytes());
    }
    encode(path, depth_m, &bytes, ExtendedColorType::L16)
}

fn encode<T>(
    path: &Path,
    image: &Image<T>,
    bytes: &[u8],
    color: ExtendedColorType,
) -> Result<(), IoError> {
    let size = |n: usize| {
        u32::try_from(n).map_err(|_| IoError::invalid(path.display(), "image too large"))
    };
    let (w, h) = (size(image.width())?, size(image.height())?);
    let file = std::fs::File::create(path).map_err(|e| IoError::io(path, e))?;
    let writer = std::io::BufWriter::new(file);
    image::codecs::png::PngEncoder::new(writer)
        .write_image(bytes, w, h, color)
        .map_err(|e| IoError::Image {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image_io::{depth_to_metres, load_depth, load_gray, load_rgb};

    #[test]
    fn images_load_back_pixel_for_pixel() {
        let dir = tempfile::tempdir().unwrap();
        let gray = Image::from_vec(3, 2, vec![0u8, 1, 2, 127, 254, 255]).unwrap();
        let path = dir.path().join("g.png");
        save_gray_png(&path, &gray).unwrap();
        assert_eq!(load_gray(&path).unwrap(), gray);
        let rgb = gray.map(|&v| [v, 255 - v, v / 2]);
        let path = dir.path().join("c.png");
        save_rgb_png(&path, &rgb).unwrap();
        assert_eq!(load_rgb(&path).unwrap(), rgb);
        let depth = Image::from_vec(3, 1, vec![0.0f32, 1.2346, 13.0]).unwrap();
        let path = dir.path().join("d.png");
        save_depth_png(&path, &depth, 5000.0).unwrap();
        let raw = load_depth(&path).unwrap();
        assert_eq!(raw.data(), &[0, 6173, 65000]);
        assert_eq!(depth_to_metres(&raw, 5000.0, &[]), depth);
    }

    #[test]
    fn bad_depths_are_holes_or_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.png");
        let odd = Image::from_vec(3, 1, vec![f32::NAN, -1.0, f32::INFINITY]).unwrap();
        save_depth_png(&path, &odd, 5000.0).unwrap();
        assert_eq!(load_depth(&path).unwrap().data(), &[0, 0, 0]);
        let far = Image::from_vec(2, 1, vec![1.0f32, 14.0]).unwrap();
        let err = save_depth_png(&path, &far, 5000.0).unwrap_err().to_string();
        assert!(err.contains("pixel (1, 0)"), "{err}");
    }
}
