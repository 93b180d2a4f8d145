use rand::{Rng, SeedableRng};
use slamkit_core::camera::Intrinsics;
use slamkit_core::image::{Image, RgbImage};

use super::*;
use crate::frame::{Preprocessor, Rig, SensorImages};

const W: usize = 160;
const H: usize = 120;

/// A random texture, smoothed so that it has corners.
fn texture(seed: u64) -> RgbImage {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let raw: Vec<f32> = (0..W * H).map(|_| rng.gen_range(0.0..255.0)).collect();
    let at = |x: usize, y: usize| raw[y.min(H - 1) * W + x.min(W - 1)];
    let data = (0..W * H)
        .map(|i| {
            let (x, y) = (i % W, i / W);
            let v = (4.0 * at(x, y) + at(x + 1, y) + at(x.saturating_sub(1), y))
                + at(x, y + 1)
                + at(x, y.saturating_sub(1));
            [(v / 8.0) as u8; 3]
        })
        .collect();
    Image::from_vec(W, H, data).unwrap()
}

/// The test images' camera.
fn camera() -> Intrinsics {
    Intrinsics {
        fx: 150.0,
        fy: 150.0,
        cx: 80.0,
        cy: 60.0,
        width: W,
        height: H,
    }
}

/// A KLT frame of an RGB-D camera whose left third has no depth.
fn klt_frame(config: &VoConfig) -> PreparedFrame {
    let k = camera();
    let mut pre = Preprocessor::new(config, Rig::Rgbd { color: k, depth: k }).unwrap();
    let depth = (0..W * H)
        .map(|i| if i % W < W / 3 { 0.0 } else { 1.5 })
        .collect();
    let images = SensorImages::Rgbd {
        color: texture(4),
        depth_m: Image::from_vec(W, H, depth).unwrap(),
    };
    pre.prepare(0, 0.0, images).unwrap()
}

#[test]
fn lazily_lifted_corners_are_those_lifted_up_front() {
    let config = VoConfig {
        max_features: 40,
        ..VoConfig::default()
    };
    let frame = klt_frame(&config);
    let corners = &frame.features.pixels;
    assert!(frame.features.points.is_empty() && corners.len() > 60);
    // features already in the reference, next to every 7th corner
    let kept: Vec<RefFeature> = corners
        .iter()
        .step_by(7)
        .map(|px| RefFeature {
            pixel: px + nalgebra::Vector2::new(3.0, -2.0),
            point: Point3::new(0.0, 0.0, 1.0),
            descriptor: None,
            landmark: None,
        })
        .collect();
    let odometry = Odometry::new(&config, Pose3::identity());
    let mut lazy = kept.clone();
    odometry.top_up_lazily(&frame, &mut lazy);
    let mut lifted = frame.clone();
    lifted.features.points = frame.lift(corners, &config).unwrap();
    let mut eager = kept.clone();
    odometry.top_up(&lifted, &mut eager, &[]);
    let summary = |f: &[RefFeature]| -> Vec<(Point2<f64>, Point3<f64>)> {
        f.iter().map(|r| (r.pixel, r.point)).collect()
    };
    assert_eq!(summary(&lazy), summary(&eager));
    assert_eq!(lazy.len(), 40);
    // corners without depth were passed over
    let without_depth = lifted
        .features
        .points
        .iter()
        .filter(|p| p.is_none())
        .count();
    assert!(without_depth > 5, "{without_depth} corners without depth");
}

/// Automatic CLAHE turns on at the first frame whose plain image lost its features to a
/// shadow, stays on while the light comes back until the plain image is looked at again
/// (`recheck_every`), and the two switch frames carry the other image's pyramid to be tracked
/// into.
#[test]
fn automatic_clahe_switches_on_a_shadow_and_back_with_hysteresis() {
    let k = camera();
    let rig = Rig::Rgbd { color: k, depth: k };
    let bright = texture(4);
    let mut shadow = bright.clone();
    for y in 0..H {
        for x in 0..(6 * W) / 10 {
            if let Some(v) = shadow.get_mut(x, y) {
                *v = v.map(|c| (f32::from(c) * 0.08).round() as u8);
            }
        }
    }
    let images = |color: &RgbImage| SensorImages::Rgbd {
        color: color.clone(),
        depth_m: Image::from_vec(W, H, vec![1.5f32; W * H]).unwrap(),
    };
    let plain = VoConfig::default();
    let mut pre = Preprocessor::new(&plain, rig.clone()).unwrap();
    let count = |pre: &mut Preprocessor, color: &RgbImage| {
        pre.prepare(0, 0.0, images(color))
            .unwrap()
            .features
            .pixels
            .len()
    };
    let (n_bright, n_shadow) = (count(&mut pre, &bright), count(&mut pre, &shadow));
    assert!(5 * n_shadow < 4 * n_bright, "{n_shadow} of {n_bright}");
    let config = VoConfig {
        auto_clahe: crate::AutoClaheConfig {
            on_below: n_shadow + (n_bright - n_shadow) / 3,
            off_at: n_shadow + 2 * (n_bright - n_shadow) / 3,
            recheck_every: 3,
        },
        ..VoConfig::default()
    };
    let mut pre = Preprocessor::new(&config, rig).unwrap();
    let seen: Vec<(bool, bool, usize)> = [&bright, &shadow, &shadow, &bright, &bright, &bright]
        .iter()
        .enumerate()
        .map(|(i, color)| {
            let f = pre.prepare(i, i as f64, images(color)).unwrap();
            (f.clahe, f.bridge.is_some(), f.features.pixels.len())
        })
        .collect();
    let switches: Vec<(bool, bool)> = seen.iter().map(|s| (s.0, s.1)).collect();
    assert_eq!(
        switches,
        [
            (false, false),
            (true, true),
            (true, false),
            (true, false),
            (false, true),
            (false, false)
        ],
        "{seen:?}"
    );
    // CLAHE gives the shadowed frame back features the plain image lost
    assert!(seen[1].2 > n_shadow, "{seen:?}, plain {n_shadow}");
    // a bad threshold pair is refused
    let bad = VoConfig {
        auto_clahe: crate::AutoClaheConfig {
            on_below: 100,
            off_at: 100,
            recheck_every: 3,
        },
        ..VoConfig::default()
    };
    assert!(bad.validate().is_err());
}
