use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A random-texture left image, smoothed horizontally so that sub-pixel shifts are defined,
/// and the right image shifted left by `disparity` px (linear interpolation).
fn pair(disparity: f32) -> (GrayImage, GrayImage) {
    let (w, h) = (160, 60);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let raw: Vec<f32> = (0..w * h).map(|_| rng.gen_range(0.0..255.0)).collect();
    let smooth = |x: f32, y: usize| {
        let x0 = x.floor().clamp(0.0, (w - 2) as f32);
        let t = x - x0;
        let x0 = x0 as usize;
        let at = |xx: usize| {
            (raw[y * w + xx.saturating_sub(1)]
                + 2.0 * raw[y * w + xx]
                + raw[y * w + (xx + 1).min(w - 1)])
                / 4.0
        };
        at(x0) * (1.0 - t) + at(x0 + 1) * t
    };
    let left = (0..w * h)
        .map(|i| smooth((i % w) as f32, i / w) as u8)
        .collect();
    let right = (0..w * h)
        .map(|i| smooth((i % w) as f32 + disparity, i / w) as u8)
        .collect();
    (
        GrayImage::from_vec(w, h, left).unwrap(),
        GrayImage::from_vec(w, h, right).unwrap(),
    )
}

#[test]
fn recovers_sub_pixel_disparity() {
    for truth in [7.0f32, 12.25, 20.5] {
        let (l, r) = pair(truth);
        let pairing = StereoPair::new(l.clone(), r.clone()).unwrap();
        // sub-pixel positions: the disparity must not follow the rounding of x
        let pts: Vec<(f32, f32)> = (0..10)
            .map(|i| (60.4 + 8.0 * i as f32 - 0.1 * i as f32, 30.0))
            .collect();
        let got = pairing
            .match_points(&pts, &StereoConfig::default())
            .unwrap();
        for m in &got {
            let m = m.expect("textured point matched");
            assert!(
                (m.disparity_px - truth).abs() < 0.3,
                "{} vs {truth}",
                m.disparity_px
            );
            assert!(m.confidence > 0.8, "{}", m.confidence);
        }
    }
}

/// On pairs of known disparity (odd, fractional, up to 61.5 px) the coarse-to-fine search
/// returns exactly what the exhaustive one returns, near the truth.
#[test]
fn coarse_to_fine_equals_exhaustive_on_known_disparities() {
    let fine = StereoConfig::default();
    assert_eq!(fine.search, DisparitySearch::CoarseToFine);
    let exhaustive = StereoConfig {
        search: DisparitySearch::Exhaustive,
        ..fine.clone()
    };
    for truth in [3.0f32, 7.0, 12.25, 20.5, 33.0, 45.75, 61.5] {
        let (l, r) = pair(truth);
        let pairing = StereoPair::new(l.clone(), r.clone()).unwrap();
        let pts: Vec<(f32, f32)> = (0..40)
            .map(|i| (75.0 + 2.1 * i as f32, 10.0 + i as f32))
            .collect();
        let a = pairing.match_points(&pts, &fine).unwrap();
        let b = pairing.match_points(&pts, &exhaustive).unwrap();
        assert_eq!(a, b, "disparity {truth}");
        let matched: Vec<f32> = a.iter().flatten().map(|m| m.disparity_px).collect();
        assert!(matched.len() >= 36, "{truth}: {} of 40", matched.len());
        assert!(
            matched.iter().all(|d| (d - truth).abs() < 0.3),
            "{matched:?}"
        );
    }
}

#[test]
fn half_box_averages_blocks() {
    let img = GrayImage::from_vec(5, 3, (0..15).map(|v| v * 10).collect()).unwrap();
    // blocks (0,1 | 5,6) and (2,3 | 7,8); the odd column and row are dropped
    assert_eq!(half_box(&img).data(), &[30, 50]);
    assert_eq!(half_box(&img).height(), 1);
}

/// The padded integer ZNCC equals the textbook formula in f64.
#[test]
fn zncc_matches_the_definition() {
    let (l, r) = pair(9.5);
    let pairing = StereoPair::new(l.clone(), r.clone()).unwrap();
    let rad = 9;
    let mut patch = Patch::with_side(2 * rad + 1);
    let window = |img: &GrayImage, x: usize, y: usize| -> Vec<f64> {
        (y - rad..=y + rad)
            .flat_map(|yy| (x - rad..=x + rad).map(move |xx| (xx, yy)))
            .map(|(xx, yy)| f64::from(*img.get(xx, yy).unwrap()))
            .collect()
    };
    for (x, y, d) in [(60, 30, 9), (70, 20, 3), (150, 50, 40), (40, 9, 30)] {
        left_patch(&l, x, y, rad, &mut patch, 0.0).unwrap();
        let got = pairing.right.zncc(&patch, x - d, y, rad);
        let (a, b) = (window(&l, x, y), window(&r, x - d, y));
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (ma, mb) = (mean(&a), mean(&b));
        let cov: f64 = a.iter().zip(&b).map(|(p, q)| (p - ma) * (q - mb)).sum();
        let var = |v: &[f64], m: f64| v.iter().map(|p| (p - m).powi(2)).sum::<f64>();
        let want = cov / (var(&a, ma) * var(&b, mb)).sqrt();
        assert!((f64::from(got) - want).abs() < 1e-3, "{got} vs {want}");
    }
}

#[test]
fn flat_and_repetitive_windows_get_no_disparity() {
    let flat = GrayImage::filled(80, 40, 100u8);
    let pairing = StereoPair::new(flat.clone(), flat.clone()).unwrap();
    let got = pairing
        .match_points(&[(40.0, 20.0)], &StereoConfig::default())
        .unwrap();
    assert_eq!(got, vec![None]);
    // vertical stripes of period 4 px: every fourth disparity fits equally well
    let stripes = GrayImage::from_vec(
        80,
        40,
        (0..3200)
            .map(|i| if i % 4 < 2 { 40 } else { 200 })
            .collect(),
    )
    .unwrap();
    let pairing = StereoPair::new(stripes.clone(), stripes.clone()).unwrap();
    let got = pairing
        .match_points(&[(60.0, 20.0)], &StereoConfig::default())
        .unwrap();
    assert_eq!(got, vec![None]);
}

#[test]
fn bad_input_is_an_error_or_none() {
    let a = GrayImage::filled(80, 40, 0u8);
    let b = GrayImage::filled(81, 40, 0u8);
    assert!(StereoPair::new(a.clone(), b.clone()).is_err());
    let pairing = StereoPair::new(a.clone(), a.clone()).unwrap();
    let bad = StereoConfig {
        min_disparity_px: 10,
        max_disparity_px: 5,
        ..Default::default()
    };
    assert!(pairing.match_points(&[(40.0, 20.0)], &bad).is_err());
    for bad in [
        StereoConfig {
            half_window_px: 65,
            ..Default::default()
        },
        StereoConfig {
            coarse_peaks: 0,
            ..Default::default()
        },
    ] {
        assert!(pairing.match_points(&[(40.0, 20.0)], &bad).is_err());
    }
    let got = pairing
        .match_points(
            &[(f32::NAN, 1.0), (-5.0, 3.0), (2.0, 20.0)],
            &StereoConfig::default(),
        )
        .unwrap();
    assert_eq!(got, vec![None, None, None]);
}

/// The AVX2 builds of the window ZNCC and of the coarse run equal the portable ones, bit for bit.
#[test]
fn zncc_builds_agree() {
    let (l, r) = pair(7.25);
    let pairing = StereoPair::new(l.clone(), r.clone()).unwrap();
    let rad = 5;
    let mut patch = Patch::with_side(2 * rad + 1);
    for (x, y, d) in [(60, 30, 9), (70, 20, 3), (150, 50, 40), (40, 9, 30)] {
        left_patch(&l, x, y, rad, &mut patch, 0.0).unwrap();
        let a = zncc_window(&pairing.right, &patch, x - d, y, rad);
        let b = zncc_window_portable(&pairing.right, &patch, x - d, y, rad);
        assert_eq!(a.to_bits(), b.to_bits(), "({x}, {y}) d {d}");
    }
    let coarse = CoarsePair::new(&l, &r);
    let rc = 3;
    let mut patch = Patch::with_side(2 * rc + 1);
    left_patch(&coarse.left, 40, 15, rc, &mut patch, 0.0).unwrap();
    let (mut d1, mut o1, mut d2, mut o2) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    zncc_run_lanes(&coarse, &patch, (10, 15), rc, 30, (&mut d1, &mut o1));
    zncc_run_lanes_portable(&coarse, &patch, (10, 15), rc, 30, (&mut d2, &mut o2));
    assert_eq!(o1.len(), 30);
    assert!(o1.iter().zip(&o2).all(|(a, b)| a.to_bits() == b.to_bits()));
}
