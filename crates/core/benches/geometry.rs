//! Benchmarks of the geometry hot paths: absolute orientation on 100 matches (one call per
//! trajectory alignment or RANSAC refit) and RANSAC motion estimation on a VO-sized match set.

use criterion::Criterion;
use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slamkit_core::{
    horn, ransac, umeyama, PointMatch, Pose3, RansacConfig, RigidTransformEstimator,
};
use std::hint::black_box;

fn random_point(rng: &mut ChaCha8Rng, half: f64) -> Point3<f64> {
    Point3::new(
        rng.gen_range(-half..half),
        rng.gen_range(-half..half),
        rng.gen_range(-half..half),
    )
}

/// `n` matches under a fixed motion, the first `inliers` with ±5 mm noise, the rest random.
fn matches(n: usize, inliers: usize) -> Vec<PointMatch> {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let dst_from_src = Pose3::from_parts(
        Translation3::new(0.3, -0.1, 0.8),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.05, -0.2, 0.1)),
    );
    (0..n)
        .map(|i| {
            let src = random_point(&mut rng, 5.0);
            let dst = if i < inliers {
                dst_from_src * src + random_point(&mut rng, 0.005).coords
            } else {
                random_point(&mut rng, 10.0)
            };
            PointMatch { src, dst }
        })
        .collect()
}

fn absolute_orientation(c: &mut Criterion) {
    let (src, dst): (Vec<_>, Vec<_>) = matches(100, 100).iter().map(|m| (m.src, m.dst)).unzip();
    c.bench_function("core/horn_100", |b| {
        b.iter(|| horn(black_box(&src), black_box(&dst), true))
    });
    c.bench_function("core/umeyama_100", |b| {
        b.iter(|| umeyama(black_box(&src), black_box(&dst), true))
    });
}

fn ransac_rigid(c: &mut Criterion) {
    let config = RansacConfig::default();
    for (label, inliers) in [
        ("core/ransac_500_10pct_outliers", 450),
        ("core/ransac_500_60pct_outliers", 200),
    ] {
        let data = matches(500, inliers);
        c.bench_function(label, |b| {
            b.iter(|| ransac(&RigidTransformEstimator, black_box(&data), &config))
        });
    }
}

// Written out instead of `criterion_group!`, whose generated function has no docs.
fn main() {
    let mut c = Criterion::default().configure_from_args();
    absolute_orientation(&mut c);
    ransac_rigid(&mut c);
    c.final_summary();
}
