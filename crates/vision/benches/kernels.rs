//! Criterion benchmarks of the image kernels on a 640×480 frame: the real 7-Scenes frame 0 when
//! `SLAMKIT_DATA` is set, else a seeded synthetic texture of the same size.

// A benchmark has no error path to report through: a broken fixture should stop it loudly.
#![allow(clippy::expect_used, missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slamkit_vision::{
    clahe::{Clahe, ClaheConfig},
    color::rgb_to_gray,
    corners::{shi_tomasi, ShiTomasiConfig},
    fast::fast9,
    filter::{gaussian_blur, scharr, sobel},
    klt::{track, KltConfig, KltPyramid},
    orb::{Orb, OrbConfig},
    pyramid::{pyr_down, resize_bilinear, Pyramid},
    GrayImage, Image, RgbImage,
};

fn frame() -> RgbImage {
    if let Ok(root) = std::env::var("SLAMKIT_DATA") {
        let p = std::path::Path::new(&root)
            .join("rgbd/7scenes_redkitchen_frames_0000-0599/frame-000000.color.jpg");
        if let Ok(img) = slamkit_io::image_io::load_rgb(&p) {
            return img;
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let noise: Vec<[u8; 3]> = (0..640 * 480)
        .map(|_| [rng.gen(), rng.gen(), rng.gen()])
        .collect();
    let img = Image::from_vec(640, 480, noise).expect("640x480");
    // smooth the noise so that it has corners of a useful scale
    let g = gaussian_blur(&rgb_to_gray(&img), 9, 2.0).expect("odd ksize");
    g.map(|&v| [v, v, v])
}

fn shifted(img: &GrayImage, dx: usize, dy: usize) -> GrayImage {
    let (w, h) = (img.width(), img.height());
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w).saturating_sub(dx), (i / w).saturating_sub(dy));
            img.data()[y * w + x]
        })
        .collect();
    Image::from_vec(w, h, data).expect("same size")
}

fn kernels(c: &mut Criterion) {
    let rgb = frame();
    let gray = rgb_to_gray(&rgb);
    c.bench_function("vision/rgb_to_gray_640x480", |b| {
        b.iter(|| rgb_to_gray(&rgb))
    });
    c.bench_function("vision/gaussian_7x7_640x480", |b| {
        b.iter(|| gaussian_blur(&gray, 7, 2.0))
    });
    c.bench_function("vision/sobel_640x480", |b| b.iter(|| sobel(&gray)));
    c.bench_function("vision/scharr_640x480", |b| b.iter(|| scharr(&gray)));
    c.bench_function("vision/pyr_down_640x480", |b| b.iter(|| pyr_down(&gray)));
    c.bench_function("vision/resize_1.2_640x480", |b| {
        b.iter(|| resize_bilinear(&gray, 533, 400))
    });
    c.bench_function("vision/fast9_nms_640x480", |b| {
        b.iter(|| fast9(&gray, 20, 31, true))
    });
    let orb = Orb::new(OrbConfig::default()).expect("default config");
    c.bench_function("vision/orb_500_640x480", |b| {
        b.iter(|| orb.detect_and_compute(&gray))
    });
    c.bench_function("vision/pyramid_4_levels", |b| {
        b.iter(|| Pyramid::new(&gray, 3))
    });
    let mut clahe = Clahe::new(ClaheConfig::default()).expect("default config");
    c.bench_function("vision/clahe_gray_640x480", |b| {
        b.iter(|| clahe.apply_gray(&gray))
    });
    c.bench_function("vision/clahe_rgb_640x480", |b| {
        b.iter(|| clahe.apply_rgb(&rgb))
    });
    let st = ShiTomasiConfig::default();
    c.bench_function("vision/shi_tomasi_640x480", |b| {
        b.iter(|| shi_tomasi(&gray, &st))
    });
    let corners = shi_tomasi(&gray, &st).expect("valid config");
    let pts: Vec<(f32, f32)> = corners.iter().map(|c| (c.x, c.y)).collect();
    let next = shifted(&gray, 2, 1);
    let cfg = KltConfig::default();
    c.bench_function("vision/klt_pyramid_640x480", |b| {
        b.iter(|| KltPyramid::new(&gray, 3))
    });
    let (pa, pb) = (KltPyramid::new(&gray, 3), KltPyramid::new(&next, 3));
    c.bench_function(&format!("vision/klt_track_fb_{}_points", pts.len()), |b| {
        b.iter(|| track(&pa, &pb, &pts, &cfg))
    });
}

criterion_group!(benches, kernels);
criterion_main!(benches);
