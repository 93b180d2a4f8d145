use super::*;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn camera() -> StereoCamera {
    StereoCamera {
        k: kinect(),
        bf: 585.0 * 0.075,
    }
}

fn kinect() -> Intrinsics {
    Intrinsics {
        fx: 585.0,
        fy: 585.0,
        cx: 320.0,
        cy: 240.0,
        width: 640,
        height: 480,
    }
}

/// `n` features 1–5 m in front of the camera, seen after `truth`; the first `good` with
/// 0.3 px pixel noise and 1 % depth noise, the rest moved to random pixels and depths.
fn scene(seed: u64, truth: &Pose3, n: usize, good: usize) -> Vec<Correspondence> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let k = kinect();
    (0..n)
        .map(|i| {
            let u = Point2::new(rng.gen_range(0.0..640.0), rng.gen_range(0.0..480.0));
            let z: f64 = rng.gen_range(1.0..5.0);
            let reference = Point3::new((u.x - k.cx) / k.fx * z, (u.y - k.cy) / k.fy * z, z);
            let mut current = truth * reference;
            let mut px = Point2::new(
                k.fx * current.x / current.z + k.cx,
                k.fy * current.y / current.z + k.cy,
            );
            if i < good {
                px += Vector2::new(rng.gen_range(-0.3..0.3), rng.gen_range(-0.3..0.3));
                current.coords *= 1.0 + rng.gen_range(-0.01..0.01);
            } else {
                px = Point2::new(rng.gen_range(0.0..640.0), rng.gen_range(0.0..480.0));
                let z = rng.gen_range(1.0..5.0);
                current = Point3::new((px.x - k.cx) / k.fx * z, (px.y - k.cy) / k.fy * z, z);
            }
            Correspondence {
                reference,
                current,
                current_px: px,
            }
        })
        .collect()
}

fn motion() -> Pose3 {
    Pose3::new(
        Vector3::new(0.05, -0.02, 0.10),
        Vector3::new(0.02, -0.03, 0.01),
    )
}

#[test]
fn recovers_synthetic_motion_with_outliers() {
    let truth = motion();
    let data = scene(7, &truth, 300, 180);
    let est = estimate_motion(&data, &camera(), &MotionConfig::default()).unwrap();
    let err = truth.inverse() * est.current_from_reference;
    assert!(err.translation.vector.norm() < 2e-3, "{err}");
    assert!(err.rotation.angle() < 1e-3, "{err}");
    let wrong = est.inliers.iter().filter(|&&i| i >= 180).count();
    assert!(
        est.inliers.len() >= 170 && wrong <= 3,
        "{} inliers, {wrong} wrong",
        est.inliers.len()
    );
}

#[test]
fn refinement_lowers_reprojection_error() {
    let truth = motion();
    let data = scene(8, &truth, 200, 200);
    let all: Vec<usize> = (0..200).collect();
    let start = fit_horn(&data, &all).unwrap();
    let config = MotionConfig::default();
    let refined = refine(&data, &all, &camera(), start, &config);
    let before = rms(&data, &all, &kinect(), &start);
    let after = rms(&data, &all, &kinect(), &refined);
    assert!(after < before, "{after} vs {before}");
    let err = truth.inverse() * refined;
    assert!(err.translation.vector.norm() < 2e-3, "{err}");
}

/// Zero-mean noise of standard deviation `sigma` (uniform, so bounded).
fn noise(rng: &mut ChaCha8Rng, sigma: f64) -> f64 {
    rng.gen_range(-1.0..1.0) * sigma * 3f64.sqrt()
}

/// `n` features 0.6–4.5 m in front of a Kinect, seen after `truth`, with the sensor's
/// noise in both frames: 0.3 px in the pixels, Nguyen et al.'s σ_z(z) in the depths.
fn kinect_scene(seed: u64, truth: &Pose3, n: usize) -> Vec<Correspondence> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (k, sensor) = (kinect(), MeasurementNoise::default());
    let observe = |rng: &mut ChaCha8Rng, p: Point3<f64>| {
        let px = Point2::new(
            k.fx * p.x / p.z + k.cx + noise(rng, 0.3),
            k.fy * p.y / p.z + k.cy + noise(rng, 0.3),
        );
        let z = p.z + noise(rng, sensor.depth_sigma_m(p.z, 0.0));
        (px, crate::depth::lift(&k, px, z))
    };
    (0..n)
        .map(|_| {
            let u = Point2::new(rng.gen_range(0.0..640.0), rng.gen_range(0.0..480.0));
            let z: f64 = rng.gen_range(0.6..4.5);
            let p = crate::depth::lift(&k, u, z);
            let (_, reference) = observe(&mut rng, p);
            let (current_px, current) = observe(&mut rng, truth * p);
            Correspondence {
                reference,
                current,
                current_px,
            }
        })
        .collect()
}

#[test]
fn weighting_by_depth_noise_beats_equal_weights() {
    let truth = motion();
    let weighted = MotionConfig {
        noise: MeasurementNoise {
            pixel_sigma_px: 0.3,
            ..MeasurementNoise::default()
        },
        ..MotionConfig::default()
    };
    let equal = MotionConfig {
        weight_by_noise: false,
        ..MotionConfig::default()
    };
    // summed translation [m] and rotation [rad] errors over 20 scenes
    let (mut weighted_err, mut equal_err) = ([0.0; 2], [0.0; 2]);
    for seed in 0..20 {
        let data = kinect_scene(seed, &truth, 150);
        let all: Vec<usize> = (0..data.len()).collect();
        let start = fit_horn(&data, &all).unwrap();
        for (config, sum) in [(&weighted, &mut weighted_err), (&equal, &mut equal_err)] {
            let err = truth.inverse() * refine(&data, &all, &camera(), start, config);
            sum[0] += err.translation.vector.norm();
            sum[1] += err.rotation.angle();
        }
    }
    eprintln!("summed errors: weighted {weighted_err:?}, equal weights {equal_err:?}");
    assert!(
        weighted_err[0] < 0.9 * equal_err[0],
        "{weighted_err:?} vs {equal_err:?}"
    );
    assert!(
        weighted_err[1] < 1.02 * equal_err[1],
        "{weighted_err:?} vs {equal_err:?}"
    );
}

#[test]
fn too_few_inliers_fail() {
    let data = scene(9, &motion(), 100, 4);
    let got = estimate_motion(&data, &camera(), &MotionConfig::default());
    assert!(
        matches!(got, Err(MotionFailure::TooFewInliers { .. })),
        "{got:?}"
    );
    let got = estimate_motion(&data[..4], &camera(), &MotionConfig::default());
    assert_eq!(got, Err(MotionFailure::TooFewCorrespondences { got: 4 }));
}

#[test]
fn config_ranges_are_checked() {
    assert!(MotionConfig::default().validate().is_ok());
    let bad = MotionConfig {
        min_inliers: 3,
        ..Default::default()
    };
    assert!(bad.validate().is_err());
}
