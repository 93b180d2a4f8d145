//! Deterministic test images shared by the kernels' unit tests.

use slamkit_core::image::{GrayImage, Image};

/// A `w × h` image of hashed grey levels (Knuth's multiplicative hash of the pixel index, top
/// byte): full-range, uncorrelated neighbours, the same on every run.
pub(crate) fn hashed(w: usize, h: usize) -> GrayImage {
    let data = (0..(w * h) as u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
        .collect();
    match Image::from_vec(w, h, data) {
        Some(img) => img,
        None => unreachable!("w*h pixels"),
    }
}
