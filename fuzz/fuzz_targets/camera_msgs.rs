//! The camera messages of a bag or a live topic on arbitrary bytes: never panics. The input is
//! decoded as a `sensor_msgs/Image`, `CameraInfo` and `CompressedImage` in both wires (ROS 1
//! and CDR), and what decodes is turned into what a visual session takes (colour, depth in
//! metres, the camera); the bytes are also handed straight to the compressed-image decoders
//! (JPEG, PNG, `compressedDepth`) under each format a driver writes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::bag::camera_image::CameraImage;
use slamkit_io::bag::messages::{
    CameraInfoMsg, CompressedImageMsg, Header, ImageMsg, RosMessage,
};
use slamkit_io::bag::record::RosTime;
use slamkit_io::bag::rgbd::camera_of;

/// Decodes `image` both ways; what is accepted must be well-formed.
fn check(image: &CameraImage) {
    let _ = image.encoding();
    let size = image.size();
    if let Ok(c) = image.colour() {
        assert_eq!(c.data().len(), c.width() * c.height());
    }
    if let Ok(d) = image.depth() {
        assert!(d.data().iter().all(|v| v.is_finite() && *v >= 0.0));
        if let Ok((w, h)) = size {
            assert_eq!((d.width(), d.height()), (w as usize, h as usize));
        }
    }
}

fuzz_target!(|data: &[u8]| {
    for image in [ImageMsg::decode(data), ImageMsg::decode_cdr(data)] {
        if let Ok(m) = image {
            check(&CameraImage::Raw(m));
        }
    }
    for image in [
        CompressedImageMsg::decode(data),
        CompressedImageMsg::decode_cdr(data),
    ] {
        if let Ok(m) = image {
            check(&CameraImage::Compressed(m));
        }
    }
    for info in [CameraInfoMsg::decode(data), CameraInfoMsg::decode_cdr(data)] {
        if let Ok(info) = info {
            for size in [None, Some((640, 480))] {
                if let Ok(camera) = camera_of(&info, size) {
                    let k = camera.intrinsics;
                    assert!(k.fx.is_finite() && k.fx > 0.0 && k.fy.is_finite() && k.fy > 0.0);
                }
            }
        }
    }
    let header = Header {
        seq: None,
        stamp: RosTime { sec: 1, nsec: 0 },
        frame_id: "camera_color_optical_frame".into(),
    };
    for format in [
        "jpeg",
        "png",
        "bgr8; jpeg compressed bgr8",
        "16UC1; compressedDepth png",
        "32FC1; compressedDepth png",
    ] {
        check(&CameraImage::Compressed(CompressedImageMsg {
            header: header.clone(),
            format: format.into(),
            data: data.to_vec(),
        }));
    }
});
