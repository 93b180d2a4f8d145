//! Degeneracy-aware correction of a scan match: keep the match only along the directions the
//! scan constrains, and the prediction along the others.
//!
//! A planar lidar with a 3 m range on a drone in a large room often sees one wall, or two
//! parallel ones: the scan then fixes the distance to the wall and the heading, but not the
//! position along it, and ICP slides there on noise and on the few points of clutter (in the
//! `office` flight it slid 0.5 m in 0.6 s while the drone hovered before one wall). Following
//! J. Zhang, M. Kaess and S. Singh, "On degeneracy of optimization-based state estimation
//! problems", ICRA 2016 ("solution remapping"), the information matrix `H = Σ Jᵀ J` of the
//! point-to-line residuals of the scan at its pose is split into eigen-directions; the match's
//! correction of the predicted pose is kept along the directions whose eigenvalue reaches
//! `min_eigenvalue` and dropped along the others, where the motion prior decides.
//!
//! The residual of a point `p` (base frame) with unit normal `n` moved by a small body-frame
//! increment `ε = (εx, εy, εθ)` changes by `J ε` with `J = (nx, ny, ny px − nx py)`; a point
//! without a normal (a corner, clutter) gives the two point-to-point rows `(1, 0, −py)` and
//! `(0, 1, px)`, as ICP uses it. The rotation column is in metres (lever arm), so an eigenvalue
//! counts, roughly, the points that pin the pose along its direction. The correction is split
//! in twist coordinates (the SE(2) logarithm), in which a slide that a scan cannot see is a
//! straight line even when it is large: a turn about the centre of a pillar's arc, a shift
//! along a wall. (Split as a translation and an angle, a 0.45 rad turn about a point 0.65 m
//! away left 7 cm of it in the kept part in the `office` flight.)

use super::velocity::{se2_exp, se2_log};
use nalgebra::{Matrix3, Point2, Vector2, Vector3};
use slamkit_core::Pose2;

/// `Σ Jᵀ J` of the scan's residuals with respect to a body-frame pose increment.
pub fn scan_information(points: &[Point2<f64>], normals: &[Option<Vector2<f64>>]) -> Matrix3<f64> {
    let mut h = Matrix3::zeros();
    let mut add = |j: Vector3<f64>| h += j * j.transpose();
    for (p, n) in points.iter().zip(normals) {
        match n {
            Some(n) => add(Vector3::new(n.x, n.y, n.y * p.x - n.x * p.y)),
            None => {
                add(Vector3::new(1.0, 0.0, -p.y));
                add(Vector3::new(0.0, 1.0, p.x));
            }
        }
    }
    h
}

/// `matched` moved back to `predicted` along every direction in which `information` has an
/// eigenvalue below `min_eigenvalue`; unchanged when the scan constrains every direction.
pub fn remap(
    predicted: &Pose2,
    matched: &Pose2,
    information: &Matrix3<f64>,
    min_eigenvalue: f64,
) -> Pose2 {
    let eps = se2_log(&(predicted.inverse() * matched));
    predicted * se2_exp(&pinned_twist(&eps, information, min_eigenvalue))
}

/// The twist `eps` (a match's correction of the prediction, body frame) kept along every
/// direction in which `information` has an eigenvalue of at least `min_eigenvalue`, zero
/// along the others.
pub fn pinned_twist(
    eps: &Vector3<f64>,
    information: &Matrix3<f64>,
    min_eigenvalue: f64,
) -> Vector3<f64> {
    let eigen = information.symmetric_eigen();
    eigen
        .eigenvalues
        .iter()
        .zip(eigen.eigenvectors.column_iter())
        .filter(|(value, _)| **value >= min_eigenvalue)
        .fold(Vector3::zeros(), |acc, (_, v)| acc + v * v.dot(eps))
}

/// The smallest eigenvalue of `information` (how well the worst direction is pinned).
pub fn weakest(information: &Matrix3<f64>) -> f64 {
    information.symmetric_eigen().eigenvalues.min()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_wall_keeps_the_prediction_along_it_two_walls_keep_the_match() {
        // a wall 1 m ahead (x = 1), seen from y = -1 to 1: normal along x
        let wall: Vec<Point2<f64>> = (0..41)
            .map(|i| Point2::new(1.0, -1.0 + 0.05 * f64::from(i)))
            .collect();
        let normals = vec![Some(Vector2::new(-1.0, 0.0)); wall.len()];
        let h = scan_information(&wall, &normals);
        assert!(weakest(&h) < 1e-9, "nothing pins y: {h}");
        let predicted = Pose2::new(Vector2::new(2.0, 3.0), 0.5);
        let matched = predicted * se2_exp(&Vector3::new(0.05, 0.4, 0.02));
        let fixed = se2_log(&(predicted.inverse() * remap(&predicted, &matched, &h, 5.0)));
        // x and heading from the match, y from the prediction
        assert!(
            (fixed - Vector3::new(0.05, 0.0, 0.02)).norm() < 1e-9,
            "{fixed}"
        );
        // a second wall along x pins y too: the match is kept whole
        let mut both = wall.clone();
        both.extend((0..41).map(|i| Point2::new(-1.0 + 0.05 * f64::from(i), 1.0)));
        let mut both_normals = normals;
        both_normals.extend(vec![Some(Vector2::new(0.0, -1.0)); 41]);
        let h = scan_information(&both, &both_normals);
        assert!(weakest(&h) > 5.0);
        let kept = remap(&predicted, &matched, &h, 5.0);
        assert!((kept.translation.vector - matched.translation.vector).norm() < 1e-9);
    }
}
