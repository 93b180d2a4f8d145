//! The coarse-to-fine disparity search against the exhaustive one on real stereo pairs (KITTI 06,
//! frames 0, 10, …, 50): at the ORB keypoints and Shi–Tomasi corners the VO presets track, the
//! two must agree on which points get a disparity and on the disparity itself for nearly every
//! point. Needs `SLAMKIT_DATA`.

#![allow(clippy::unwrap_used)] // test helpers fail loudly

use std::path::Path;

use slamkit_io::image_io::load_gray;
use slamkit_vision::corners::{shi_tomasi, ShiTomasiConfig};
use slamkit_vision::orb::{Orb, OrbConfig};
use slamkit_vision::stereo::{DisparitySearch, StereoConfig, StereoPair};

/// Counts of one comparison.
#[derive(Debug, Default)]
struct Agreement {
    points: usize,
    /// Both without a disparity, or both with the same one (±0.01 px).
    same: usize,
    /// Only one of the two searches gave a disparity.
    accepted_differently: usize,
    /// Both gave one, more than 0.01 px apart.
    disparity_differs: usize,
}

#[test]
fn coarse_to_fine_agrees_with_exhaustive_on_kitti() {
    let Ok(root) = std::env::var("SLAMKIT_DATA") else {
        eprintln!("skipped: coarse_to_fine_agrees_with_exhaustive_on_kitti: SLAMKIT_DATA not set");
        return;
    };
    let dir = Path::new(&root).join("stereo/kitti_odometry_06_0000-0050");
    let orb = Orb::new(OrbConfig {
        n_features: 3000,
        n_levels: 1,
        ..OrbConfig::default()
    })
    .unwrap();
    let corners = ShiTomasiConfig {
        max_corners: 500,
        ..ShiTomasiConfig::default()
    };
    let fine = StereoConfig::default();
    assert_eq!(fine.search, DisparitySearch::CoarseToFine);
    let exhaustive = StereoConfig {
        search: DisparitySearch::Exhaustive,
        ..fine.clone()
    };
    let mut total = Agreement::default();
    for frame in (0..=50).step_by(10) {
        let name = format!("{frame:06}.png");
        let left = load_gray(&dir.join("image_0").join(&name)).unwrap();
        let right = load_gray(&dir.join("image_1").join(&name)).unwrap();
        let mut points: Vec<(f32, f32)> = orb
            .detect_and_compute(&left)
            .keypoints
            .iter()
            .map(|k| (k.x, k.y))
            .collect();
        points.extend(
            shi_tomasi(&left, &corners)
                .unwrap()
                .iter()
                .map(|c| (c.x, c.y)),
        );
        let pair = StereoPair::new(left.clone(), right.clone()).unwrap();
        let a = pair.match_points(&points, &fine).unwrap();
        let b = pair.match_points(&points, &exhaustive).unwrap();
        for (a, b) in a.iter().zip(&b) {
            total.points += 1;
            match (a, b) {
                (None, None) => total.same += 1,
                (Some(a), Some(b)) if (a.disparity_px - b.disparity_px).abs() <= 0.01 => {
                    total.same += 1;
                }
                (Some(_), Some(_)) => total.disparity_differs += 1,
                _ => total.accepted_differently += 1,
            }
        }
    }
    eprintln!("coarse-to-fine vs exhaustive on KITTI 06: {total:?}");
    let share = |n: usize| n as f64 / total.points as f64;
    assert!(total.points > 10_000, "{total:?}");
    assert!(share(total.same) >= 0.99, "{total:?}");
    assert!(share(total.disparity_differs) <= 0.005, "{total:?}");
}
