//! Ray-cast laser scans in a world of line segments: deterministic fixtures for the tests and
//! benchmarks of the scan matchers, and a way to run them without any dataset.

use nalgebra::{Point2, Vector2};
use slamkit_core::{LaserScan, Pose2};

/// A 2D world made of wall segments.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentWorld {
    /// Wall segments, end points in the world frame \[m\].
    pub segments: Vec<(Point2<f64>, Point2<f64>)>,
}

impl SegmentWorld {
    /// A closed polygon of walls through `corners` (the last joins the first).
    pub fn polygon(corners: &[(f64, f64)]) -> Self {
        let pts: Vec<Point2<f64>> = corners.iter().map(|&(x, y)| Point2::new(x, y)).collect();
        let segments = pts
            .iter()
            .zip(pts.iter().cycle().skip(1))
            .map(|(a, b)| (*a, *b))
            .collect();
        Self { segments }
    }

    /// An asymmetric 12 m × 8 m room with an alcove and two boxes, so every pose is observable.
    pub fn room() -> Self {
        let mut world = Self::polygon(&[
            (-6.0, -4.0),
            (6.0, -4.0),
            (6.0, 1.0),
            (8.0, 1.0),
            (8.0, 3.0),
            (6.0, 3.0),
            (6.0, 4.0),
            (-6.0, 4.0),
        ]);
        for corners in [
            [(1.0, -0.6), (1.8, -0.6), (1.8, 0.2), (1.0, 0.2)],
            [(-2.0, 0.5), (-1.2, 0.9), (-1.6, 1.5), (-2.3, 1.1)],
        ] {
            world.segments.extend(Self::polygon(&corners).segments);
        }
        world
    }

    /// Range along the ray from `origin` in direction `dir` (unit) to the nearest wall, if any.
    pub fn ray_cast(&self, origin: &Point2<f64>, dir: &Vector2<f64>) -> Option<f64> {
        self.segments
            .iter()
            .filter_map(|(a, b)| {
                let e = b - a;
                let denom = dir.x * e.y - dir.y * e.x;
                if denom.abs() < 1e-12 {
                    return None;
                }
                let w = a - origin;
                let t = (w.x * e.y - w.y * e.x) / denom;
                let u = (w.x * dir.y - w.y * dir.x) / denom;
                (t > 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
            })
            .min_by(f64::total_cmp)
    }

    /// A noise-free scan of `beams` beams over `fov_rad` (centred ahead) taken by a laser at the
    /// base origin of a robot at `world_from_base`. Beams that hit nothing read `max_range_m`.
    pub fn scan(
        &self,
        world_from_base: &Pose2,
        beams: usize,
        fov_rad: f64,
        max_range_m: f64,
    ) -> LaserScan {
        let increment = fov_rad / (beams.max(2) - 1) as f64;
        let angle_min = -fov_rad / 2.0;
        let origin = Point2::from(world_from_base.translation.vector);
        let ranges_m = (0..beams)
            .map(|i| {
                let dir = world_from_base.rotation * Vector2::new(1.0, 0.0);
                let dir = nalgebra::Rotation2::new(angle_min + i as f64 * increment) * dir;
                self.ray_cast(&origin, &dir)
                    .filter(|r| *r < max_range_m)
                    .unwrap_or(max_range_m)
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_hits_nearest_wall() {
        let world = SegmentWorld::room();
        let r = world
            .ray_cast(&Point2::new(0.0, 0.0), &Vector2::new(0.0, 1.0))
            .unwrap();
        assert!((r - 4.0).abs() < 1e-12);
        let r = world
            .ray_cast(&Point2::new(0.0, -0.5), &Vector2::new(1.0, 0.0))
            .unwrap();
        assert!((r - 1.0).abs() < 1e-12, "box face at x = 1: {r}");
        let scan = world.scan(&Pose2::identity(), 181, std::f64::consts::PI, 30.0);
        assert_eq!(scan.ranges_m.len(), 181);
        assert!((scan.ranges_m[90] - 1.0).abs() < 1e-9);
    }
}
