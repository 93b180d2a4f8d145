//! Issue 25 (10): real images under `$SLAMKIT_DATA` (a 7-Scenes RedKitchen JPEG, a KITTI 06
//! PNG, a 7-Scenes 16-bit depth PNG), truncated or with bytes overwritten in a temporary copy,
//! fail to load with the decoder's message on one line, naming the file; none decodes
//! silently into garbage. Overwritten bytes are caught in PNG (every chunk has a CRC), not in
//! JPEG: the format has no checksum, and 64 bytes of 0xA5 in the RedKitchen frame's scan decode
//! as valid (wrong) pixels, so JPEG is checked on truncation only.

use std::path::Path;

use slamkit_io::image_io::{load_depth, load_gray, load_rgb};
use slamkit_io::IoError;

/// Copies of `bytes`: cut at 50 % and at 90 %, and with `overwrite` also one with 64 bytes at
/// 40 % overwritten.
fn damaged(bytes: &[u8], overwrite: bool) -> Vec<(&'static str, Vec<u8>)> {
    let mut copies = vec![
        ("cut at 50 %", bytes[..bytes.len() / 2].to_vec()),
        ("cut at 90 %", bytes[..bytes.len() * 9 / 10].to_vec()),
    ];
    if overwrite {
        let mut overwritten = bytes.to_vec();
        let at = bytes.len() * 4 / 10;
        overwritten[at..at + 64].fill(0xA5);
        copies.push(("overwritten", overwritten));
    }
    copies
}

fn check<T>(original: &Path, overwrite: bool, load: impl Fn(&Path) -> Result<T, IoError>) {
    assert!(load(original).is_ok());
    let tmp = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(original).unwrap();
    for (what, bytes) in damaged(&bytes, overwrite) {
        let path = tmp.path().join(original.file_name().unwrap());
        std::fs::write(&path, bytes).unwrap();
        let err = match load(&path) {
            Ok(_) => panic!("{}: {what}: decoded", original.display()),
            Err(e) => e,
        };
        assert!(matches!(err, IoError::Image { .. }), "{what}: {err:?}");
        let msg = err.to_string();
        assert!(
            msg.starts_with(&format!("{}: image: ", path.display())),
            "{what}: {msg}"
        );
        assert!(
            !msg.contains('\n') && !msg.contains("Os {"),
            "{what}: {msg}"
        );
    }
}

#[test]
fn damaged_real_images_fail_with_the_decoders_message() {
    let test = "damaged_real_images_fail_with_the_decoders_message";
    let Some(data) = slamkit_testdata::data(test, "") else {
        return;
    };
    let kitchen = data.join("rgbd/7scenes_redkitchen_frames_0000-0599");
    check(&kitchen.join("frame-000100.color.jpg"), false, load_rgb);
    check(&kitchen.join("frame-000100.color.jpg"), false, load_gray);
    check(&kitchen.join("frame-000100.depth.png"), true, load_depth);
    let kitti = data.join("stereo/kitti_odometry_06_0000-0050/image_0/000010.png");
    check(&kitti, true, load_gray);
}

/// The strict JPEG path gives the same pixels as the `image` crate on intact real frames
/// (7-Scenes RedKitchen and Redwood colour).
#[test]
fn strict_jpeg_decoding_matches_image_crate_on_intact_frames() {
    let test = "strict_jpeg_decoding_matches_image_crate_on_intact_frames";
    let Some(data) = slamkit_testdata::data(test, "rgbd") else {
        return;
    };
    for rel in [
        "7scenes_redkitchen_frames_0000-0599/frame-000000.color.jpg",
        "7scenes_redkitchen_frames_0000-0599/frame-000599.color.jpg",
        "open3d_testdata_redwood_5frames/color/00003.jpg",
    ] {
        let path = data.join(rel);
        let ours = load_rgb(&path).unwrap();
        let theirs = image::open(&path).unwrap().into_rgb8();
        assert_eq!(ours.width(), theirs.width() as usize);
        let theirs: Vec<[u8; 3]> = theirs.pixels().map(|p| p.0).collect();
        assert!(ours.data() == &theirs[..], "{rel}");
    }
}
