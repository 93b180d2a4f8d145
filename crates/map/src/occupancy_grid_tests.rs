use super::*;
use crate::test_room::room_scan;

fn grid() -> OccupancyGrid {
    OccupancyGrid::new(OccupancyGridConfig::default()).unwrap()
}

/// A scan with the given ranges, beams 90° apart starting along +x.
fn scan(ranges_m: Vec<f64>) -> LaserScan {
    LaserScan {
        timestamp: 0.0,
        angle_min_rad: 0.0,
        angle_increment_rad: std::f64::consts::FRAC_PI_2,
        ranges_m,
        max_range_m: 10.0,
        odometry: None,
        base_from_laser: Pose2::identity(),
    }
}

/// Laser at the centre of cell (0, 0), heading +x.
fn at_cell_centre() -> Pose2 {
    Pose2::new(Vector2::new(0.025, 0.025), 0.0)
}

fn cell(x: i32, y: i32) -> CellIndex {
    CellIndex { x, y }
}

#[test]
fn single_hit_marks_end_occupied_and_path_free() {
    let mut g = grid();
    let stats = g.insert_scan(&scan(vec![1.0]), &at_cell_centre()).unwrap();
    assert_eq!(
        stats,
        InsertStats {
            hits: 1,
            cleared: 0,
            ignored: 0
        }
    );
    let l_miss = log_odds_from_probability(0.4);
    let l_hit = log_odds_from_probability(0.7);
    for x in 0..20 {
        assert_eq!(g.log_odds(cell(x, 0)), Some(l_miss), "cell {x}");
    }
    assert_eq!(g.log_odds(cell(20, 0)), Some(l_hit));
    assert_eq!(g.occupancy(cell(20, 0)), Some(Occupancy::Occupied));
    assert_eq!(g.occupancy(cell(21, 0)), Some(Occupancy::Unknown));
    assert_eq!(g.occupancy(cell(5, 1)), Some(Occupancy::Unknown));
    assert!((g.probability(cell(20, 0)).unwrap() - 0.7).abs() < 1e-6);
    assert_eq!(
        g.occupancy_at(&Point2::new(1.01, 0.01)),
        Some(Occupancy::Occupied)
    );
    assert_eq!(
        g.occupancy_at(&Point2::new(0.5, 0.01)),
        Some(Occupancy::Free)
    );
}

#[test]
fn no_return_clears_up_to_limit_without_hit() {
    let mut g = grid();
    // Beam 0 reads max range, beam 1 (+y) reads beyond it.
    let stats = g
        .insert_scan(&scan(vec![10.0, 25.0]), &at_cell_centre())
        .unwrap();
    assert_eq!(stats.cleared, 2);
    // Free up to 5 m: cell 100 holds x = 5.025 m.
    for x in 0..=100 {
        assert_eq!(g.occupancy(cell(x, 0)), Some(Occupancy::Free), "cell {x}");
        assert_eq!(g.occupancy(cell(0, x)), Some(Occupancy::Free), "cell {x}");
    }
    assert_eq!(g.occupancy(cell(101, 0)), Some(Occupancy::Unknown));
    assert_eq!(g.occupancy(cell(0, 101)), Some(Occupancy::Unknown));
    let bounds = g.known_bounds().unwrap();
    assert_eq!(
        bounds,
        CellBounds {
            min: cell(0, 0),
            max: cell(100, 100)
        }
    );
}

#[test]
fn short_max_range_limits_clearing() {
    let mut g = grid();
    let mut s = scan(vec![2.0]);
    s.max_range_m = 2.0;
    g.insert_scan(&s, &at_cell_centre()).unwrap();
    assert_eq!(g.occupancy(cell(40, 0)), Some(Occupancy::Free));
    assert_eq!(g.occupancy(cell(41, 0)), Some(Occupancy::Unknown));
}

#[test]
fn hits_beyond_usable_range_only_clear() {
    let config = OccupancyGridConfig {
        max_usable_range_m: 1.0,
        ..OccupancyGridConfig::default()
    };
    let mut g = OccupancyGrid::new(config).unwrap();
    let stats = g.insert_scan(&scan(vec![3.0]), &at_cell_centre()).unwrap();
    assert_eq!(stats.cleared, 1);
    assert_eq!(g.occupancy(cell(20, 0)), Some(Occupancy::Free));
    assert_eq!(g.occupancy(cell(21, 0)), Some(Occupancy::Unknown));
}

#[test]
fn garbage_ranges_are_ignored() {
    let mut g = grid();
    let s = scan(vec![f64::NAN, -1.0, f64::INFINITY, 0.0]);
    let stats = g.insert_scan(&s, &at_cell_centre()).unwrap();
    assert_eq!(
        stats,
        InsertStats {
            hits: 0,
            cleared: 0,
            ignored: 4
        }
    );
    assert_eq!(g.known_bounds(), None);
}

#[test]
fn bad_poses_are_errors() {
    let mut g = grid();
    let nan = Pose2::new(Vector2::new(f64::NAN, 0.0), 0.0);
    assert!(matches!(
        g.insert_scan(&scan(vec![1.0]), &nan),
        Err(MapError::NonFinitePose { .. })
    ));
    let far = Pose2::new(Vector2::new(1e12, 0.0), 0.0);
    assert!(matches!(
        g.insert_scan(&scan(vec![1.0]), &far),
        Err(MapError::OutsideMap { .. })
    ));
    assert_eq!(g.cell_at(&Point2::new(f64::NAN, 0.0)), None);
    assert_eq!(g.occupancy_at(&Point2::new(3.0, 3.0)), None);
}

#[test]
fn repeated_evidence_is_clamped() {
    let mut g = grid();
    for _ in 0..100 {
        g.insert_scan(&scan(vec![1.0]), &at_cell_centre()).unwrap();
    }
    let (l_min, l_max) = g.log_odds_limits();
    assert!((f64::from(l_max) - (0.97f64 / 0.03).ln()).abs() < 1e-6);
    assert_eq!(g.log_odds(cell(20, 0)), Some(l_max));
    assert_eq!(g.log_odds(cell(3, 0)), Some(l_min));
    assert!((g.probability(cell(3, 0)).unwrap() - 0.12).abs() < 1e-6);
}

#[test]
fn each_cell_updated_once_per_scan_and_hit_wins() {
    // 720 beams converge on the robot's cell: without de-duplication it would get 720 updates.
    let mut g = grid();
    let mut s = room_scan(&at_cell_centre(), 2.0, 720, 30.0);
    s.angle_increment_rad = std::f64::consts::TAU / 720.0;
    s.ranges_m = (0..720)
        .map(|i| {
            let (sin, cos) = s.beam_angle_rad(i).sin_cos();
            crate::test_room::range_to_walls(0.025, 0.025, cos, sin, 2.0)
        })
        .collect();
    g.insert_scan(&s, &at_cell_centre()).unwrap();
    let l_miss = log_odds_from_probability(0.4);
    let l_hit = log_odds_from_probability(0.7);
    let bounds = g.known_bounds().unwrap();
    let mut occupied = 0;
    for y in bounds.min.y..=bounds.max.y {
        for x in bounds.min.x..=bounds.max.x {
            let l = g.log_odds(cell(x, y)).unwrap();
            assert!(
                l == 0.0 || l == l_miss || l == l_hit,
                "cell ({x},{y}) = {l}"
            );
            occupied += usize::from(l == l_hit);
        }
    }
    assert_eq!(g.log_odds(cell(0, 0)), Some(l_miss));
    // The four walls are 80 cells long: every end point is a distinct wall cell or shared.
    assert!(
        occupied > 250 && occupied <= 720,
        "{occupied} occupied cells"
    );
}

#[test]
fn room_map_matches_geometry() {
    let mut g = grid();
    for (i, (x, y)) in [(0.0, 0.0), (2.0, 1.0), (-2.5, -2.0), (1.5, -2.5)]
        .iter()
        .enumerate()
    {
        for k in 0..4 {
            let heading = k as f64 * std::f64::consts::FRAC_PI_2 + i as f64 * 0.3;
            let pose = Pose2::new(Vector2::new(*x, *y), heading);
            g.insert_scan(&room_scan(&pose, 4.025, 180, 30.0), &pose)
                .unwrap();
        }
    }
    // Walls run through cell centres (x = ±4.025 m). Beams 1° apart leave gaps between wall
    // hits at 5 cm cells, so a wall point must have an occupied cell within one cell along the
    // wall; the interior is free and the outside never free.
    let occupied_near = |x: f64, y: f64, along: Vector2<f64>| {
        (-1..=1).any(|k| {
            let p = Point2::new(x, y) + along * (0.05 * f64::from(k));
            g.occupancy_at(&p) == Some(Occupancy::Occupied)
        })
    };
    for y in [-3.0, -1.0, 0.5, 2.0, 3.5] {
        assert!(occupied_near(4.02, y, Vector2::y()), "east wall at y {y}");
        assert!(occupied_near(y, -4.02, Vector2::x()), "south wall at x {y}");
        assert_eq!(
            g.occupancy_at(&Point2::new(0.3 * y, y)),
            Some(Occupancy::Free)
        );
        assert_ne!(g.occupancy_at(&Point2::new(4.3, y)), Some(Occupancy::Free));
    }
    let b = g.known_bounds().unwrap();
    assert_eq!((b.min, b.max), (cell(-81, -81), cell(80, 80)));
}

#[test]
fn grid_grows_while_exploring() {
    let mut g = grid();
    for step in 0..40 {
        let pose = Pose2::new(Vector2::new(step as f64 * 5.0, -(step as f64) * 3.0), 0.7);
        g.insert_scan(&scan(vec![2.0, 2.0, 2.0, 2.0]), &pose)
            .unwrap();
    }
    for step in 0..40 {
        let (x, y) = (step as f64 * 5.0, -(step as f64) * 3.0);
        let (s, c) = 0.7f64.sin_cos();
        let hit = Point2::new(x + 2.0 * c, y + 2.0 * s);
        assert_eq!(
            g.occupancy_at(&hit),
            Some(Occupancy::Occupied),
            "step {step}"
        );
        assert_eq!(g.occupancy_at(&Point2::new(x, y)), Some(Occupancy::Free));
    }
}

#[test]
fn clones_share_untouched_tiles() {
    let mut base = grid();
    for k in 0..8 {
        let pose = Pose2::new(Vector2::new(k as f64 * 6.0 - 21.0, 0.0), 0.0);
        base.insert_scan(&room_scan(&pose, 30.0, 360, 8.0), &pose)
            .unwrap();
    }
    let base_stats = base.tile_stats();
    assert!(base_stats.unique_tiles > 50, "{base_stats:?}");
    let probe = Point2::new(1.01, 0.0);
    let before = base.log_odds_at(&probe);
    let mut particles: Vec<OccupancyGrid> = (0..100).map(|_| base.clone()).collect();
    for (i, p) in particles.iter_mut().enumerate() {
        let pose = Pose2::new(Vector2::new(0.001 * i as f64, 0.0), 0.0);
        p.insert_scan(&scan(vec![1.0, 1.0, 1.0, 1.0]), &pose)
            .unwrap();
    }
    let stats = shared_tile_stats(&particles);
    assert!(
        stats.tile_references >= 100 * base_stats.unique_tiles,
        "{stats:?}"
    );
    // Each particle copied only the 4 tiles around (0, 0) its small scan touched.
    assert!(
        stats.unique_tiles <= base_stats.unique_tiles + 100 * 4,
        "{stats:?}"
    );
    assert!(stats.bytes < 100 * base_stats.bytes / 5, "{stats:?}");
    // The base map is unchanged, the particles changed.
    assert_eq!(base.log_odds_at(&probe), before);
    assert_ne!(particles[0].log_odds_at(&probe), before);
}

#[test]
fn invalid_configs_are_rejected() {
    let bad = [
        OccupancyGridConfig {
            resolution_m: 0.0,
            ..Default::default()
        },
        OccupancyGridConfig {
            resolution_m: f64::NAN,
            ..Default::default()
        },
        OccupancyGridConfig {
            p_hit: 0.4,
            ..Default::default()
        },
        OccupancyGridConfig {
            p_min: 0.5,
            ..Default::default()
        },
        OccupancyGridConfig {
            no_return_clear_m: -1.0,
            ..Default::default()
        },
    ];
    for config in bad {
        assert!(matches!(
            OccupancyGrid::new(config),
            Err(MapError::InvalidConfig { .. })
        ));
    }
}

/// One odometry jump in a real log (x = 1e6 m) asked a grid for a 5 TB tile index; the grid
/// refuses a box beyond `MAX_INDEX_TILES`, says how large, and keeps what it had.
#[test]
fn a_jump_beyond_the_largest_grid_is_refused_and_loses_nothing() {
    let mut g = grid();
    g.insert_scan(&scan(vec![1.0, 1.0, 1.0, 1.0]), &at_cell_centre())
        .unwrap();
    let known = g.known_bounds();
    let jump = Pose2::new(Vector2::new(1e6, 1e6), 0.0);
    let err = g
        .insert_scan(&scan(vec![1.0, 1.0, 1.0, 1.0]), &jump)
        .unwrap_err();
    let MapError::TooLarge { width_m, .. } = err else {
        panic!("{err}");
    };
    assert!(width_m >= 1e6, "{width_m}");
    assert!(err.to_string().contains("jump"), "{err}");
    assert_eq!(g.known_bounds(), known);
    assert!(g.tile_stats().bytes < 1 << 20, "{:?}", g.tile_stats());
    // 6 km away at 5 cm still fits: a very large building, not a jump
    let far = Pose2::new(Vector2::new(6000.0, 0.0), 0.0);
    g.insert_scan(&scan(vec![1.0, 1.0, 1.0, 1.0]), &far)
        .unwrap();
    let far_cell = cell(-1000, -1000);
    assert!(g.set_log_odds(far_cell, 1.0).is_ok());
    assert!(g.set_log_odds(cell(0, 200_000), 1.0).is_err());
}
