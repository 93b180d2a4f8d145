//! 2D laser scans, as a planar lidar delivers them.

use crate::Pose2;
use nalgebra::Point2;

/// One sweep of a planar laser scanner.
///
/// Beam `i` points at `angle_min_rad + i * angle_increment_rad` in the laser frame (x forward,
/// y left). A reading at or beyond `max_range_m` means "no return": the beam saw nothing within
/// range. Such beams tell free space but are not obstacles; see [`LaserScan::is_hit`].
#[derive(Debug, Clone, PartialEq)]
pub struct LaserScan {
    /// Time of the scan \[s\].
    pub timestamp: f64,
    /// Bearing of the first beam in the laser frame \[rad\].
    pub angle_min_rad: f64,
    /// Angle between consecutive beams \[rad\].
    pub angle_increment_rad: f64,
    /// Measured ranges \[m\]; may hold NaN or negative values from broken sensors.
    pub ranges_m: Vec<f64>,
    /// Readings at or beyond this are "no return" \[m\].
    pub max_range_m: f64,
    /// Wheel-odometry pose of the robot base at scan time, when the log has odometry.
    pub odometry: Option<Pose2>,
    /// Pose of the laser in the robot base frame (`base_from_laser`).
    pub base_from_laser: Pose2,
}

impl LaserScan {
    /// Bearing of beam `i` in the laser frame \[rad\].
    pub fn beam_angle_rad(&self, i: usize) -> f64 {
        self.angle_min_rad + i as f64 * self.angle_increment_rad
    }

    /// True when beam `i` hit something: finite, positive and below the maximum range.
    pub fn is_hit(&self, i: usize) -> bool {
        self.ranges_m
            .get(i)
            .is_some_and(|r| r.is_finite() && *r > 0.0 && *r < self.max_range_m)
    }

    /// The end points of the beams that hit something, in the laser frame.
    pub fn hit_points(&self) -> Vec<Point2<f64>> {
        (0..self.ranges_m.len())
            .filter(|&i| self.is_hit(i))
            .map(|i| {
                let (s, c) = self.beam_angle_rad(i).sin_cos();
                let r = self.ranges_m[i];
                Point2::new(r * c, r * s)
            })
            .collect()
    }

    /// Number of beams that hit something.
    pub fn hit_count(&self) -> usize {
        (0..self.ranges_m.len()).filter(|&i| self.is_hit(i)).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan(ranges: Vec<f64>) -> LaserScan {
        LaserScan {
            timestamp: 0.0,
            angle_min_rad: -std::f64::consts::FRAC_PI_2,
            angle_increment_rad: std::f64::consts::FRAC_PI_2,
            ranges_m: ranges,
            max_range_m: 10.0,
            odometry: None,
            base_from_laser: Pose2::identity(),
        }
    }

    #[test]
    fn hits_skip_no_return_and_garbage() {
        let s = scan(vec![1.0, 10.0, f64::NAN, -1.0, 2.0]);
        assert_eq!(s.hit_count(), 2);
        let pts = s.hit_points();
        assert!((pts[0] - Point2::new(0.0, -1.0)).norm() < 1e-12);
        // beam 4 is at -90 + 4*90 = 270 degrees
        assert!((pts[1] - Point2::new(0.0, -2.0)).norm() < 1e-12);
    }
}
