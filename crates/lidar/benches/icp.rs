//! Hot stages of scan matching on simulated 361-beam scans of the test room: k-d tree and grid
//! builds, nearest-neighbour queries within ICP's 0.3 m threshold in each, one point-to-line ICP
//! alignment against each, one correlative search (±0.5 m, ±20°).

use criterion::{criterion_main, Criterion};
use nalgebra::Vector2;
use slamkit_core::Pose2;
use slamkit_lidar::cloud::{estimate_normals, scan_points};
use slamkit_lidar::correlative::{correlative_match, CorrelativeConfig};
use slamkit_lidar::icp::{align, IcpConfig};
use slamkit_lidar::nn::{GridIndex, NearestNeighbours, PointIndex};
use slamkit_lidar::sim_scan::SegmentWorld;
use std::f64::consts::PI;

fn scans() -> (Vec<nalgebra::Point2<f64>>, Vec<nalgebra::Point2<f64>>) {
    let world = SegmentWorld::room();
    let a = Pose2::new(Vector2::new(-1.0, 0.5), 0.3);
    let b = Pose2::new(Vector2::new(-0.8, 0.35), 0.38);
    let pts = |p: &Pose2| scan_points(&world.scan(p, 361, PI, 30.0), 0.05, 29.0);
    (pts(&b), pts(&a))
}

/// Number of `queries` with a neighbour within 0.3 m in `index`.
fn nearest_all(index: &impl NearestNeighbours, queries: &[nalgebra::Point2<f64>]) -> usize {
    queries
        .iter()
        .filter(|q| index.nearest_within(q, 0.3).is_some())
        .count()
}

fn bench_matching(c: &mut Criterion) {
    let (source, target) = scans();
    let normals = estimate_normals(&target, 6, 0.5, 0.2);
    c.bench_function("lidar/kdtree_build_361", |b| {
        b.iter(|| PointIndex::new(target.clone(), Some(normals.clone())))
    });
    c.bench_function("lidar/normals_361", |b| {
        b.iter(|| estimate_normals(&target, 6, 0.5, 0.2))
    });
    c.bench_function("lidar/grid_build_361", |b| {
        b.iter(|| GridIndex::new(target.clone(), Some(normals.clone()), 0.1))
    });
    let index = PointIndex::new(target.clone(), Some(normals.clone()));
    let grid = GridIndex::new(target.clone(), Some(normals), 0.1);
    c.bench_function("lidar/kdtree_queries_361", |b| {
        b.iter(|| nearest_all(&index, &source))
    });
    c.bench_function("lidar/grid_queries_361", |b| {
        b.iter(|| nearest_all(&grid, &source))
    });
    let config = IcpConfig::default();
    c.bench_function("lidar/icp_point_to_line_361", |b| {
        b.iter(|| align(&source, &index, &Pose2::identity(), &config))
    });
    c.bench_function("lidar/icp_point_to_line_361_grid", |b| {
        b.iter(|| align(&source, &grid, &Pose2::identity(), &config))
    });
    let corr = CorrelativeConfig::default();
    c.bench_function("lidar/correlative_361", |b| {
        b.iter(|| correlative_match(&source, &target, &Pose2::identity(), &corr))
    });
}

// Written out instead of `criterion_group!`, whose generated function has no docs.
/// Runs every benchmark of this file.
fn benches() {
    let mut criterion = Criterion::default().configure_from_args();
    bench_matching(&mut criterion);
}

criterion_main!(benches);
