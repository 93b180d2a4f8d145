//! Simulated laser scans in a square room of known size, shared by unit tests and benches.
//!
//! The room is the square `[-half, half]²` centred on the world origin; the range of each beam is
//! the exact distance to the first wall, so every test knows the answer in closed form.

use slamkit_core::{LaserScan, Pose2};

/// Range from `(x, y)` along unit direction `(cos, sin)` to the walls of the room \[m\].
pub fn range_to_walls(x: f64, y: f64, cos: f64, sin: f64, half_m: f64) -> f64 {
    let along = |p: f64, d: f64| {
        if d > 1e-12 {
            (half_m - p) / d
        } else if d < -1e-12 {
            (-half_m - p) / d
        } else {
            f64::INFINITY
        }
    };
    along(x, cos).min(along(y, sin))
}

/// A scan of `beams` beams, one degree apart and centred on the laser's x axis, taken at
/// `world_from_laser` inside a room of half side `half_m`; beams longer than `max_range_m` read
/// `max_range_m` ("no return").
pub fn room_scan(
    world_from_laser: &Pose2,
    half_m: f64,
    beams: usize,
    max_range_m: f64,
) -> LaserScan {
    let increment = 1f64.to_radians();
    let angle_min = -increment * (beams as f64 - 1.0) / 2.0;
    let heading = world_from_laser.rotation.angle();
    let t = world_from_laser.translation.vector;
    let ranges_m = (0..beams)
        .map(|i| {
            let (sin, cos) = (heading + angle_min + i as f64 * increment).sin_cos();
            range_to_walls(t.x, t.y, cos, sin, half_m).min(max_range_m)
        })
        .collect();
    LaserScan {
        timestamp: 0.0,
        angle_min_rad: angle_min,
        angle_increment_rad: increment,
        ranges_m,
        max_range_m,
        odometry: None,
        base_from_laser: Pose2::identity(),
    }
}
