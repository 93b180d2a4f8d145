use super::*;
use crate::cloud::{estimate_normals, scan_points};
use crate::icp::{align, IcpConfig};
use crate::nn::PointIndex;
use crate::sim_scan::SegmentWorld;
use std::f64::consts::PI;

/// A hall with a lattice of small pillars: repetitive structure full of local minima for ICP.
fn pillar_hall() -> SegmentWorld {
    let mut world = SegmentWorld::polygon(&[(-6.0, -4.0), (7.0, -4.0), (7.0, 4.0), (-6.0, 4.0)]);
    for i in -4..=4 {
        for j in -2..=2 {
            let (x, y) = (i as f64 * 0.6 + 0.3, j as f64 * 0.6 + 0.3);
            let c = [
                (x - 0.08, y - 0.08),
                (x + 0.08, y - 0.08),
                (x + 0.08, y + 0.08),
                (x - 0.08, y + 0.08),
            ];
            world.segments.extend(SegmentWorld::polygon(&c).segments);
        }
    }
    world
}

fn scans(world_from_a: &Pose2, world_from_b: &Pose2) -> (Vec<Point2<f64>>, Vec<Point2<f64>>) {
    scans_in(&SegmentWorld::room(), world_from_a, world_from_b)
}

fn scans_in(
    world: &SegmentWorld,
    world_from_a: &Pose2,
    world_from_b: &Pose2,
) -> (Vec<Point2<f64>>, Vec<Point2<f64>>) {
    let pts = |p: &Pose2| scan_points(&world.scan(p, 361, PI, 30.0), 0.05, 29.0);
    (pts(world_from_b), pts(world_from_a))
}

fn error(a: &Pose2, b: &Pose2) -> (f64, f64) {
    let e = a.inverse() * b;
    (e.translation.vector.norm(), e.rotation.angle().abs())
}

#[test]
fn recovers_an_offset_plain_icp_cannot() {
    // (start, offset direction, rotation): 0.3 m / 10° offsets where the pillar lattice traps ICP.
    let cases = [
        ((0.0, 0.0), PI / 2.0, 10.0),
        ((0.0, 0.0), 1.25 * PI, -10.0),
        ((0.6, -0.6), PI / 2.0, 10.0),
    ];
    let world = pillar_hall();
    for ((x, y), dir, rot_deg) in cases {
        let a = Pose2::new(Vector2::new(x, y), 0.1);
        let b = Pose2::new(
            Vector2::new(x + 0.3 * dir.cos(), y + 0.3 * dir.sin()),
            0.1 + f64::to_radians(rot_deg),
        );
        let (source, target) = scans_in(&world, &a, &b);
        let gt = a.inverse() * b;
        let normals = estimate_normals(&target, 6, 0.5, 0.2);
        let index = PointIndex::new(target.clone(), Some(normals));
        let icp = IcpConfig::default();
        if let Ok(plain) = align(&source, &index, &Pose2::identity(), &icp) {
            let (dt, _) = error(&plain.target_from_source, &gt);
            assert!(dt > 0.1, "plain ICP succeeded from ({x}, {y}): {dt} m");
        }
        let config = CorrelativeConfig::default();
        let coarse = correlative_match(&source, &target, &Pose2::identity(), &config).unwrap();
        let (dt, dr) = error(&coarse.target_from_source, &gt);
        assert!(
            dt < 0.06 && dr < 1.5f64.to_radians(),
            "correlative: {dt} m {dr} rad"
        );
        assert!(coarse.score > 0.5, "score {}", coarse.score);
        let fine = align(&source, &index, &coarse.target_from_source, &icp).unwrap();
        let (dt, dr) = error(&fine.target_from_source, &gt);
        assert!(
            dt < 0.005 && dr < 0.1f64.to_radians(),
            "refined: {dt} m {dr} rad"
        );
    }
}

#[test]
fn branch_and_bound_equals_exhaustive_search() {
    let a = Pose2::new(Vector2::new(1.0, 1.0), -0.4);
    let b = Pose2::new(Vector2::new(1.2, 0.9), -0.3);
    let (source, target) = scans(&a, &b);
    let config = CorrelativeConfig {
        linear_window_m: 0.3,
        angular_window_rad: 8f64.to_radians(),
        max_angular_step_rad: 2f64.to_radians(),
        coarse_cells: 3,
        ..CorrelativeConfig::default()
    };
    let fast = correlative_match(&source, &target, &Pose2::identity(), &config).unwrap();

    let res = config.resolution_m;
    let reach = source.iter().map(|p| p.coords.norm()).fold(0.0, f64::max);
    let half = reach + config.linear_window_m + 4.0 * config.sigma_m + res;
    let side = (2.0 * half / res).ceil() as i64 + 1;
    let origin = Point2::new(-half, -half);
    let whole = ((0, 0), (side - 1, side - 1));
    let field = Field::new(&target, &origin, whole, res, config.sigma_m);
    let step = (1.0 - res * res / (2.0 * reach * reach))
        .acos()
        .min(config.max_angular_step_rad);
    let n = (config.angular_window_rad / step).ceil() as i64;
    let w = (config.linear_window_m / res).ceil() as i64;
    let mut best = f64::NEG_INFINITY;
    for a in -n..=n {
        let pose = Pose2::new(Vector2::zeros(), a as f64 * step);
        let cells: Vec<(i64, i64)> = source.iter().map(|p| field.cell(&(pose * p))).collect();
        for di in -w..=w {
            for dj in -w..=w {
                let score: f64 = cells
                    .iter()
                    .map(|&(i, j)| field.value(i + di, j + dj))
                    .sum();
                best = best.max(score);
            }
        }
    }
    assert!(
        (fast.score - best / source.len() as f64).abs() < 1e-9,
        "{} vs {}",
        fast.score,
        best
    );
}

#[test]
fn bad_input_is_an_error() {
    let target = vec![Point2::new(1.0, 1.0); 30];
    let config = CorrelativeConfig::default();
    assert!(matches!(
        correlative_match(&[], &target, &Pose2::identity(), &config),
        Err(LidarError::TooFewPoints { .. })
    ));
    let bad = CorrelativeConfig {
        resolution_m: 0.0,
        ..config.clone()
    };
    assert!(correlative_match(&target, &target, &Pose2::identity(), &bad).is_err());
    let empty_target = correlative_match(&target, &[], &Pose2::identity(), &config).unwrap();
    assert_eq!(empty_target.score, 0.0);
}

#[test]
fn a_field_built_once_gives_the_per_call_results_and_serves_other_sources() {
    let config = CorrelativeConfig::default();
    let a = Pose2::new(Vector2::new(1.0, 1.0), -0.4);
    let b = Pose2::new(Vector2::new(1.2, 0.9), -0.3);
    let (source, target) = scans(&a, &b);
    let headings = [0.0, 0.5, -2.0];
    let per_call =
        correlative_match_headings(&source, &target, &Vector2::zeros(), &headings, &config)
            .unwrap();
    // On the per-call lattice (the same corner), the whole square holds the same cells.
    let reach = source.iter().map(|p| p.coords.norm()).fold(0.0, f64::max);
    let half = LikelihoodField::half_m_for_reach(reach, &config);
    let field = LikelihoodField::square(&target, &Vector2::zeros(), half, &config).unwrap();
    assert_eq!(
        field
            .match_headings(&source, &Vector2::zeros(), &headings)
            .unwrap(),
        per_call
    );
    // One field wider than any source, matched against scans from elsewhere in the room.
    let wide = LikelihoodField::half_m_for_reach(30.0, &config);
    let field = LikelihoodField::square(&target, &Vector2::zeros(), wide, &config).unwrap();
    assert!(field.bytes() >= 2 * 4 * ((2.0 * wide / config.resolution_m) as usize).pow(2));
    for b in [
        Pose2::new(Vector2::new(0.8, 1.3), -0.2),
        Pose2::new(Vector2::new(1.3, 0.7), -0.5),
    ] {
        let (source, _) = scans(&a, &b);
        let got = field
            .match_headings(&source, &Vector2::zeros(), &[0.0])
            .unwrap()[0];
        let (dt, dr) = error(&got.target_from_source, &(a.inverse() * b));
        assert!(dt < 0.06 && dr < 1.5f64.to_radians(), "{dt} m {dr} rad");
    }
    assert!(matches!(
        field.match_headings(&[], &Vector2::zeros(), &[0.0]),
        Err(LidarError::TooFewPoints { .. })
    ));
    assert!(LikelihoodField::square(&target, &Vector2::zeros(), 0.0, &config).is_err());
    assert!(LikelihoodField::square(&target, &Vector2::zeros(), 1e6, &config).is_err());
}
