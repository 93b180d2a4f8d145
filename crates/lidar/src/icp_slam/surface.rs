//! How much of a scan the map explains, judged fairly on a degraded laser: the score a match
//! is accepted by when ICP's plain goodness ([`crate::icp::goodness`]) falls short.
//!
//! The plain goodness counts a scan point as matched when a map point lies within the final
//! ICP threshold. Three things lower it without the alignment being wrong (issue 24, item 4;
//! docs/experiments/lidar-icp-slam.md, "Degraded logs"):
//!
//! - Returns beyond the surface (glass, mirrors, spurious long readings): the beam passed
//!   through where the map already holds a wall, so the point lies behind it and nothing in
//!   the map can explain it. Such a point says nothing for or against the alignment; it is left
//!   out of the count when it is unmatched.
//! - New ground: a point in a direction where the map holds no surface at all (the robot
//!   moved far since the last scan, or turned towards where it has not looked) cannot be
//!   explained yet; it is left out of the count too when unmatched.
//! - A sparse map (lost beams, a laser whose scans come seldom): its walls have gaps wider than
//!   the threshold, and a point on the wall finds its nearest map point farther along the wall.
//!   The point counts as matched when it lies within the threshold of the surface line through
//!   that point (its normal), the metric point-to-line ICP minimises.
//!
//! Both only ever raise the score above the plain goodness, so a match the plain goodness
//! accepts is accepted the same, and the score is computed only for the others.

use crate::nn::{GridIndex, NearestNeighbours};
use nalgebra::{Point2, Vector2};
use slamkit_core::Pose2;
use std::f64::consts::TAU;

/// Angular width of the bins of the map's surface as seen from the scan \[rad\]: wide enough
/// that a wall 3 m away puts a map point (one per 5 cm voxel) in every bin it crosses, narrow
/// enough that a doorway 0.3 m wide 10 m away still has bins of its own.
const SURFACE_BIN_RAD: f64 = std::f64::consts::PI / 180.0;

/// What a match is scored against.
pub struct SurfaceScore<'a> {
    /// The map, indexed with its normals (world frame).
    pub map: &'a GridIndex,
    /// A point counts as matched within this distance of the map (ICP's final threshold) \[m\].
    pub threshold_m: f64,
    /// A point lies behind the map's surface when it is farther than the surface along its
    /// beam by more than this (ICP's widest correspondence distance: no pairing could have
    /// brought it there) \[m\].
    pub behind_margin_m: f64,
    /// Map points beyond this range from the laser are not part of the surface \[m\].
    pub max_range_m: f64,
}

impl SurfaceScore<'_> {
    /// The fraction of `points` (base frame, beams from `laser` in the base frame) at
    /// `world_from_base` that the map explains, among those it could: see the module
    /// documentation. 0 when fewer than half the points could be explained.
    pub fn goodness(
        &self,
        points: &[Point2<f64>],
        laser: &Point2<f64>,
        world_from_base: &Pose2,
    ) -> f64 {
        let origin = world_from_base * laser;
        let surface = Surface::seen_from(self.map.points(), &origin, self.max_range_m);
        let (mut matched, mut counted) = (0usize, 0usize);
        for p in points {
            let q = world_from_base * p;
            if self.on_surface(&q) {
                matched += 1;
                counted += 1;
            } else if !surface.beyond(&q, self.behind_margin_m) {
                counted += 1;
            }
        }
        // A pose that turns most of the scan towards where the map has nothing, or behind its
        // walls, leaves too few points to judge it by: it keeps ICP's own goodness.
        if 2 * counted < points.len() {
            0.0
        } else {
            matched as f64 / counted as f64
        }
    }

    /// True when `q` is within the threshold of its nearest map point, or of the surface line
    /// through a map point within twice the threshold.
    fn on_surface(&self, q: &Point2<f64>) -> bool {
        let Some(nearest) = self.map.nearest_within(q, 2.0 * self.threshold_m) else {
            return false;
        };
        if nearest.distance_m <= self.threshold_m {
            return true;
        }
        let along_normal = |n: Vector2<f64>, p: &Point2<f64>| n.dot(&(q - p)).abs();
        match (
            self.map.normal(nearest.index),
            self.map.point(nearest.index),
        ) {
            (Some(n), Some(p)) => along_normal(n, p) <= self.threshold_m,
            _ => false,
        }
    }
}

/// The map's surface as seen from one place: per angular bin, the range of the nearest map
/// point (infinite where the map has none: nothing is known there).
struct Surface {
    origin: Point2<f64>,
    nearest_m: Vec<f64>,
}

impl Surface {
    fn seen_from(map: &[Point2<f64>], origin: &Point2<f64>, max_range_m: f64) -> Self {
        let bins = (TAU / SURFACE_BIN_RAD).ceil() as usize;
        let mut surface = Self {
            origin: *origin,
            nearest_m: vec![f64::INFINITY; bins],
        };
        for p in map {
            let (bin, range) = surface.polar(p);
            if range < max_range_m {
                if let Some(nearest) = surface.nearest_m.get_mut(bin) {
                    *nearest = nearest.min(range);
                }
            }
        }
        surface
    }

    /// The bin and range of `p`.
    fn polar(&self, p: &Point2<f64>) -> (usize, f64) {
        let d = p - self.origin;
        let angle = d.y.atan2(d.x).rem_euclid(TAU);
        ((angle / SURFACE_BIN_RAD) as usize, d.norm())
    }

    /// True when `q` lies farther than the surface along its beam by more than `margin_m`, or
    /// in a direction where the map has no surface.
    fn beyond(&self, q: &Point2<f64>, margin_m: f64) -> bool {
        let (bin, range) = self.polar(q);
        self.nearest_m.get(bin).map_or(true, |nearest| {
            !nearest.is_finite() || range > nearest + margin_m
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wall at x = 2 with map points every 0.2 m (a sparse map), normals along x.
    fn sparse_wall() -> GridIndex {
        let points: Vec<Point2<f64>> = (-10..=10)
            .map(|i| Point2::new(2.0, 0.2 * f64::from(i)))
            .collect();
        let normals = vec![Some(Vector2::x()); points.len()];
        GridIndex::new(points, Some(normals), 0.25)
    }

    #[test]
    fn returns_behind_the_wall_and_on_new_ground_do_not_count_and_sparse_walls_do() {
        let map = sparse_wall();
        let score = SurfaceScore {
            map: &map,
            threshold_m: 0.05,
            behind_margin_m: 0.3,
            max_range_m: 30.0,
        };
        let origin = Point2::origin();
        // on the wall between map points (0.1 m from the nearest): matched by the line
        let on_wall: Vec<Point2<f64>> = (0..10)
            .map(|i| Point2::new(2.0, 0.1 + 0.2 * f64::from(i) - 1.0))
            .collect();
        let plain = crate::icp::goodness(&on_wall, &map, &Pose2::identity(), 0.05);
        assert_eq!(plain, 0.0);
        assert_eq!(score.goodness(&on_wall, &origin, &Pose2::identity()), 1.0);
        // plus returns through the wall (along the beams of its map points, the bins the map
        // fills): left out; plus points in front of it: counted
        let mut points = on_wall.clone();
        points.extend((-2..=2).map(|i| Point2::new(6.0, 0.6 * f64::from(i))));
        assert_eq!(score.goodness(&points, &origin, &Pose2::identity()), 1.0);
        points.extend((0..10).map(|i| Point2::new(1.0, 0.1 * f64::from(i) - 0.5)));
        assert_eq!(score.goodness(&points, &origin, &Pose2::identity()), 0.5);
        // new ground, where the map has no surface (behind the robot): left out
        points.extend((0..10).map(|i| Point2::new(-3.0, 0.1 * f64::from(i))));
        assert_eq!(score.goodness(&points, &origin, &Pose2::identity()), 0.5);
        // but not when they are most of the scan: too little left to judge by
        points.extend((0..30).map(|i| Point2::new(-3.0, -0.1 * f64::from(i))));
        assert_eq!(score.goodness(&points, &origin, &Pose2::identity()), 0.0);
        // the scan moved 0.5 m: the wall's points are off the surface
        let moved = Pose2::new(Vector2::new(-0.5, 0.0), 0.0);
        assert!(score.goodness(&on_wall, &origin, &moved) < 0.01);
    }
}
