//! Hot stages of 2D mapping: inserting a scan into an occupancy grid, scoring a scan against a
//! likelihood field.
//!
//! Input: 180 beams one degree apart (the Intel Research Lab log's SICK LMS geometry) in a
//! simulated 16 m × 16 m room, ranges about 8 m, 5 cm cells.
//!
//! Results (2-core shared x86-64 VM, other builds running, `cargo bench`):
//!
//! | bench                               | time    |
//! |-------------------------------------|---------|
//! | map/insert_scan_180_beams_8m        | 57 µs   |
//! | map/likelihood_score_points_180     | 0.87 µs |
//! | map/likelihood_score_scan_180       | 0.98 µs |
//! | map/likelihood_field_build_16m_room | 4.7 ms  |
//!
//! Insertion went 111 → 78 µs with the branch-free fixed-point line walk, and → 57 µs with
//! byte marks, incremental beam directions and one `Arc::make_mut` per tile.

// A bench aborts on setup failure; criterion's macros generate undocumented functions.
#![allow(clippy::expect_used, missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Vector2;
use slamkit_core::Pose2;
use slamkit_map::{LikelihoodField, LikelihoodFieldConfig, OccupancyGrid, OccupancyGridConfig};
use std::hint::black_box;

#[path = "../src/test_room.rs"]
#[allow(dead_code)]
mod test_room;

const HALF_ROOM_M: f64 = 8.0;

fn insert_scan(c: &mut Criterion) {
    let pose = Pose2::new(Vector2::new(0.3, -0.2), 0.4);
    let scan = test_room::room_scan(&pose, HALF_ROOM_M, 180, 30.0);
    let mut grid = OccupancyGrid::new(OccupancyGridConfig::default()).expect("default config");
    grid.insert_scan(&scan, &pose).expect("finite pose");
    c.bench_function("map/insert_scan_180_beams_8m", |b| {
        b.iter(|| grid.insert_scan(black_box(&scan), black_box(&pose)))
    });
}

fn score_scan(c: &mut Criterion) {
    let mut grid = OccupancyGrid::new(OccupancyGridConfig::default()).expect("default config");
    for k in 0..8 {
        let pose = Pose2::new(
            Vector2::new(0.5 * f64::from(k) - 2.0, 0.3),
            f64::from(k) * 0.8,
        );
        let scan = test_room::room_scan(&pose, HALF_ROOM_M, 180, 30.0);
        grid.insert_scan(&scan, &pose).expect("finite pose");
    }
    let field =
        LikelihoodField::new(&grid, &LikelihoodFieldConfig::default()).expect("default config");
    let pose = Pose2::new(Vector2::new(0.3, -0.2), 0.4);
    let scan = test_room::room_scan(&pose, HALF_ROOM_M, 180, 30.0);
    let points = scan.hit_points();
    c.bench_function("map/likelihood_score_points_180", |b| {
        b.iter(|| field.score_points(black_box(&points), black_box(&pose)))
    });
    c.bench_function("map/likelihood_score_scan_180", |b| {
        b.iter(|| field.score_scan(black_box(&scan), black_box(&pose)))
    });
    c.bench_function("map/likelihood_field_build_16m_room", |b| {
        b.iter(|| LikelihoodField::new(black_box(&grid), &LikelihoodFieldConfig::default()))
    });
}

criterion_group!(benches, insert_scan, score_scan);
criterion_main!(benches);
