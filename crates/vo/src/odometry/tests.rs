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

/// ORB frame to frame across a scale change: a textured wall 2 m ahead, then 0.6 m nearer,
/// so every point is seen 1.43 times larger (two levels at `scale_factor` 1.2) and the image
/// moves up to 90 px at the border; the second frame has no motion to predict from. With the
/// features described on coarser levels (`local_map.scale_levels`) the motion is found; on
/// level 0 alone it is not.
#[test]
fn orb_frame_to_frame_matches_across_a_scale_change() {
    let (w, h) = (320usize, 240usize);
    let k = Intrinsics {
        fx: 300.0,
        fy: 300.0,
        cx: 160.0,
        cy: 120.0,
        width: w,
        height: h,
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
    let raw: Vec<f32> = (0..(w / 4 + 2) * (h / 4 + 2))
        .map(|_| rng.gen_range(0.0..255.0))
        .collect();
    // blobs about 4 px across: the raw grid bilinearly interpolated
    let wall = |x: f64, y: f64| {
        let (gx, gy) = (
            (x / 4.0).clamp(0.0, (w / 4) as f64),
            (y / 4.0).clamp(0.0, (h / 4) as f64),
        );
        let (x0, y0) = (gx.floor(), gy.floor());
        let (fx, fy) = ((gx - x0) as f32, (gy - y0) as f32);
        let at = |dx: usize, dy: usize| raw[(y0 as usize + dy) * (w / 4 + 2) + x0 as usize + dx];
        (at(0, 0) * (1.0 - fx) + at(1, 0) * fx) * (1.0 - fy)
            + (at(0, 1) * (1.0 - fx) + at(1, 1) * fx) * fy
    };
    // the wall seen from depth `z`, its texture fixed to the view from 2 m
    let view = |z: f64| {
        let s = 2.0 / z;
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                [wall((x - k.cx) / s + k.cx, (y - k.cy) / s + k.cy) as u8; 3]
            })
            .collect();
        SensorImages::Rgbd {
            color: Image::from_vec(w, h, data).unwrap(),
            depth_m: Image::from_vec(w, h, vec![z as f32; w * h]).unwrap(),
        }
    };
    let run = |scale_levels: usize| {
        let mut config = VoConfig {
            frontend: FrontendKind::Orb,
            mode: TrackingMode::FrameToFrame,
            ..VoConfig::default()
        };
        config.orb.n_levels = 1;
        config.orb.n_features = 1000;
        config.local_map.scale_levels = scale_levels;
        let mut pre = Preprocessor::new(&config, Rig::Rgbd { color: k, depth: k }).unwrap();
        let mut odometry = Odometry::new(&config, Pose3::identity());
        let first = odometry.track(pre.prepare(0, 0.0, view(2.0)).unwrap());
        assert!(
            matches!(first, FrameStatus::Initialised { .. }),
            "{first:?}"
        );
        let status = odometry.track(pre.prepare(1, 0.1, view(1.4)).unwrap());
        (status, odometry.pose().translation.vector)
    };
    let (status, t) = run(3);
    let FrameStatus::Tracked { inliers, .. } = status else {
        panic!("{status:?}");
    };
    assert!(inliers >= 30, "{status:?}");
    assert!(
        (t - nalgebra::Vector3::new(0.0, 0.0, 0.6)).norm() < 0.02,
        "{t:?}"
    );
    let (status, t) = run(0);
    assert!(
        !matches!(status, FrameStatus::Tracked { .. })
            || (t - nalgebra::Vector3::new(0.0, 0.0, 0.6)).norm() > 0.1,
        "{status:?} {t:?}"
    );
}
