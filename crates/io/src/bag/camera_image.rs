//! A camera image as a ROS topic carries it: a raw `sensor_msgs/Image`, or a
//! `sensor_msgs/CompressedImage` as `image_transport` writes them (JPEG or PNG colour, PNG depth,
//! and the `compressedDepth` plugin's PNG behind a 12-byte header), decoded into the colour and
//! depth images a visual session takes.
//!
//! A compressed image's `format` names the encoding it was made from (`rgb8; jpeg compressed
//! bgr8`, `16UC1; compressedDepth png`); a bare `jpeg` is colour, and a bare `png` is depth in
//! millimetres when it holds 16-bit grey pixels, colour otherwise. `compressedDepth` of `32FC1`
//! stores quantised inverse depth, `depth = A / (v − B)` with the header's `A`, `B`; of `16UC1`,
//! the millimetres as they are.

use super::messages::{CompressedImageMsg, Header, ImageMsg, RosMessage};
use super::rgbd::{colour_image, depth_image};
use super::{connection::Connection, messages::is_type};
use crate::image_io::{decode_bytes, depth_to_metres};
use image::DynamicImage;
use slamkit_core::image::{Image, RgbImage};

/// Bytes before the PNG of a `compressedDepth` image: the format (i32) and the two
/// quantisation parameters (f32).
const DEPTH_HEADER: usize = 12;

/// A raw or a compressed camera image message.
#[derive(Debug, Clone, PartialEq)]
pub enum CameraImage {
    /// `sensor_msgs/Image`.
    Raw(ImageMsg),
    /// `sensor_msgs/CompressedImage`.
    Compressed(CompressedImageMsg),
}

impl CameraImage {
    /// The message on `conn` when it is an image of either kind, `None` for another type.
    ///
    /// # Errors
    /// An image message that does not decode.
    pub fn decode_from(conn: &Connection, bytes: &[u8]) -> Result<Option<Self>, String> {
        let decoded = if is_type::<ImageMsg>(conn) {
            ImageMsg::decode_from(conn, bytes).map(Self::Raw)
        } else if is_type::<CompressedImageMsg>(conn) {
            CompressedImageMsg::decode_from(conn, bytes).map(Self::Compressed)
        } else {
            return Ok(None);
        };
        decoded.map(Some).map_err(|e| e.to_string())
    }

    /// Whether `conn` carries images of either kind.
    pub fn is_image(conn: &Connection) -> bool {
        is_type::<ImageMsg>(conn) || is_type::<CompressedImageMsg>(conn)
    }

    /// The message's header.
    pub fn header(&self) -> &Header {
        match self {
            Self::Raw(m) => &m.header,
            Self::Compressed(m) => &m.header,
        }
    }

    /// The encoding the image stands for (see the module documentation): a raw image's own,
    /// a compressed one's original, told from its format and, for a bare PNG, its header.
    ///
    /// ```
    /// use slamkit_io::bag::camera_image::CameraImage;
    /// use slamkit_io::bag::messages::{CompressedImageMsg, Header};
    /// use slamkit_io::bag::record::RosTime;
    /// let header = Header { seq: None, stamp: RosTime { sec: 1, nsec: 0 }, frame_id: "cam".into() };
    /// let jpeg = |format: &str| CameraImage::Compressed(CompressedImageMsg {
    ///     header: header.clone(), format: format.into(), data: vec![] });
    /// assert_eq!(jpeg("bgr8; jpeg compressed bgr8").encoding().unwrap(), "bgr8");
    /// assert_eq!(jpeg("16UC1; compressedDepth png").encoding().unwrap(), "16UC1");
    /// assert_eq!(jpeg("jpeg").encoding().unwrap(), "rgb8");
    /// assert!(jpeg("tiff").encoding().is_err());
    /// ```
    ///
    /// # Errors
    /// A format that is neither JPEG nor PNG, or a bare PNG whose header does not read.
    pub fn encoding(&self) -> Result<String, String> {
        let m = match self {
            Self::Raw(m) => return Ok(m.encoding.clone()),
            Self::Compressed(m) => m,
        };
        let format = m.format.to_ascii_lowercase();
        if !(format.contains("jpeg") || format.contains("jpg") || format.contains("png")) {
            return Err(format!(
                "compressed format {:?} is not JPEG or PNG",
                m.format
            ));
        }
        if let Some((original, _)) = m.format.split_once(';') {
            return Ok(original.trim().to_string());
        }
        if format.contains("png") {
            let grey16 = matches!(
                png_header(&m.data)?,
                image::ColorType::L16 | image::ColorType::La16
            );
            return Ok(if grey16 { "16UC1" } else { "rgb8" }.into());
        }
        Ok("rgb8".into())
    }

    /// As colour (RGB; grey as three equal channels).
    ///
    /// # Errors
    /// An encoding that is not colour, or an image that does not decode.
    pub fn colour(&self) -> Result<RgbImage, String> {
        match self {
            Self::Raw(m) => colour_image(m),
            Self::Compressed(m) => {
                let img = decode_bytes(&m.data)?;
                if matches!(img.color(), image::ColorType::L16 | image::ColorType::La16) {
                    return Err("a 16-bit grey PNG is depth, not colour".into());
                }
                let rgb = img.into_rgb8();
                let (w, h) = (rgb.width() as usize, rgb.height() as usize);
                let pixels = rgb.into_raw();
                let pixels = pixels.chunks_exact(3).map(|p| [p[0], p[1], p[2]]);
                Image::from_vec(w, h, pixels.collect()).ok_or_else(size_error)
            }
        }
    }

    /// As depth in metres, 0.0 where there is none.
    ///
    /// # Errors
    /// An encoding that is not depth, or an image that does not decode.
    pub fn depth(&self) -> Result<Image<f32>, String> {
        let m = match self {
            Self::Raw(m) => return depth_image(m),
            Self::Compressed(m) => m,
        };
        let encoding = self.encoding()?;
        let png = if m.format.contains("compressedDepth") {
            m.data
                .get(DEPTH_HEADER..)
                .ok_or("compressedDepth image shorter than its header")?
        } else {
            &m.data
        };
        let DynamicImage::ImageLuma16(raw) = decode_bytes(png)? else {
            return Err(format!("{:?}: depth must be a 16-bit grey PNG", m.format));
        };
        let (w, h) = (raw.width() as usize, raw.height() as usize);
        let raw = Image::from_vec(w, h, raw.into_raw()).ok_or_else(size_error)?;
        match encoding.as_str() {
            "16UC1" | "mono16" => Ok(depth_to_metres(&raw, 1000.0, &[])),
            "32FC1" if m.format.contains("compressedDepth") => {
                let f = |i: usize| {
                    let b = [m.data[i], m.data[i + 1], m.data[i + 2], m.data[i + 3]];
                    f32::from_le_bytes(b)
                };
                let (a, b) = (f(4), f(8));
                Ok(raw.map(|&v| {
                    let d = a / (f32::from(v) - b);
                    if v != 0 && d.is_finite() && d > 0.0 {
                        d
                    } else {
                        0.0
                    }
                }))
            }
            other => Err(format!("{other} is not a depth encoding")),
        }
    }

    /// Width and height \[px\], from the header of a compressed image.
    ///
    /// # Errors
    /// A compressed image whose header does not read.
    pub fn size(&self) -> Result<(u32, u32), String> {
        match self {
            Self::Raw(m) => Ok((m.width, m.height)),
            Self::Compressed(m) => {
                let data = if m.format.contains("compressedDepth") {
                    m.data.get(DEPTH_HEADER..).unwrap_or_default()
                } else {
                    &m.data
                };
                image::ImageReader::new(std::io::Cursor::new(data))
                    .with_guessed_format()
                    .map_err(|e| e.to_string())?
                    .into_dimensions()
                    .map_err(|e| e.to_string())
            }
        }
    }
}

fn size_error() -> String {
    "image size does not match its pixels".into()
}

/// The colour type a PNG's header declares.
fn png_header(data: &[u8]) -> Result<image::ColorType, String> {
    use image::ImageDecoder;
    let decoder = image::codecs::png::PngDecoder::new(std::io::Cursor::new(data))
        .map_err(|e| format!("PNG: {e}"))?;
    Ok(decoder.color_type())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bag::record::RosTime;

    fn compressed(format: &str, data: Vec<u8>) -> CameraImage {
        CameraImage::Compressed(CompressedImageMsg {
            header: Header {
                seq: None,
                stamp: RosTime { sec: 1, nsec: 0 },
                frame_id: "cam".into(),
            },
            format: format.into(),
            data,
        })
    }

    fn png<P: image::PixelWithColorType>(img: image::ImageBuffer<P, Vec<P::Subpixel>>) -> Vec<u8>
    where
        [P::Subpixel]: image::EncodableLayout,
    {
        let mut out = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
            .unwrap();
        out
    }

    #[test]
    fn compressed_colour_and_depth_decode() {
        let rgb = png(image::RgbImage::from_raw(2, 1, vec![1, 2, 3, 4, 5, 6]).unwrap());
        let c = compressed("bgr8; png compressed bgr8", rgb)
            .colour()
            .unwrap();
        assert_eq!(
            (c.get(0, 0), c.get(1, 0)),
            (Some(&[1, 2, 3]), Some(&[4, 5, 6]))
        );
        let mm = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(2, 1, vec![1500, 0]).unwrap();
        let bare = compressed("png", png(mm.clone()));
        assert_eq!(bare.encoding().unwrap(), "16UC1");
        assert_eq!(bare.size().unwrap(), (2, 1));
        let d = bare.depth().unwrap();
        assert_eq!((d.get(0, 0), d.get(1, 0)), (Some(&1.5), Some(&0.0)));
        assert!(bare.colour().unwrap_err().contains("is depth"));
        // compressedDepth of 32FC1: v = A / d + B, here A = 1000, B = 100: 2 m is 600
        let mut data = vec![0u8; 4];
        data.extend(1000f32.to_le_bytes());
        data.extend(100f32.to_le_bytes());
        let quantised =
            image::ImageBuffer::<image::Luma<u16>, _>::from_raw(2, 1, vec![600, 0]).unwrap();
        data.extend(png(quantised));
        let d = compressed("32FC1; compressedDepth png", data)
            .depth()
            .unwrap();
        assert_eq!((d.get(0, 0), d.get(1, 0)), (Some(&2.0), Some(&0.0)));
        let short = compressed("16UC1; compressedDepth png", vec![1, 2]);
        assert!(short
            .depth()
            .unwrap_err()
            .contains("shorter than its header"));
        let garbage = compressed("jpeg", vec![0xff, 0xd8, 0xff, 0, 1]);
        assert!(garbage.colour().unwrap_err().starts_with("JPEG"));
    }
}
