//! Criterion benchmarks of the stereo VO kernels on KITTI 06 frames 0 and 1 (1226×370): ORB
//! (3000 features, full resolution only, as the stereo preset), stereo matching of those
//! keypoints (coarse-to-fine and exhaustive), and Hamming matching of the two frames'
//! descriptors (brute force and within 100 px). Times are the thread's CPU time (the machine is
//! shared). Needs `SLAMKIT_DATA`; prints a note and does nothing without it.

// A benchmark has no error path to report through: a broken fixture should stop it loudly.
#![allow(clippy::expect_used, missing_docs)]

use std::path::Path;

use std::hint::black_box;
use std::time::Duration;

use cpu_time::ThreadTime;
use criterion::{criterion_group, criterion_main, Bencher, Criterion};
use slamkit_io::image_io::load_gray;
use slamkit_vision::matching::{match_descriptors, match_descriptors_within, MatchConfig};
use slamkit_vision::orb::{Orb, OrbConfig};
use slamkit_vision::stereo::{DisparitySearch, StereoConfig, StereoPair};

/// Times `f` in thread CPU time.
fn cpu<T>(b: &mut Bencher, mut f: impl FnMut() -> T) {
    b.iter_custom(|iters| {
        let start = ThreadTime::now();
        for _ in 0..iters {
            black_box(f());
        }
        start.elapsed().max(Duration::from_nanos(1))
    });
}

fn stereo_features(c: &mut Criterion) {
    let Ok(root) = std::env::var("SLAMKIT_DATA") else {
        eprintln!("skipped: stereo_features benches: SLAMKIT_DATA not set");
        return;
    };
    let dir = Path::new(&root).join("stereo/kitti_odometry_06_0000-0050");
    let load = |cam: &str, i: usize| {
        load_gray(&dir.join(cam).join(format!("{i:06}.png"))).expect("KITTI frame")
    };
    let (left, right, next) = (load("image_0", 0), load("image_1", 0), load("image_0", 1));
    let orb = Orb::new(OrbConfig {
        n_features: 3000,
        n_levels: 1,
        ..OrbConfig::default()
    })
    .expect("valid config");
    c.bench_function("vision/orb_3000_kitti", |b| {
        cpu(b, || orb.detect_and_compute(&left))
    });
    let (f0, f1) = (orb.detect_and_compute(&left), orb.detect_and_compute(&next));
    let pts: Vec<(f32, f32)> = f0.keypoints.iter().map(|k| (k.x, k.y)).collect();
    for search in [DisparitySearch::CoarseToFine, DisparitySearch::Exhaustive] {
        let config = StereoConfig {
            search,
            ..StereoConfig::default()
        };
        c.bench_function(&format!("vision/stereo_{search:?}_3000_kitti"), |b| {
            cpu(b, || {
                let pair = StereoPair::new(left.clone(), right.clone()).expect("same size");
                pair.match_points(&pts, &config).expect("valid config")
            })
        });
    }
    let mc = MatchConfig::default();
    c.bench_function("vision/hamming_brute_3000x3000_kitti", |b| {
        cpu(b, || {
            match_descriptors(&f1.descriptors, &f0.descriptors, &mc)
        })
    });
    let px = |f: &slamkit_vision::OrbFeatures| -> Vec<[f32; 2]> {
        f.keypoints.iter().map(|k| [k.x, k.y]).collect()
    };
    let (p0, p1) = (px(&f0), px(&f1));
    c.bench_function("vision/hamming_within_100px_3000x3000_kitti", |b| {
        cpu(b, || {
            match_descriptors_within((&f1.descriptors, &p1), (&f0.descriptors, &p0), 100.0, &mc)
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = stereo_features
}
criterion_main!(benches);
