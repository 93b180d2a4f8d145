use super::*;
use nalgebra::Vector2;

/// Distance from `p` to the polyline `path`.
fn cross_track(path: &[Point2<f64>], p: &Point2<f64>) -> f64 {
    path.windows(2)
        .map(|w| {
            let (a, b) = (w[0], w[1]);
            let ab = b - a;
            let t = ((p - a).dot(&ab) / ab.norm_squared().max(1e-12)).clamp(0.0, 1.0);
            (a + ab * t - p).norm()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Drives a unicycle from `pose` along `path` for at most `seconds`; returns the worst
/// cross-track error, whether the goal was reached, and the largest commands seen.
fn drive(path: &[Point2<f64>], mut pose: Pose2, seconds: f64) -> (f64, bool, f64, f64) {
    let mut tracker = PathTracker::new(TrackerConfig::default()).unwrap();
    tracker.set_path(path);
    let dt = 0.02;
    let (mut worst, mut max_v, mut max_w) = (0.0f64, 0.0f64, 0.0f64);
    for _ in 0..(seconds / dt) as usize {
        let cmd = tracker.step(Some(&pose), dt);
        if cmd.status == TrackerStatus::GoalReached {
            return (worst, true, max_v, max_w);
        }
        max_v = max_v.max(cmd.speed_m_s.abs());
        max_w = max_w.max(cmd.yaw_rate_rad_s.abs());
        let theta = pose.rotation.angle() + cmd.yaw_rate_rad_s * dt;
        let t =
            pose.translation.vector + Vector2::new(theta.cos(), theta.sin()) * cmd.speed_m_s * dt;
        pose = Pose2::new(t, theta);
        worst = worst.max(cross_track(path, &Point2::from(t)));
    }
    (worst, false, max_v, max_w)
}

/// Points every `step` metres along the polyline through `corners`, as a grid planner's path.
fn densify(corners: &[(f64, f64)], step: f64) -> Vec<Point2<f64>> {
    let mut out = vec![Point2::new(corners[0].0, corners[0].1)];
    for w in corners.windows(2) {
        let (a, b) = (Point2::new(w[0].0, w[0].1), Point2::new(w[1].0, w[1].1));
        let n = ((b - a).norm() / step).ceil().max(1.0) as usize;
        out.extend((1..=n).map(|i| a + (b - a) * (i as f64 / n as f64)));
    }
    out
}

#[test]
fn follows_straight_diagonal_and_zigzag_paths() {
    let cases: [(&[(f64, f64)], f64); 3] = [
        (&[(0.0, 0.0), (3.0, 0.0)], 0.02),
        (&[(0.0, 0.0), (1.0, 0.0), (2.0, 1.0), (2.0, 2.5)], 0.1),
        (
            &[(0.0, 0.0), (1.0, 1.0), (2.0, 0.0), (3.0, 1.0), (4.0, 1.0)],
            0.1,
        ),
    ];
    for (corners, tolerance) in cases {
        let path = densify(corners, 0.1);
        let (worst, reached, max_v, max_w) = drive(&path, Pose2::new(Vector2::zeros(), 0.0), 120.0);
        assert!(reached, "{corners:?}");
        assert!(max_v <= 0.25 + 1e-12 && max_w <= 30f64.to_radians() + 1e-12);
        // 45° corners cut by the 0.5 m look-ahead stay within the 0.17 m.
        assert!(
            worst <= 0.17 && (corners.len() > 2 || worst <= tolerance),
            "{corners:?}: {worst}"
        );
    }
}

#[test]
fn starting_off_path_and_facing_away_still_converges() {
    let path = densify(&[(0.0, 0.0), (4.0, 0.0)], 0.1);
    let start = Pose2::new(Vector2::new(0.0, 0.3), std::f64::consts::PI);
    let (_, reached, _, _) = drive(&path, start, 120.0);
    assert!(reached);
}

#[test]
fn lost_localisation_and_no_path_give_zero_commands() {
    let mut tracker = PathTracker::new(TrackerConfig::default()).unwrap();
    let pose = Pose2::identity();
    assert_eq!(tracker.step(Some(&pose), 0.1).status, TrackerStatus::NoPath);
    tracker.set_path(&densify(&[(0.0, 0.0), (2.0, 0.0)], 0.1));
    for _ in 0..20 {
        tracker.step(Some(&pose), 0.1);
    }
    let lost = tracker.step(None, 0.1);
    assert_eq!((lost.speed_m_s, lost.yaw_rate_rad_s), (0.0, 0.0));
    assert_eq!(lost.status, TrackerStatus::LocalisationLost);
    let nan = Pose2::new(Vector2::new(f64::NAN, 0.0), 0.0);
    assert_eq!(
        tracker.step(Some(&nan), 0.1).status,
        TrackerStatus::LocalisationLost
    );
    // The smoothing restarts from zero: the first command after recovery is small.
    let back = tracker.step(Some(&pose), 0.02);
    assert!(back.speed_m_s > 0.0 && back.speed_m_s < 0.02, "{back:?}");
}

#[test]
fn smoothing_has_the_configured_time_constant() {
    let mut tracker = PathTracker::new(TrackerConfig::default()).unwrap();
    tracker.set_path(&densify(&[(0.0, 0.0), (10.0, 0.0)], 0.1));
    let pose = Pose2::identity();
    let mut cmd = tracker.step(Some(&pose), 0.0);
    for _ in 0..(1.0 / 3.0 / 0.001) as usize {
        cmd = tracker.step(Some(&pose), 0.001);
    }
    // After one time constant a step input reaches 1 − 1/e of its value.
    let expected = 0.25 * (1.0 - (-1.0f64).exp());
    assert!((cmd.speed_m_s - expected).abs() < 0.003, "{cmd:?}");
    assert!(PathTracker::new(TrackerConfig {
        lookahead_m: f64::NAN,
        ..TrackerConfig::default()
    })
    .is_err());
}
