//! Scan preprocessing: beam end points in the base frame, voxel downsampling, and surface
//! normals from local principal component analysis (the normals point-to-line ICP needs;
//! Censi 2008 takes them from the two nearest points, PCA over a few neighbours is the same
//! idea made robust to range noise).

use crate::nn::{GridIndex, NearestNeighbours};
use nalgebra::{Matrix2, Point2, Vector2};
use slamkit_core::LaserScan;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// The end points of the beams of `scan` with range in `[min_range_m, max_range_m)` and below the
/// scanner's own "no return" range, in the robot base frame. NaN, negative and no-return
/// readings are dropped.
pub fn scan_points(scan: &LaserScan, min_range_m: f64, max_range_m: f64) -> Vec<Point2<f64>> {
    scan.ranges_m
        .iter()
        .enumerate()
        .filter(|&(i, r)| scan.is_hit(i) && *r >= min_range_m && *r < max_range_m)
        .map(|(i, r)| {
            let (s, c) = scan.beam_angle_rad(i).sin_cos();
            scan.base_from_laser * Point2::new(r * c, r * s)
        })
        .collect()
}

/// Keeps the first point falling in each square voxel of side `voxel_m`, in input order (so the
/// result is deterministic). A non-positive or non-finite voxel size keeps every point.
pub fn voxel_downsample(points: &[Point2<f64>], voxel_m: f64) -> Vec<Point2<f64>> {
    if !(voxel_m.is_finite() && voxel_m > 0.0) {
        return points.to_vec();
    }
    let mut seen = VoxelMap::with_capacity_and_hasher(points.len(), Default::default());
    points
        .iter()
        .filter(|p| seen.insert(voxel_key(p, voxel_m), ()).is_none())
        .copied()
        .collect()
}

/// A hash map keyed by voxel coordinates, with a multiply–rotate hash (the "Fx" hash of the
/// Firefox and rustc hash tables) instead of the default SipHash: voxel keys come from our own
/// points, so flooding resistance buys nothing, and hashing was a few percent of ICP-SLAM.
pub type VoxelMap<V> = HashMap<(i64, i64), V, BuildHasherDefault<VoxelHasher>>;

/// The hasher of [`VoxelMap`].
#[derive(Debug, Default, Clone, Copy)]
pub struct VoxelHasher {
    hash: u64,
}

impl Hasher for VoxelHasher {
    fn finish(&self) -> u64 {
        self.hash
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, v: u64) {
        self.hash = (self.hash.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }

    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }
}

/// Integer voxel coordinates of `p` for voxels of side `voxel_m`.
pub fn voxel_key(p: &Point2<f64>, voxel_m: f64) -> (i64, i64) {
    (floor_i64(p.x / voxel_m), floor_i64(p.y / voxel_m))
}

/// `v.floor() as i64` (saturating, NaN to 0), without the library call `floor` compiles to on
/// baseline x86-64 (a tenth of the grid query's time, a few percent of ICP-SLAM's, went there).
pub(crate) fn floor_i64(v: f64) -> i64 {
    let t = v as i64;
    if (t as f64) > v {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// Cells of the normals' grid index per search radius. Any size gives the same neighbours;
/// on MIT CSAIL's 1988 scans (0.5 m radius, 6 neighbours) 1 / 2 / 4 / 8 / 16 cells per radius
/// took 0.91 / 0.68 / 0.61 / 0.64 / 0.95 s in one run (a kiddo k-d tree: 1.4 s).
const NORMAL_CELLS_PER_RADIUS: f64 = 4.0;

/// Unit normal of each point from the PCA of its `neighbours` nearest points within
/// `max_radius_m`: the eigenvector of the smallest eigenvalue of their covariance. `None` when
/// fewer than 3 neighbours are close enough or the neighbourhood is not line-like (smallest over
/// largest eigenvalue above `max_flatness`, e.g. a corner or scattered clutter). Neighbours at
/// equal distances are taken by index, so the normals do not depend on how the points are
/// indexed. The neighbours come from a grid ([`GridIndex::nearest_k_within`]): every keyframe
/// of a map needs its normals before localisation starts, and a k-d tree per scan made that a
/// third of localising MIT CSAIL.
pub fn estimate_normals(
    points: &[Point2<f64>],
    neighbours: usize,
    max_radius_m: f64,
    max_flatness: f64,
) -> Vec<Option<Vector2<f64>>> {
    let index = GridIndex::new(
        points.to_vec(),
        None,
        max_radius_m / NORMAL_CELLS_PER_RADIUS,
    );
    points
        .iter()
        .map(|p| {
            let near: Vec<Point2<f64>> = index
                .nearest_k_within(p, neighbours.max(3), max_radius_m)
                .iter()
                .filter_map(|n| index.point(n.index).copied())
                .collect();
            line_normal(&near, max_flatness)
        })
        .collect()
}

/// Normal of the best-fit line through `pts`, or `None` when they do not look like a line.
fn line_normal(pts: &[Point2<f64>], max_flatness: f64) -> Option<Vector2<f64>> {
    if pts.len() < 3 {
        return None;
    }
    let n = pts.len() as f64;
    let mean = pts.iter().fold(Vector2::zeros(), |acc, p| acc + p.coords) / n;
    let cov = pts.iter().fold(Matrix2::zeros(), |acc, p| {
        let d = p.coords - mean;
        acc + d * d.transpose()
    }) / n;
    smallest_eigenvector(&cov, max_flatness)
}

/// Unit eigenvector of the smaller eigenvalue of the symmetric 2×2 `cov`, or `None` when the
/// larger is not positive or the smaller over the larger exceeds `max_flatness`. Closed form
/// (the roots of the characteristic polynomial), where nalgebra's general symmetric
/// eigensolver iterates: a fifth of the normals' time went there.
fn smallest_eigenvector(cov: &Matrix2<f64>, max_flatness: f64) -> Option<Vector2<f64>> {
    let (a, b, c) = (cov[(0, 0)], 0.5 * (cov[(0, 1)] + cov[(1, 0)]), cov[(1, 1)]);
    let mid = 0.5 * (a + c);
    let spread = (0.5 * (a - c)).hypot(b);
    let (l_small, l_large) = (mid - spread, mid + spread);
    if l_large.is_nan() || l_large <= 0.0 || l_small / l_large > max_flatness {
        return None;
    }
    // (cov − λ I) v = 0: either row gives v; the longer is the better conditioned.
    let from_first = Vector2::new(b, l_small - a);
    let from_second = Vector2::new(l_small - c, b);
    let v = if from_first.norm_squared() >= from_second.norm_squared() {
        from_first
    } else {
        from_second
    };
    let norm = v.norm();
    (norm > 0.0 && norm.is_finite()).then(|| v / norm)
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_core::Pose2;

    #[test]
    fn floor_matches_the_library() {
        for v in [
            -2.5,
            -2.0,
            -1e-300,
            -0.0,
            0.0,
            0.7,
            3.0,
            1e11 + 0.5,
            -1e11 - 0.5,
            1e300,
            -1e300,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ] {
            assert_eq!(floor_i64(v), v.floor() as i64, "{v}");
        }
    }

    #[test]
    fn points_skip_bad_beams_and_apply_mounting() {
        let scan = LaserScan {
            timestamp: 0.0,
            angle_min_rad: 0.0,
            angle_increment_rad: std::f64::consts::FRAC_PI_2,
            ranges_m: vec![1.0, f64::NAN, -2.0, 50.0, 0.01],
            max_range_m: 50.0,
            odometry: None,
            base_from_laser: Pose2::new(Vector2::new(0.5, 0.0), 0.0),
        };
        let pts = scan_points(&scan, 0.05, 40.0);
        assert_eq!(pts.len(), 1);
        assert!((pts[0] - Point2::new(1.5, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn voxel_map_keeps_distinct_keys_apart() {
        let mut map = VoxelMap::default();
        for i in -50..50 {
            for j in -50..50 {
                map.insert((i, j), i * 1000 + j);
            }
        }
        assert_eq!(map.len(), 10_000);
        assert_eq!(map.get(&(-3, 7)), Some(&-2993));
        assert_eq!(map.get(&(50, 0)), None);
    }

    #[test]
    fn voxel_keeps_first_per_cell() {
        let pts = vec![
            Point2::new(0.01, 0.01),
            Point2::new(0.02, 0.03),
            Point2::new(0.2, 0.0),
            Point2::new(-0.01, 0.0),
        ];
        let out = voxel_downsample(&pts, 0.1);
        assert_eq!(out, vec![pts[0], pts[2], pts[3]]);
        assert_eq!(voxel_downsample(&pts, f64::NAN).len(), 4);
    }

    #[test]
    fn closed_form_eigenvector_matches_the_general_solver() {
        let mut checked = 0;
        for i in 0..200 {
            let t = i as f64 * 0.37;
            // covariances of every orientation, from nearly a line to nearly round
            let (l1, l2) = (1.0 + (i % 7) as f64, 1e-6 + (i % 5) as f64 * 0.1);
            let r = Matrix2::new(t.cos(), -t.sin(), t.sin(), t.cos());
            let cov = r * Matrix2::new(l1, 0.0, 0.0, l2) * r.transpose();
            let eig = cov.symmetric_eigen();
            let small = if eig.eigenvalues[0] <= eig.eigenvalues[1] {
                0
            } else {
                1
            };
            let want = eig.eigenvectors.column(small).into_owned();
            let flatness = eig.eigenvalues[small] / eig.eigenvalues[1 - small];
            match smallest_eigenvector(&cov, 0.2) {
                Some(got) => {
                    assert!(flatness <= 0.2 + 1e-12, "{i}");
                    // the same axis, either sign
                    assert!(
                        (got.dot(&want).abs() - 1.0).abs() < 1e-12,
                        "{i}: {got} vs {want}"
                    );
                    checked += 1;
                }
                None => assert!(flatness > 0.2 - 1e-12, "{i}"),
            }
        }
        assert!(checked > 100);
        assert_eq!(smallest_eigenvector(&Matrix2::identity(), 0.5), None);
        assert_eq!(smallest_eigenvector(&Matrix2::zeros(), 0.5), None);
        let nan = Matrix2::new(f64::NAN, 0.0, 0.0, 1.0);
        assert_eq!(smallest_eigenvector(&nan, 0.5), None);
        let axis = smallest_eigenvector(&Matrix2::new(4.0, 0.0, 0.0, 0.0), 0.1).unwrap();
        assert!((axis.y.abs() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn normals_of_a_wall_and_a_blob() {
        let wall: Vec<Point2<f64>> = (0..20).map(|i| Point2::new(i as f64 * 0.1, 2.0)).collect();
        for n in estimate_normals(&wall, 5, 0.5, 0.1) {
            let n = n.unwrap();
            assert!(n.x.abs() < 1e-9 && (n.y.abs() - 1.0).abs() < 1e-9);
        }
        let blob = vec![
            Point2::new(0.0, 0.0),
            Point2::new(0.1, 0.0),
            Point2::new(0.0, 0.1),
            Point2::new(0.1, 0.1),
        ];
        assert!(estimate_normals(&blob, 4, 0.5, 0.1)
            .iter()
            .all(Option::is_none));
    }
}
