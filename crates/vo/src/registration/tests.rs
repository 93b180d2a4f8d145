use rand::{Rng, SeedableRng};
use slamkit_io::{Dataset, DatasetFormat};

use super::*;
use crate::depth::depth_at;

/// A 40 × 30 depth camera.
fn k() -> Intrinsics {
    Intrinsics::from_array([100.0, 100.0, 20.0, 15.0], 40, 30)
}

/// The whole image warped with the arithmetic of [`RegisteredDepth::project`] (the pipeline's
/// former full warp), before gap filling.
fn full_warp_unfilled(depth: &Image<f32>, dk: &Intrinsics, reg: &DepthRegistration) -> Vec<f32> {
    let (w, h) = (depth.width(), depth.height());
    let sparse = RegisteredDepth::new(depth.clone(), dk, reg);
    let mut out = vec![f32::INFINITY; w * h];
    for y in 0..h {
        for x in 0..w {
            let d = *depth.get(x, y).unwrap();
            if let Some((u, v, z)) = sparse.project(sparse.columns[x], sparse.rows[y], d) {
                out[v * w + u] = out[v * w + u].min(z);
            }
        }
    }
    out
}

/// The textbook forward warp, pixel by pixel with `f64::round`, before gap filling.
fn warp_reference(depth: &Image<f32>, dk: &Intrinsics, reg: &DepthRegistration) -> Vec<f32> {
    let (w, h) = (depth.width(), depth.height());
    let ck = reg.color_camera(w, h);
    let t = nalgebra::Vector3::from(reg.color_from_depth_m);
    let mut out = vec![f32::INFINITY; w * h];
    for y in 0..h {
        for x in 0..w {
            let z = f64::from(*depth.get(x, y).unwrap());
            if z <= 0.0 {
                continue;
            }
            let p = nalgebra::Vector3::new(
                (x as f64 - dk.cx) / dk.fx * z,
                (y as f64 - dk.cy) / dk.fy * z,
                z,
            ) + t;
            let u = (ck.fx * p.x / p.z + ck.cx).round();
            let v = (ck.fy * p.y / p.z + ck.cy).round();
            if p.z > 0.0 && u >= 0.0 && v >= 0.0 && u < w as f64 && v < h as f64 {
                let o = &mut out[v as usize * w + u as usize];
                *o = o.min(p.z as f32);
            }
        }
    }
    out
}

/// Gap filling with every decision on a copy of the unfilled image; empty pixels become 0.
fn fill_reference(z: &[f32], w: usize) -> Vec<f32> {
    let h = z.len() / w;
    let mut out = z.to_vec();
    for y in 1..h.saturating_sub(1) {
        for x in 1..w - 1 {
            let i = y * w + x;
            if z[i].is_finite() {
                continue;
            }
            for (a, b) in [(z[i - 1], z[i + 1]), (z[i - w], z[i + w])] {
                if a.is_finite() && b.is_finite() && (a - b).abs() <= 0.05 * a.min(b) {
                    out[i] = a.min(b);
                    break;
                }
            }
        }
    }
    out.iter()
        .map(|&v| if v.is_finite() { v } else { 0.0 })
        .collect()
}

/// The fully warped and filled image, as the pipeline used to build it for every frame.
fn full_warp(depth: &Image<f32>, dk: &Intrinsics, reg: &DepthRegistration) -> Image<f32> {
    let filled = fill_reference(&full_warp_unfilled(depth, dk, reg), depth.width());
    Image::from_vec(depth.width(), depth.height(), filled).unwrap()
}

/// Checks that the lookup equals `depth_at` in the full warp at every pixel and at `extra`
/// off-grid positions; returns how many pixels have a depth.
fn assert_same_as_full_warp(
    depth: &Image<f32>,
    dk: &Intrinsics,
    reg: &DepthRegistration,
    extra: &[Point2<f64>],
) -> usize {
    let config = DepthConfig {
        min_depth_m: 0.0,
        max_depth_m: 100.0,
        ..DepthConfig::default()
    };
    let full = full_warp(depth, dk, reg);
    let sparse = RegisteredDepth::new(depth.clone(), dk, reg);
    let grid = (0..depth.height())
        .flat_map(|y| (0..depth.width()).map(move |x| Point2::new(x as f64, y as f64)));
    let mut with_depth = 0;
    for px in grid.chain(extra.iter().copied()) {
        let want = depth_at(&full, px, &config);
        assert_eq!(sparse.depth_at(px, &config), want, "at {px}");
        with_depth += usize::from(want.is_some());
    }
    with_depth
}

/// Piecewise-planar depth with steps and holes, so that depth edges, occlusions in the warp,
/// cracks and smooth regions all occur.
fn scene(w: usize, h: usize, seed: u64) -> Image<f32> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            if rng.gen_bool(0.05) || y == 7.0 {
                0.0 // holes, and one row without any depth
            } else if x > 0.4 * w as f32 && x < 0.6 * w as f32 && y > 0.3 * h as f32 {
                0.6 + 0.002 * y // a near box: occludes what lies to one side of it
            } else {
                2.0 + 0.01 * x - 0.005 * y
            }
        })
        .collect();
    Image::from_vec(w, h, data).unwrap()
}

#[test]
fn full_warp_matches_the_textbook_formula() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let data = (0..40 * 30)
        .map(|_| {
            if rng.gen_bool(0.1) {
                0.0
            } else {
                rng.gen_range(0.4f32..5.0)
            }
        })
        .collect();
    let depth = Image::from_vec(40, 30, data).unwrap();
    let reg = DepthRegistration {
        color_intrinsics: [97.3, 101.1, 19.7, 15.2],
        color_from_depth_m: [-0.025, 0.01, 0.003],
    };
    assert_eq!(
        full_warp_unfilled(&depth, &k(), &reg),
        warp_reference(&depth, &k(), &reg)
    );
}

#[test]
fn a_plane_moves_by_the_baseline() {
    let depth = Image::filled(40, 30, 2.0f32);
    let reg = DepthRegistration {
        color_intrinsics: [100.0, 100.0, 20.0, 15.0],
        color_from_depth_m: [-0.2, 0.0, 0.0],
    };
    let sparse = RegisteredDepth::new(depth, &k(), &reg);
    let c = DepthConfig::default();
    // a shift of −0.2 m at 2 m is −10 px: the right 10 columns receive nothing
    assert_eq!(sparse.depth_at(Point2::new(10.0, 10.0), &c), Some(2.0));
    // depth column 39 lands on colour column 29, the last one with depth
    assert_eq!(sparse.depth_at(Point2::new(29.0, 10.0), &c), Some(2.0));
    assert_eq!(sparse.depth_at(Point2::new(30.0, 10.0), &c), None);
    assert_eq!(sparse.depth_at(Point2::new(35.0, 10.0), &c), None);
    let zero = RegisteredDepth::new(Image::filled(40, 30, 0.0f32), &k(), &reg);
    assert_eq!(zero.depth_at(Point2::new(10.0, 10.0), &c), None);
    assert!(zero
        .samples(1, &Image::filled(40, 30, [0; 3]), &c)
        .0
        .is_empty());
}

#[test]
fn lookups_equal_the_full_warp_on_synthetic_scenes() {
    let regs = [
        // 7-Scenes-like: colour focal length below the depth camera's (minifying warp)
        ([88.0, 88.0, 19.5, 14.5], [-0.025, 0.0, 0.0]),
        // magnifying (cracks to fill), vertical and forward offsets
        ([115.0, 112.0, 20.5, 15.5], [0.04, -0.02, 0.01]),
        // colour camera behind the depth camera, far off: many pixels land outside
        ([100.0, 100.0, 20.0, 15.0], [-0.3, 0.1, -0.5]),
    ];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let extra: Vec<Point2<f64>> = (0..500)
        .map(|_| Point2::new(rng.gen_range(-2.0..42.0), rng.gen_range(-2.0..32.0)))
        .chain([Point2::new(f64::NAN, 3.0), Point2::new(5.0, f64::INFINITY)])
        .collect();
    for (seed, (color, t)) in regs.into_iter().enumerate() {
        let reg = DepthRegistration {
            color_intrinsics: color,
            color_from_depth_m: t,
        };
        let with_depth = assert_same_as_full_warp(&scene(40, 30, seed as u64), &k(), &reg, &extra);
        assert!(with_depth > 300, "only {with_depth} pixels with depth");
    }
}

#[test]
fn lookups_equal_the_full_warp_on_real_frames() {
    let Some(dir) = slamkit_testdata::data(
        "lookups_equal_the_full_warp_on_real_frames",
        "rgbd/7scenes_redkitchen_frames_0000-0599",
    ) else {
        return;
    };
    let Dataset::Rgbd(seq) = Dataset::open(&dir, DatasetFormat::SevenScenes).unwrap() else {
        panic!("7-Scenes is RGB-D");
    };
    let reg = DepthRegistration::default();
    for index in [0, 299, 599] {
        let frame = seq.load(&seq.frames[index]).unwrap();
        let dk = seq.depth_camera.intrinsics;
        let with_depth = assert_same_as_full_warp(&frame.depth_m, &dk, &reg, &[]);
        eprintln!("frame {index}: {with_depth} pixels with depth");
        assert!(with_depth > 200_000);
    }
}

#[test]
fn samples_are_depth_pixels_moved_into_the_colour_camera() {
    let depth = Image::filled(40, 30, 2.0f32);
    let reg = DepthRegistration {
        color_intrinsics: [50.0, 50.0, 20.0, 15.0],
        color_from_depth_m: [-0.2, 0.0, 0.0],
    };
    let c = DepthConfig::default();
    // colour image: each pixel's colour is its coordinates
    let color = Image::from_vec(
        40,
        30,
        (0..40 * 30)
            .map(|i| [(i % 40) as u8, (i / 40) as u8, 0])
            .collect(),
    )
    .unwrap();
    let (points, colors) = RegisteredDepth::new(depth, &k(), &reg).samples(4, &color, &c);
    // depth pixel (24, 16) at 2 m: (0.08, 0.02) m in the depth camera, (−0.12, 0.02) m in the
    // colour camera, seen at (50 · −0.12 / 2 + 20, 50 · 0.02 / 2 + 15) = (17, 15.5) px
    let i = points
        .iter()
        .position(|p| (p.x + 0.12).abs() < 1e-9 && (p.y - 0.02).abs() < 1e-9)
        .unwrap();
    assert_eq!(colors[i], [17, 16, 0]);
    assert!((points[i].z - 2.0).abs() < 1e-12);
    // 10 × 8 grid pixels, all inside the colour image (the colour camera is wider)
    assert_eq!((points.len(), colors.len()), (80, 80));
}
