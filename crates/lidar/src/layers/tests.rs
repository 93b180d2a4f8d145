use super::height::{HeightConfig, HeightTracker};
use super::*;
use crate::sim_scan::SegmentWorld;
use nalgebra::Vector2;

#[test]
fn climbing_changes_the_layer_flying_over_a_box_does_not() {
    let mut t = HeightTracker::new(HeightConfig::default());
    // 0.03 m sensor offsets: base at 0.30 m in a 1 m room
    let e = t.update(Some(0.67), Some(0.27)).unwrap();
    assert!((e.height_m - 0.30).abs() < 1e-9 && e.layer == 6);
    // climb 1 cm steps to 0.40: both ranges move, the sum stays
    for k in 1..=10 {
        let h = 0.30 + 0.01 * f64::from(k);
        let e = t.update(Some(0.97 - h), Some(h - 0.03)).unwrap();
        assert!((e.height_m - h).abs() < 1e-9 && !e.obstacle_edge);
    }
    // 0.40 m is the boundary of layers 7 and 8: hysteresis keeps layer 7 until 0.41 m
    assert_eq!(t.estimate().unwrap().layer, 7);
    // over a 0.2 m crate: down drops by 0.2, up unchanged: an edge, the height stays
    let e = t.update(Some(0.57), Some(0.17)).unwrap();
    assert!(e.obstacle_edge && (e.height_m - 0.40).abs() < 1e-9 && e.layer == 7);
    // climbing over the crate still works, then off the crate the floor comes back
    let e = t.update(Some(0.56), Some(0.18)).unwrap();
    assert!(!e.obstacle_edge && (e.height_m - 0.41).abs() < 1e-9);
    let e = t.update(Some(0.56), Some(0.38)).unwrap();
    assert!(e.obstacle_edge && (e.height_m - 0.41).abs() < 1e-9);
    // under a hanging box: the up range jumps, the height stays
    let e = t.update(Some(0.20), Some(0.38)).unwrap();
    assert!(e.obstacle_edge && (e.height_m - 0.41).abs() < 1e-9);
    // only one sensor: still tracked, a jump on it is an edge
    let e = t.update(None, Some(0.39)).unwrap();
    assert!((e.height_m - 0.42).abs() < 1e-9 && e.layer == 8);
    let e = t.update(None, Some(0.09)).unwrap();
    assert!(e.obstacle_edge && (e.height_m - 0.42).abs() < 1e-9);
    assert!(t.update(Some(f64::NAN), None).is_some());
    assert!(HeightTracker::new(HeightConfig::default())
        .update(None, Some(f64::NAN))
        .is_none());
}

#[test]
fn hysteresis_keeps_the_layer_on_a_boundary() {
    let mut t = HeightTracker::new(HeightConfig::default());
    // hovering at 0.35 m, right on the boundary between layers 6 and 7, with 4 mm noise
    let mut layers = Vec::new();
    for k in 0..40 {
        let noise = if k % 2 == 0 { 0.004 } else { -0.004 };
        let h = 0.35 + noise;
        layers.push(t.update(Some(1.0 - h), Some(h - 0.03)).unwrap().layer);
    }
    assert!(layers.windows(2).all(|w| w[0] == w[1]), "{layers:?}");
    let e = t.update(Some(1.0 - 0.365), Some(0.335)).unwrap();
    assert_eq!(e.layer, 7);
}

/// A room whose lower slice holds a box that the upper slice does not.
fn worlds() -> (SegmentWorld, SegmentWorld) {
    let high = SegmentWorld::room();
    let mut low = high.clone();
    let crate_box = [(3.0, -2.5), (3.8, -2.5), (3.8, -1.7), (3.0, -1.7)];
    low.segments
        .extend(SegmentWorld::polygon(&crate_box).segments);
    (low, high)
}

struct Step {
    truth: Pose2,
    z_m: f64,
    pitch_rad: f64,
}

/// Flies along x at 0.3 m, climbs to 0.62 m (over the box's height), flies on, comes back down.
fn flight() -> Vec<Step> {
    let mut steps = Vec::new();
    for k in 0..120 {
        let x = -3.0 + 0.04 * f64::from(k.min(100));
        let z = match k {
            0..=39 => 0.3,
            40..=59 => 0.3 + 0.016 * f64::from(k - 39),
            60..=99 => 0.62,
            _ => 0.62 - 0.016 * f64::from(k - 99),
        };
        let pitch = if k == 20 { 0.05 } else { 0.0 };
        steps.push(Step {
            truth: Pose2::new(
                Vector2::new(x, 0.2 * (f64::from(k) * 0.05).sin()),
                0.02 * f64::from(k),
            ),
            z_m: z,
            pitch_rad: pitch,
        });
    }
    steps
}

#[test]
fn one_map_per_layer_reused_on_return_and_tilted_scans_skipped() {
    let (low, high) = worlds();
    // the flight stops dead at the end, with no tilt, which no drone can: the odometry (5 %
    // long, no noise) is the prior that follows it
    let config = LayeredSlamConfig {
        use_odometry: true,
        ..LayeredSlamConfig::default()
    };
    let mut slam = LayeredIcpSlam::new(config).unwrap();
    let steps = flight();
    let mut errors = Vec::new();
    for (k, step) in steps.iter().enumerate() {
        let world = if step.z_m < 0.45 { &low } else { &high };
        let mut scan = world.scan(&step.truth, 360, 1.5 * std::f64::consts::PI, 8.0);
        // odometry reads 5 % long
        let start = steps[0].truth;
        let delta = start.inverse() * step.truth;
        let odo = start * Pose2::new(delta.translation.vector * 1.05, delta.rotation.angle());
        scan.odometry = Some(odo);
        scan.timestamp = k as f64 * 0.1;
        let est = slam.process(&LayerInput {
            scan: &scan,
            // tilted beams read long
            up_m: Some((2.0 - step.z_m - 0.03) / step.pitch_rad.cos()),
            down_m: Some((step.z_m - 0.03) / step.pitch_rad.cos()),
            roll_rad: 0.0,
            pitch_rad: step.pitch_rad,
            gyro_yaw_rad: None,
            flow_velocity_mps: None,
        });
        if k == 20 {
            assert_eq!(est.status, LayerScanStatus::Tilted);
        }
        let truth_in_first = start.inverse() * step.truth;
        let err = (est.world_from_base.translation.vector.xy() - truth_in_first.translation.vector)
            .norm();
        assert!((est.world_from_base.translation.z - step.z_m).abs() < 1e-9);
        errors.push(err);
    }
    let max = errors.iter().copied().fold(0.0, f64::max);
    assert!(max < 0.02, "max error {max}");
    let stats = *slam.stats();
    assert_eq!(stats.scans_tilted, 1);
    assert!(stats.layer_returns >= 1, "{stats:?}");
    let maps = slam.layer_maps();
    // layers 6 (0.30 m) to 12 (0.62 m), each created once
    assert_eq!(maps.first().unwrap().layer, 6);
    assert_eq!(maps.last().unwrap().layer, 12);
    assert!(maps.windows(2).all(|w| w[0].layer < w[1].layer));
    let cloud = slam.merged_cloud();
    assert_eq!(
        cloud.len(),
        maps.iter().map(|m| m.points.len()).sum::<usize>()
    );
    assert!(cloud.iter().any(|p| (p.z - 0.625).abs() < 1e-9));
}

#[test]
fn bad_config_is_an_error() {
    let mut config = LayeredSlamConfig::default();
    config.height.layer_height_m = 0.0;
    assert!(LayeredIcpSlam::new(config).is_err());
    let config = LayeredSlamConfig {
        max_tilt_rad: f64::NAN,
        ..LayeredSlamConfig::default()
    };
    assert!(LayeredIcpSlam::new(config).is_err());
    for bad in [-1.0, f64::NAN] {
        let mut config = LayeredSlamConfig::default();
        config.relocalise.max_shift_m = bad;
        assert!(LayeredIcpSlam::new(config).is_err());
        let mut config = LayeredSlamConfig::default();
        config.relocalise.min_gain = bad;
        assert!(LayeredIcpSlam::new(config).is_err());
        let mut config = LayeredSlamConfig::default();
        config.reference.max_height_gap_m = bad;
        assert!(LayeredIcpSlam::new(config).is_err());
    }
    let mut config = LayeredSlamConfig::default();
    config.reference.min_goodness = 1.5;
    assert!(LayeredIcpSlam::new(config).is_err());
}

/// Heading error at the end of a turn in place beside a lone pillar, whose scans do not pin the
/// rotation about the pillar's centre, with and without the gyro's heading (biased by
/// 0.01 rad/s).
fn turn_beside_a_pillar(gyro: bool) -> (f64, f64) {
    let pillar: Vec<(f64, f64)> = (0..24)
        .map(|i| {
            let a = f64::from(i) * std::f64::consts::TAU / 24.0;
            (1.0 + 0.3 * a.cos(), 0.3 * a.sin())
        })
        .collect();
    let world = SegmentWorld::polygon(&pillar);
    let mut slam = LayeredIcpSlam::new(LayeredSlamConfig::default()).unwrap();
    let mut last = Pose2::identity();
    let mut est = None;
    // hover for 2 s, then turn at 0.4 rad/s for 2 s
    for k in 0..40 {
        let t = 0.1 * f64::from(k);
        let yaw = 0.4 * (t - 2.0).max(0.0);
        last = Pose2::new(Vector2::zeros(), yaw);
        let mut scan = world.scan(&last, 512, 1.5 * std::f64::consts::PI, 3.0);
        scan.timestamp = t;
        est = Some(slam.process(&LayerInput {
            scan: &scan,
            up_m: Some(1.0),
            down_m: Some(0.5),
            roll_rad: 0.0,
            pitch_rad: 0.0,
            gyro_yaw_rad: gyro.then_some(yaw + 0.01 * t),
            flow_velocity_mps: None,
        }));
    }
    let est = est.unwrap().world_from_base;
    let (_, _, yaw) = est.rotation.euler_angles();
    let position = est.translation.vector.xy().norm();
    assert!(slam.stats().scans_degenerate > 0);
    ((yaw - last.rotation.angle()).abs(), position)
}

#[test]
fn beside_a_pillar_the_heading_follows_the_gyro() {
    let (with_gyro, with_position) = turn_beside_a_pillar(true);
    let (without, without_position) = turn_beside_a_pillar(false);
    eprintln!("heading error with gyro {with_gyro} ({with_position} m), without {without} ({without_position} m)");
    assert!(
        with_gyro < 0.05 && with_position < 0.05,
        "{with_gyro} {with_position}"
    );
    assert!(without > 0.1, "{without}");
}

/// Heading error at the end of a flight that hovers in layer 6 for 5 s, jumps to layer 10 as
/// its odometry turns by 0.02 rad (a new layer starts from the odometry: the layer alignment
/// is off), and hovers there for 5 s more; with or without reference layers, and the number of
/// reference fixes.
fn climb_with_a_heading_slip(reference: bool) -> (f64, usize) {
    let world = SegmentWorld::room();
    let mut config = LayeredSlamConfig {
        use_odometry: true,
        align_new_layer: false,
        ..LayeredSlamConfig::default()
    };
    config.reference.enabled = reference;
    let mut slam = LayeredIcpSlam::new(config).unwrap();
    let mut error = f64::NAN;
    for k in 0..105 {
        let t = 0.1 * f64::from(k);
        let z = if k < 50 { 0.32 } else { 0.52 };
        let truth = Pose2::new(Vector2::new(-1.0 + 0.01 * t, 0.5), 0.3);
        let slip = if k < 50 { 0.0 } else { 0.02 };
        let mut scan = world.scan(&truth, 360, 1.5 * std::f64::consts::PI, 8.0);
        scan.timestamp = t;
        scan.odometry = Some(truth * Pose2::new(Vector2::zeros(), slip));
        let est = slam.process(&LayerInput {
            scan: &scan,
            up_m: Some(2.0 - z - 0.03),
            down_m: Some(z - 0.03),
            roll_rad: 0.0,
            pitch_rad: 0.0,
            gyro_yaw_rad: None,
            flow_velocity_mps: None,
        });
        // the world frame is the first scan's pose, at the same heading
        let (_, _, yaw) = est.world_from_base.rotation.euler_angles();
        error = yaw.abs();
    }
    assert_eq!(slam.current_layer(), Some(10));
    (error, slam.stats().reference_fixes)
}

#[test]
fn an_older_layer_below_pulls_a_slipped_heading_back() {
    let (with, fixes) = climb_with_a_heading_slip(true);
    let (without, none) = climb_with_a_heading_slip(false);
    assert!(with < 0.003 && fixes > 0, "{with} rad, {fixes} fixes");
    assert!(without > 0.015 && none == 0, "{without} rad");
}
