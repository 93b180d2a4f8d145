use super::*;
use crate::cloud::{estimate_normals, scan_points};
use crate::nn::{GridIndex, PointIndex};
use crate::sim_scan::SegmentWorld;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// Source scan at `world_from_b`, target scan at `world_from_a`, both with 1 cm range noise;
/// returns the source points, the target index and the true `a_from_b`.
fn fixture(world_from_a: Pose2, world_from_b: Pose2) -> (Vec<Point2<f64>>, PointIndex, Pose2) {
    let world = SegmentWorld::room();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut noisy = |pose: &Pose2| {
        let mut scan = world.scan(pose, 361, 1.5 * PI, 30.0);
        for r in &mut scan.ranges_m {
            *r += rng.gen_range(-0.01..0.01);
        }
        scan_points(&scan, 0.05, 29.0)
    };
    let target_pts = noisy(&world_from_a);
    let source = noisy(&world_from_b);
    let normals = estimate_normals(&target_pts, 6, 0.5, 0.2);
    let target = PointIndex::new(target_pts, Some(normals));
    (source, target, world_from_a.inverse() * world_from_b)
}

fn pose_error(a: &Pose2, b: &Pose2) -> (f64, f64) {
    let e = a.inverse() * b;
    (e.translation.vector.norm(), e.rotation.angle().abs())
}

#[test]
fn recovers_known_motion_every_metric_solver_and_kernel() {
    let a = Pose2::new(Vector2::new(-1.0, 0.5), 0.3);
    let b = Pose2::new(Vector2::new(-0.8, 0.35), 0.38);
    let (source, target, gt) = fixture(a, b);
    for metric in [IcpMetric::PointToPoint, IcpMetric::PointToLine] {
        for solver in [IcpSolver::GaussNewton, IcpSolver::LevenbergMarquardt] {
            for kernel in [
                RobustKernel::None,
                RobustKernel::Huber,
                RobustKernel::Cauchy,
                RobustKernel::Tukey,
            ] {
                let config = IcpConfig {
                    metric,
                    solver,
                    kernel,
                    ..IcpConfig::default()
                };
                let res = align(&source, &target, &Pose2::identity(), &config).unwrap();
                let (dt, dr) = pose_error(&res.target_from_source, &gt);
                let label = format!("{metric:?} {solver:?} {kernel:?}");
                assert!(
                    dt < 0.01 && dr < 0.2_f64.to_radians(),
                    "{label}: {dt} m {dr} rad"
                );
                assert!(res.goodness > 0.85, "{label}: goodness {}", res.goodness);
            }
        }
    }
}

#[test]
fn point_to_line_converges_in_fewer_iterations() {
    let a = Pose2::new(Vector2::new(0.0, 0.0), 0.0);
    let b = Pose2::new(Vector2::new(0.2, -0.1), -0.05);
    let (source, target, gt) = fixture(a, b);
    let run = |metric| {
        let config = IcpConfig {
            metric,
            ..IcpConfig::default()
        };
        align(&source, &target, &Pose2::identity(), &config).unwrap()
    };
    let p2l = run(IcpMetric::PointToLine);
    let p2p = run(IcpMetric::PointToPoint);
    assert!(pose_error(&p2l.target_from_source, &gt).0 < 0.005);
    assert!(
        p2l.iterations < p2p.iterations,
        "{} vs {}",
        p2l.iterations,
        p2p.iterations
    );
}

#[test]
fn grid_and_kd_tree_give_the_same_alignment() {
    let a = Pose2::new(Vector2::new(0.3, -0.2), 0.1);
    let b = Pose2::new(Vector2::new(0.5, -0.1), 0.2);
    let (source, tree, _) = fixture(a, b);
    let normals = (0..tree.len()).map(|i| tree.normal(i)).collect();
    let grid = GridIndex::new(tree.points().to_vec(), Some(normals), 0.1);
    let config = IcpConfig::default();
    let by_tree = align(&source, &tree, &Pose2::identity(), &config).unwrap();
    let by_grid = align(&source, &grid, &Pose2::identity(), &config).unwrap();
    assert_eq!(by_tree, by_grid);
}

#[test]
fn robust_kernel_rejects_outliers() {
    let a = Pose2::new(Vector2::new(1.0, -1.0), -0.2);
    let b = Pose2::new(Vector2::new(1.15, -0.9), -0.15);
    let (mut source, target, gt) = fixture(a, b);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let n = source.len();
    for p in source.iter_mut().take(n / 4) {
        *p += Vector2::new(rng.gen_range(-0.15..0.15), rng.gen_range(-0.15..0.15));
    }
    let config = IcpConfig {
        kernel: RobustKernel::Tukey,
        kernel_scale_m: 0.05,
        ..IcpConfig::default()
    };
    let res = align(&source, &target, &Pose2::identity(), &config).unwrap();
    let (dt, dr) = pose_error(&res.target_from_source, &gt);
    assert!(dt < 0.015 && dr < 0.3_f64.to_radians(), "{dt} m {dr} rad");
}

#[test]
fn goodness_is_low_for_a_wrong_pose() {
    let a = Pose2::identity();
    let (source, target, gt) = fixture(a, a);
    assert!(goodness(&source, &target, &gt, 0.05) > 0.95);
    let wrong = Pose2::new(Vector2::new(0.4, 0.3), 0.3);
    assert!(goodness(&source, &target, &wrong, 0.05) < 0.3);
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let target = PointIndex::new(vec![Point2::new(1.0, 0.0); 20], None);
    let few = vec![Point2::new(0.0, 0.0); 3];
    let config = IcpConfig::default();
    assert!(matches!(
        align(&few, &target, &Pose2::identity(), &config),
        Err(LidarError::TooFewPoints { got: 3, .. })
    ));
    let far: Vec<Point2<f64>> = (0..20).map(|i| Point2::new(50.0, i as f64)).collect();
    assert!(matches!(
        align(&far, &target, &Pose2::identity(), &config),
        Err(LidarError::TooFewCorrespondences { .. })
    ));
    let empty = PointIndex::new(Vec::new(), None);
    assert!(align(&far, &empty, &Pose2::identity(), &config).is_err());
    let bad = IcpConfig {
        dist_shrink_factor: 0.0,
        ..IcpConfig::default()
    };
    assert!(matches!(
        align(&far, &target, &Pose2::identity(), &bad),
        Err(LidarError::InvalidConfig {
            field: "dist_shrink_factor",
            ..
        })
    ));
}

#[test]
fn weights_are_the_derivative_of_the_costs() {
    for kernel in [
        RobustKernel::None,
        RobustKernel::Huber,
        RobustKernel::Cauchy,
        RobustKernel::Tukey,
    ] {
        for r in [0.01, 0.04, 0.07, 0.2] {
            let h = 1e-7;
            let drho = (rho(kernel, 0.05, r + h) - rho(kernel, 0.05, r - h)) / (2.0 * h);
            assert!(
                (drho / r - weight(kernel, 0.05, r * r)).abs() < 1e-5,
                "{kernel:?} at {r}"
            );
        }
    }
}

#[test]
fn cost_sum_equals_the_sum_of_costs() {
    let residuals: Vec<f64> = (0..400).map(|i| f64::from(i) * 0.37 % 3.0).collect();
    for kind in [
        RobustKernel::None,
        RobustKernel::Huber,
        RobustKernel::Cauchy,
        RobustKernel::Tukey,
    ] {
        let kernel = Kernel {
            kind,
            scale_m: 0.01,
        };
        let mut sum = CostSum::new(kernel);
        for r in &residuals {
            sum.add(r * r);
        }
        let direct: f64 = residuals.iter().map(|&r| rho(kind, 0.01, r)).sum();
        assert!(
            (sum.total() - direct).abs() <= 1e-12 * direct,
            "{kind:?}: {} vs {direct}",
            sum.total()
        );
    }
    // Huge residuals (a wild trial step) neither overflow the product nor lose their cost.
    let cauchy = Kernel {
        kind: RobustKernel::Cauchy,
        scale_m: 0.01,
    };
    let mut sum = CostSum::new(cauchy);
    let huge = [1e145, 1e200, 1e140, 1e290];
    for r2 in huge {
        sum.add(r2);
    }
    let direct: f64 = huge
        .iter()
        .map(|r2| rho(cauchy.kind, 0.01, r2.sqrt()))
        .sum();
    assert!((sum.total() - direct).abs() <= 1e-12 * direct);
}

#[test]
fn config_round_trips_through_toml_text() {
    let config: IcpConfig =
        toml::from_str("metric = \"point_to_point\"\nkernel = \"huber\"").unwrap();
    assert_eq!(config.metric, IcpMetric::PointToPoint);
    assert_eq!(config.max_iterations, IcpConfig::default().max_iterations);
    assert!(toml::from_str::<IcpConfig>("bogus = 1").is_err());
}

#[test]
fn correspondence_cache_gives_the_fresh_answers() {
    // Target: a room scan on the grid (the ICP-SLAM case) and on the k-d tree (default
    // clearance). Queries drift in small and large steps, as ICP's do, under shrinking radii.
    let (source, kd, _) = fixture(Pose2::identity(), Pose2::new(Vector2::new(0.1, 0.0), 0.02));
    let grid = GridIndex::new(kd.points().to_vec(), Some(kd.normals().to_vec()), 0.1);
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    for (target, is_grid) in [(&grid as &dyn NearestNeighbours, true), (&kd, false)] {
        let mut cache = Correspondences::new(source.len());
        let mut pose = Pose2::new(Vector2::new(0.05, -0.03), 0.01);
        let (mut queries, mut fresh_queries) = (0, 0);
        for step in 0..60 {
            let radius = 0.3 * 0.97f64.powi(step);
            let size = if step % 3 == 0 { 1e-2 } else { 1e-4 };
            let motion = Vector3::new(
                rng.gen_range(-size..size),
                rng.gen_range(-size..size),
                rng.gen_range(-size..size) * 0.1,
            );
            pose = exp_step(&motion) * pose;
            for (i, p) in source.iter().enumerate() {
                let q = pose * p;
                let before = cache.last[i];
                let cached = cache.nearest(i, &q, target, radius);
                let fresh = target.nearest_within(&q, radius).map(|n| n.index);
                assert_eq!(cached, fresh, "point {i} step {step}");
                queries += 1;
                fresh_queries += usize::from(cache.last[i] != before);
            }
        }
        // The grid's clearances let most small steps reuse the answer.
        if is_grid {
            assert!(fresh_queries * 2 < queries, "{fresh_queries} of {queries}");
        }
    }
}
