//! Loading camera images (8-bit grayscale or RGB, 16-bit depth) from PNG or JPEG into
//! [`slamkit_core::image::Image`], through the `image` crate.
//!
//! Missing, truncated or corrupt files give an [`IoError`] naming the file; none panics.
//! JPEG is decoded by zune-jpeg (the decoder `image` uses) in strict mode: `image` runs it
//! lenient, which fills the rest of a truncated or corrupt scan with gray and reports
//! success, so a damaged frame would be tracked as if it were real.
//! Depth is kept raw (`u16`, the dataset's own unit) by [`load_depth`]; [`depth_to_metres`]
//! converts it with the dataset's scale (TUM 5000 units/m, 7-Scenes and Redwood 1000).

use std::path::Path;

use image::{DynamicImage, ImageFormat, ImageReader};
use slamkit_core::image::{DepthImage, GrayImage, Image, RgbImage};

use crate::error::IoError;

/// Loads an image as 8-bit grayscale; colour images are converted to luma
/// (ITU-R BT.709 weights, as the `image` crate does).
pub fn load_gray(path: &Path) -> Result<GrayImage, IoError> {
    let img = decode(path)?.into_luma8();
    let (w, h) = img.dimensions();
    wrap(path, w, h, img.into_raw())
}

/// Loads an image as 8-bit RGB; grayscale images get three equal channels.
pub fn load_rgb(path: &Path) -> Result<RgbImage, IoError> {
    let img = decode(path)?.into_rgb8();
    let (w, h) = img.dimensions();
    let pixels = img
        .into_raw()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    wrap(path, w, h, pixels)
}

/// Loads a 16-bit single-channel depth image, values as stored (no scaling).
///
/// Any other pixel type (8-bit, colour) is an error: converting it would silently give wrong
/// depths.
pub fn load_depth(path: &Path) -> Result<DepthImage, IoError> {
    match decode(path)? {
        DynamicImage::ImageLuma16(img) => {
            let (w, h) = img.dimensions();
            wrap(path, w, h, img.into_raw())
        }
        other => Err(IoError::Image {
            path: path.to_path_buf(),
            message: format!(
                "depth must be 16-bit single-channel, found {:?}",
                other.color()
            ),
        }),
    }
}

/// Converts raw depth to metres: `value / units_per_metre`. Raw 0 and any value listed in
/// `invalid` become 0.0, which means "no depth" everywhere in slamkit.
pub fn depth_to_metres(raw: &DepthImage, units_per_metre: f64, invalid: &[u16]) -> Image<f32> {
    raw.map(|&v| {
        if v == 0 || invalid.contains(&v) {
            0.0
        } else {
            (f64::from(v) / units_per_metre) as f32
        }
    })
}

/// Reads only the header of an image file: (width, height) \[px\].
pub fn image_size(path: &Path) -> Result<(usize, usize), IoError> {
    let reader = open(path)?;
    let (w, h) = reader.into_dimensions().map_err(|e| image_error(path, e))?;
    Ok((w as usize, h as usize))
}

fn open(path: &Path) -> Result<ImageReader<std::io::BufReader<std::fs::File>>, IoError> {
    ImageReader::open(path)
        .map_err(|e| IoError::io(path, e))?
        .with_guessed_format()
        .map_err(|e| IoError::io(path, e))
}

fn decode(path: &Path) -> Result<DynamicImage, IoError> {
    let reader = open(path)?;
    if reader.format() == Some(ImageFormat::Jpeg) {
        let bytes = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
        return decode_jpeg_strict(path, &bytes);
    }
    reader.decode().map_err(|e| image_error(path, e))
}

/// An image file's bytes (a ROS `CompressedImage`'s, say) decoded: PNG, or JPEG strictly (see
/// the module documentation), told by their content.
///
/// ```
/// let mut png = Vec::new();
/// image::GrayImage::from_raw(2, 1, vec![10, 20])
///     .unwrap()
///     .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
///     .unwrap();
/// let decoded = slamkit_io::image_io::decode_bytes(&png).unwrap();
/// assert_eq!(decoded.into_luma8().into_raw(), [10, 20]);
/// assert!(slamkit_io::image_io::decode_bytes(b"GIF89a").is_err());
/// ```
///
/// # Errors
/// Bytes that are neither a PNG nor a JPEG, or that do not decode.
pub fn decode_bytes(bytes: &[u8]) -> Result<DynamicImage, String> {
    match image::guess_format(bytes) {
        Ok(ImageFormat::Jpeg) => jpeg_strict(bytes),
        Ok(ImageFormat::Png) => image::load_from_memory_with_format(bytes, ImageFormat::Png)
            .map_err(|e| format!("PNG: {e}")),
        Ok(other) => Err(format!("{other:?} images are not read (PNG or JPEG)")),
        Err(_) => Err("neither a PNG nor a JPEG".into()),
    }
}

/// A JPEG decoded as 8-bit RGB, failing on a truncated or corrupt scan.
fn decode_jpeg_strict(path: &Path, bytes: &[u8]) -> Result<DynamicImage, IoError> {
    jpeg_strict(bytes).map_err(|message| IoError::Image {
        path: path.to_path_buf(),
        message,
    })
}

fn jpeg_strict(bytes: &[u8]) -> Result<DynamicImage, String> {
    use zune_core::{bytestream::ZCursor, colorspace::ColorSpace, options::DecoderOptions};
    let options = DecoderOptions::default()
        .set_strict_mode(true)
        .jpeg_set_out_colorspace(ColorSpace::RGB);
    let mut decoder = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    let failed = |message: String| format!("JPEG: {}", message.trim_matches('"'));
    let pixels = decoder.decode().map_err(|e| failed(e.to_string()))?;
    let (w, h) = decoder
        .dimensions()
        .ok_or_else(|| failed("no image size".into()))?;
    let (w, h) = (u32::try_from(w), u32::try_from(h));
    let (Ok(w), Ok(h)) = (w, h) else {
        return Err(failed("image too large".into()));
    };
    image::RgbImage::from_raw(w, h, pixels)
        .map(DynamicImage::ImageRgb8)
        .ok_or_else(|| failed("decoded buffer does not match the image size".into()))
}

fn image_error(path: &Path, e: image::ImageError) -> IoError {
    IoError::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

fn wrap<T>(path: &Path, w: u32, h: u32, data: Vec<T>) -> Result<Image<T>, IoError> {
    Image::from_vec(w as usize, h as usize, data).ok_or_else(|| IoError::Image {
        path: path.to_path_buf(),
        message: "decoded buffer does not match the image size".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_round_trip_and_conversion() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.png");
        let raw: Vec<u16> = vec![0, 5000, 10000, 65535, 1, 2];
        image::ImageBuffer::<image::Luma<u16>, _>::from_raw(3, 2, raw.clone())
            .unwrap()
            .save(&path)
            .unwrap();
        let depth = load_depth(&path).unwrap();
        assert_eq!((depth.width(), depth.height()), (3, 2));
        assert_eq!(depth.data(), &raw[..]);
        assert_eq!(image_size(&path).unwrap(), (3, 2));
        let m = depth_to_metres(&depth, 5000.0, &[65535]);
        assert_eq!(&m.data()[..4], &[0.0, 1.0, 2.0, 0.0]);
    }

    #[test]
    fn gray_and_rgb_load_and_convert() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.png");
        let rgb = vec![255u8, 0, 0, 0, 255, 0];
        image::RgbImage::from_raw(2, 1, rgb)
            .unwrap()
            .save(&path)
            .unwrap();
        let img = load_rgb(&path).unwrap();
        assert_eq!(img.get(1, 0), Some(&[0, 255, 0]));
        let gray = load_gray(&path).unwrap();
        assert!(gray.get(1, 0).unwrap() > gray.get(0, 0).unwrap());
        // An 8-bit image is not depth.
        assert!(matches!(load_depth(&path), Err(IoError::Image { .. })));
    }

    #[test]
    fn missing_and_corrupt_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("none.png");
        assert!(matches!(load_gray(&missing), Err(IoError::Io { .. })));
        let corrupt = dir.path().join("bad.png");
        std::fs::write(&corrupt, b"\x89PNG\r\n\x1a\n garbage").unwrap();
        let err = load_rgb(&corrupt).unwrap_err();
        assert!(err.to_string().contains("bad.png"), "{err}");
        let text = dir.path().join("text.png");
        std::fs::write(&text, b"hello").unwrap();
        assert!(load_depth(&text).is_err());
        assert!(image_size(&text).is_err());
    }
}
