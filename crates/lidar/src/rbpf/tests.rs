use super::*;
use crate::sim_scan::SegmentWorld;
use nalgebra::Vector2;

/// A loop around the simulated room: straight legs of 0.1 m steps joined by turns on the spot.
pub(crate) fn room_loop() -> Vec<Pose2> {
    let corners: [(f64, f64); 5] = [
        (-4.0, -2.5),
        (4.0, -2.5),
        (4.0, 2.5),
        (-4.0, 2.5),
        (-4.0, -2.5),
    ];
    let mut poses = Vec::new();
    for leg in corners.windows(2) {
        let (a, b) = (
            Vector2::new(leg[0].0, leg[0].1),
            Vector2::new(leg[1].0, leg[1].1),
        );
        let heading = (b - a).y.atan2((b - a).x);
        if let Some(last) = poses.last().copied() {
            let last: Pose2 = last;
            let start = last.rotation.angle();
            for k in 1..=8 {
                let angle = start + wrap_angle(heading - start) * f64::from(k) / 8.0;
                poses.push(Pose2::new(last.translation.vector, angle));
            }
        }
        let steps = ((b - a).norm() / 0.1).round() as usize;
        for k in 0..steps {
            poses.push(Pose2::new(a + (b - a) * (k as f64 / steps as f64), heading));
        }
    }
    poses
}

/// Scans along `truth`, and odometry that overestimates distance by 5 % and drifts 0.03 rad per
/// metre to the left.
pub(crate) fn simulate(truth: &[Pose2]) -> (Vec<LaserScan>, Vec<Pose2>) {
    let world = SegmentWorld::room();
    let mut odometry = vec![Pose2::identity()];
    for pair in truth.windows(2) {
        let step = pair[0].inverse() * pair[1];
        let d = step.translation.vector.norm();
        let distorted = Pose2::new(
            step.translation.vector * 1.05,
            step.rotation.angle() + 0.03 * d,
        );
        let last = odometry[odometry.len() - 1];
        odometry.push(last * distorted);
    }
    let scans = truth
        .iter()
        .zip(&odometry)
        .enumerate()
        .map(|(i, (p, o))| {
            let mut scan = world.scan(p, 181, std::f64::consts::PI, 30.0);
            scan.timestamp = i as f64 * 0.1;
            scan.odometry = Some(*o);
            scan
        })
        .collect();
    (scans, odometry)
}

/// Largest position error of `est` against `truth`, both expressed relative to their first pose.
fn max_error_m(truth: &[Pose2], est: &[Pose2]) -> f64 {
    let (t0, e0) = (truth[0].inverse(), est[0].inverse());
    truth
        .iter()
        .zip(est)
        .map(|(t, e)| ((t0 * t).translation.vector - (e0 * e).translation.vector).norm())
        .fold(0.0, f64::max)
}

fn small_config() -> RbpfConfig {
    RbpfConfig {
        particles: 10,
        ..RbpfConfig::default()
    }
}

#[test]
fn corrects_drifting_odometry_on_a_room_loop() {
    let truth = room_loop();
    let (scans, odometry) = simulate(&truth);
    let odo_error = max_error_m(&truth, &odometry);
    let out = run_rbpf(&scans, &small_config(), |_| {}).unwrap();
    assert_eq!(out.poses.len(), scans.len());
    assert_eq!(out.trajectory.len(), scans.len());
    let err = max_error_m(&truth, &out.poses);
    assert!(odo_error > 1.0, "odometry drifts: {odo_error}");
    // Measured 0.094 m with the default 2-cell kernel, the largest errors in the first metres
    // while the map holds only a few scans (0.08 m with a 1-cell kernel, which does far worse
    // on the Intel log).
    assert!(err < 0.1, "rbpf max error {err} m (odometry {odo_error} m)");
    assert!(out.stats.updates > 50 && out.stats.wheel_odometry);
    assert_eq!(out.stats.scans_skipped, 0);
    // The maps share the tiles no particle changed since the last resampling. In this small
    // room every scan touches nearly every tile, so sharing saves less here than on a building
    // log (see tests/rbpf_logs.rs).
    let m = out.stats.memory_end;
    assert!(m.shared_bytes * 10 < m.unshared_bytes * 7, "{m:?}");
    assert!(m.unshared_bytes >= 10 * m.single_map_bytes / 2, "{m:?}");
}

#[test]
fn same_seed_same_result_and_other_seed_differs() {
    let truth = room_loop();
    let (scans, _) = simulate(&truth[..120]);
    let a = run_rbpf(&scans, &small_config(), |_| {}).unwrap();
    let b = run_rbpf(&scans, &small_config(), |_| {}).unwrap();
    assert_eq!(a.poses, b.poses);
    let other = RbpfConfig {
        seed: 99,
        ..small_config()
    };
    let c = run_rbpf(&scans, &other, |_| {}).unwrap();
    assert_ne!(a.poses, c.poses);
}

#[test]
fn tempered_weights_resample_less_often() {
    let truth = room_loop();
    let (scans, _) = simulate(&truth[..150]);
    let plain = run_rbpf(&scans, &small_config(), |_| {}).unwrap();
    let tempered = RbpfConfig {
        weight_temperature: 1000.0,
        ..small_config()
    };
    let out = run_rbpf(&scans, &tempered, |_| {}).unwrap();
    let (a, b) = (plain.stats.resamples, out.stats.resamples);
    assert!(a > 0 && b < a, "resamples: plain {a}, tempered {b}");
}

#[test]
fn scan_odometry_replaces_missing_wheel_odometry() {
    let truth = room_loop();
    let (mut scans, _) = simulate(&truth[..150]);
    for scan in &mut scans {
        scan.odometry = None;
    }
    let out = run_rbpf(&scans, &small_config(), |_| {}).unwrap();
    assert!(!out.stats.wheel_odometry);
    let err = max_error_m(&truth[..150], &out.poses);
    assert!(err < 0.08, "rbpf with ICP odometry: max error {err} m");
}

#[test]
fn broken_scans_are_skipped_and_counted() {
    let truth = room_loop();
    let (mut scans, _) = simulate(&truth[..60]);
    scans[10].ranges_m.iter_mut().for_each(|r| *r = f64::NAN);
    scans[20].ranges_m.clear();
    scans[30].ranges_m.iter_mut().for_each(|r| *r = -1.0);
    scans[40].ranges_m.iter_mut().for_each(|r| *r = 30.0);
    let config = RbpfConfig {
        update_linear_m: 0.0,
        update_angular_rad: 0.0,
        ..small_config()
    };
    let out = run_rbpf(&scans, &config, |_| {}).unwrap();
    assert_eq!(out.stats.scans_skipped, 4);
    assert_eq!(out.poses.len(), 60);
    assert!(out.poses.iter().all(crate::motion::is_finite_pose));
}

#[test]
fn interpolation_spreads_the_correction() {
    let odometry: Vec<Pose2> = (0..5)
        .map(|i| Pose2::new(Vector2::new(f64::from(i), 0.0), 0.0))
        .collect();
    // Updates at scans 1 and 3; scan 3 was corrected by +0.2 m in y.
    let updates = [
        (1, Pose2::new(Vector2::new(1.0, 0.0), 0.0)),
        (3, Pose2::new(Vector2::new(3.0, 0.2), 0.0)),
    ];
    let poses = interpolate_poses(&updates, &odometry);
    let y: Vec<f64> = poses.iter().map(|p| p.translation.vector.y).collect();
    let x: Vec<f64> = poses.iter().map(|p| p.translation.vector.x).collect();
    for (got, want) in y.iter().zip([0.0, 0.0, 0.1, 0.2, 0.2]) {
        assert!((got - want).abs() < 1e-12, "{y:?}");
    }
    for (got, want) in x.iter().zip([0.0, 1.0, 2.0, 3.0, 4.0]) {
        assert!((got - want).abs() < 1e-12, "{x:?}");
    }
    assert_eq!(interpolate_poses(&[], &odometry), odometry);
}

#[test]
fn invalid_config_is_rejected() {
    for config in [
        RbpfConfig {
            particles: 0,
            ..RbpfConfig::default()
        },
        RbpfConfig {
            max_range_m: f64::NAN,
            ..RbpfConfig::default()
        },
        RbpfConfig {
            resample_threshold: 2.0,
            ..RbpfConfig::default()
        },
        RbpfConfig {
            weight_temperature: 0.5,
            ..RbpfConfig::default()
        },
        RbpfConfig {
            relocalisation: RelocalisationConfig {
                fraction: 1.5,
                ..RelocalisationConfig::default()
            },
            ..RbpfConfig::default()
        },
    ] {
        assert!(matches!(
            Rbpf::new(config),
            Err(LidarError::InvalidConfig { .. })
        ));
    }
    // A relocalisation value out of range is reported by its field name.
    let bad = RbpfConfig {
        relocalisation: RelocalisationConfig {
            every_updates: 0,
            ..RelocalisationConfig::default()
        },
        ..RbpfConfig::default()
    };
    assert!(matches!(
        Rbpf::new(bad),
        Err(LidarError::InvalidConfig {
            field: "every_updates",
            ..
        })
    ));
}

/// A scan of a straight wall 2.01 m ahead, 1 cm off the centre line of its 5 cm cells.
fn wall_scan() -> LaserScan {
    let (first, step, n) = (-0.6, 0.01, 121);
    LaserScan {
        timestamp: 0.0,
        angle_min_rad: first,
        angle_increment_rad: step,
        ranges_m: (0..n)
            .map(|i| 2.01 / (first + f64::from(i) * step).cos())
            .collect(),
        max_range_m: 30.0,
        odometry: None,
        base_from_laser: Pose2::identity(),
    }
}

/// x of the pose the hill climb reaches from 3 cm behind the truth (the origin) on the wall.
fn climbed_x(means: Option<&hit_means::HitMeans>, grid: &OccupancyGrid) -> f64 {
    let config = proposal::ProposalConfig::default();
    let scorer = GridScorer::new(grid, means, &config);
    let scan = PreparedScan::new(&wall_scan(), 0.1, 30.0, 1, grid.resolution_m());
    let start = Pose2::new(Vector2::new(-0.03, 0.0), 0.0);
    scorer
        .climb(&scan, &start, &config, None)
        .0
        .translation
        .vector
        .x
}

#[test]
fn mean_hit_points_match_below_the_cell_size() {
    let scan = wall_scan();
    let mut grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
    let mut means = HitMeans::new(grid.origin_m(), grid.resolution_m(), 20.0);
    for _ in 0..3 {
        grid.insert_scan(&scan, &Pose2::identity()).unwrap();
        means.insert_scan(&scan, &Pose2::identity());
    }
    let centres = HitMeans::new(grid.origin_m(), grid.resolution_m(), 20.0);
    let (with_means, with_centres) = (
        climbed_x(Some(&means), &grid),
        climbed_x(Some(&centres), &grid),
    );
    // No store at all scores at the cell centres, as an empty one does.
    assert_eq!(climbed_x(None, &grid), with_centres);
    // The cell centres sit at 2.025 m: matched to them the wall is found 1.5 cm short.
    assert!(
        with_means.abs() < 0.003,
        "mean hit points: x = {with_means}"
    );
    assert!(with_centres > 0.008, "cell centres: x = {with_centres}");
}

/// With `climb_with_motion_prior`, a tight motion prior holds the climb at the prediction
/// 3 cm behind the wall's match; a loose one lets it reach the match as the plain climb does.
#[test]
fn a_tight_motion_prior_holds_the_climb_near_the_prediction() {
    let scan = wall_scan();
    let mut grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
    for _ in 0..3 {
        grid.insert_scan(&scan, &Pose2::identity()).unwrap();
    }
    let config = proposal::ProposalConfig::default();
    let scorer = GridScorer::new(&grid, None, &config);
    let prepared = PreparedScan::new(&scan, 0.1, 30.0, 1, grid.resolution_m());
    let start = Pose2::new(Vector2::new(-0.03, 0.0), 0.0);
    let prior = |sigma: f64| proposal::MotionPrior {
        predicted: start,
        information: nalgebra::Matrix3::identity() / (sigma * sigma),
    };
    let x = |p: Option<&proposal::MotionPrior>| {
        scorer
            .climb(&prepared, &start, &config, p)
            .0
            .translation
            .vector
            .x
    };
    let (plain, loose, tight) = (x(None), x(Some(&prior(1.0))), x(Some(&prior(0.001))));
    assert!(plain > 0.0, "plain climb: x = {plain}");
    assert!((loose - plain).abs() < 1e-9, "loose prior: x = {loose}");
    assert!((tight + 0.03).abs() < 0.002, "tight prior: x = {tight}");
}

/// Particles are of one lineage when they share their ancestor `depth` updates back; a
/// trajectory shorter than that counts from its first node.
#[test]
fn lineages_are_the_ancestors_a_depth_back() {
    let node = |scan: usize, parent: Option<&Arc<Node>>| {
        Arc::new(Node {
            scan,
            world_from_base: Pose2::identity(),
            cloud: None,
            parent: parent.cloned(),
        })
    };
    let root = node(0, None);
    let (a, b) = (node(1, Some(&root)), node(1, Some(&root)));
    let newest = [node(2, Some(&a)), node(2, Some(&a)), node(2, Some(&b))];
    let grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
    let particles: Vec<Particle> = newest
        .iter()
        .map(|n| Particle {
            world_from_base: Pose2::identity(),
            grid: grid.clone(),
            means: None,
            log_weight: 0.0,
            log_likelihood_sum: 0.0,
            node: n.clone(),
            closure: None,
        })
        .collect();
    let one_back = lineage_keys(&particles, 1);
    assert_eq!(one_back[0], one_back[1]);
    assert_ne!(one_back[0], one_back[2]);
    for depth in [2, 10] {
        let keys = lineage_keys(&particles, depth);
        assert!(
            keys.iter().all(|k| *k == Arc::as_ptr(&root)),
            "depth {depth}"
        );
    }
}

#[test]
fn poses_agree_within_both_tolerances() {
    let a = Pose2::new(Vector2::new(1.0, 2.0), 3.1);
    let b = Pose2::new(Vector2::new(1.2, 2.0), -3.15);
    assert!(agree(&a, &b, 0.25, 0.05), "the angle wraps");
    assert!(!agree(&a, &b, 0.1, 0.05));
    assert!(!agree(&a, &b, 0.25, 0.02));
}
