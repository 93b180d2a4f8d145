//! ORB descriptors are rotation invariant: features of a synthetic texture and of its copy
//! rotated by 90° and by 30° match to the right places.

#![allow(clippy::unwrap_used)] // test helpers fail loudly

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slamkit_vision::filter::gaussian_blur;
use slamkit_vision::matching::{match_descriptors, MatchConfig};
use slamkit_vision::orb::{Orb, OrbConfig, OrbFeatures};
use slamkit_vision::{GrayImage, Image};

const N: usize = 480;

/// Random discs and rectangles of random grey on a blurred-noise background.
fn texture(seed: u64) -> GrayImage {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise =
        Image::from_vec(N, N, (0..N * N).map(|_| rng.gen_range(60..196u8)).collect()).unwrap();
    let mut img = gaussian_blur(&noise, 9, 3.0).unwrap();
    for _ in 0..260 {
        let (cx, cy) = (rng.gen_range(0..N) as f32, rng.gen_range(0..N) as f32);
        let r = rng.gen_range(3.0..14.0f32);
        let v: u8 = rng.gen();
        let square = rng.gen_bool(0.5);
        for y in (cy - r).max(0.0) as usize..((cy + r) as usize).min(N) {
            for x in (cx - r).max(0.0) as usize..((cx + r) as usize).min(N) {
                let (dx, dy) = (x as f32 - cx, y as f32 - cy);
                if square || dx * dx + dy * dy <= r * r {
                    *img.get_mut(x, y).unwrap() = v;
                }
            }
        }
    }
    gaussian_blur(&img, 3, 0.8).unwrap()
}

/// Rotates about the image centre by `theta` (counter-clockwise on screen, y down), bilinear.
fn rotate(img: &GrayImage, theta: f32) -> GrayImage {
    let c = (N as f32 - 1.0) / 2.0;
    let (s, co) = theta.sin_cos();
    let mut out = Image::filled(N, N, 0u8);
    for y in 0..N {
        for x in 0..N {
            // inverse map: p = R⁻¹ (p' − c) + c
            let (dx, dy) = (x as f32 - c, y as f32 - c);
            let (sx, sy) = (co * dx + s * dy + c, -s * dx + co * dy + c);
            let (x0, y0) = (sx.floor(), sy.floor());
            if x0 < 0.0 || y0 < 0.0 || x0 as usize + 1 >= N || y0 as usize + 1 >= N {
                continue;
            }
            let (ax, ay) = (sx - x0, sy - y0);
            let p = |xx: usize, yy: usize| f32::from(*img.get(xx, yy).unwrap());
            let (x0, y0) = (x0 as usize, y0 as usize);
            let v = p(x0, y0) * (1.0 - ax) * (1.0 - ay)
                + p(x0 + 1, y0) * ax * (1.0 - ay)
                + p(x0, y0 + 1) * (1.0 - ax) * ay
                + p(x0 + 1, y0 + 1) * ax * ay;
            *out.get_mut(x, y).unwrap() = v.round() as u8;
        }
    }
    out
}

/// Where a point of the original lands in the rotated image.
fn rotate_point(x: f32, y: f32, theta: f32) -> (f32, f32) {
    let c = (N as f32 - 1.0) / 2.0;
    let (s, co) = theta.sin_cos();
    let (dx, dy) = (x - c, y - c);
    (co * dx - s * dy + c, s * dx + co * dy + c)
}

/// Fraction of cross-checked matches that land within 3 px (× level scale) of the truth.
fn correct_fraction(a: &OrbFeatures, b: &OrbFeatures, theta: f32) -> (f32, usize) {
    let m = match_descriptors(&a.descriptors, &b.descriptors, &MatchConfig::default());
    let good = m
        .iter()
        .filter(|mm| {
            let (ka, kb) = (a.keypoints[mm.query_idx], b.keypoints[mm.train_idx]);
            let (ex, ey) = rotate_point(ka.x, ka.y, theta);
            (ex - kb.x).hypot(ey - kb.y) <= 3.0 * 1.2f32.powi(ka.level as i32)
        })
        .count();
    (good as f32 / m.len().max(1) as f32, m.len())
}

#[test]
fn descriptors_are_rotation_invariant() {
    let img = texture(11);
    let orb = Orb::new(OrbConfig::default()).unwrap();
    let fa = orb.detect_and_compute(&img);
    assert!(fa.keypoints.len() > 400, "{} keypoints", fa.keypoints.len());
    for &deg in &[90.0f32, 30.0] {
        let theta = deg.to_radians();
        let rotated = rotate(&img, theta);
        let fb = orb.detect_and_compute(&rotated);
        let (frac, n) = correct_fraction(&fa, &fb, theta);
        eprintln!(
            "rotation {deg}°: {n} matches, {:.1} % correct",
            100.0 * frac
        );
        assert!(
            n >= 100 && frac >= 0.8,
            "rotation {deg}°: {n} matches, {frac} correct"
        );
    }
}

#[test]
fn orientation_follows_the_rotation() {
    let img = texture(12);
    let orb = Orb::new(OrbConfig::default()).unwrap();
    let theta = 90f32.to_radians();
    let (fa, fb) = (
        orb.detect_and_compute(&img),
        orb.detect_and_compute(&rotate(&img, theta)),
    );
    let m = match_descriptors(&fa.descriptors, &fb.descriptors, &MatchConfig::default());
    let mut diffs: Vec<f32> = m
        .iter()
        .map(|mm| {
            let d =
                fb.keypoints[mm.train_idx].angle_rad - fa.keypoints[mm.query_idx].angle_rad - theta;
            d.sin().atan2(d.cos()).abs()
        })
        .collect();
    diffs.sort_by(f32::total_cmp);
    let median = diffs[diffs.len() / 2];
    assert!(
        median < 3f32.to_radians(),
        "median orientation error {} deg",
        median.to_degrees()
    );
}
