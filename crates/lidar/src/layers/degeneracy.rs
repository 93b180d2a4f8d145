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

/// The correction from `predicted` to `matched` kept along the directions in which
/// `information` has an eigenvalue of at least `min_eigenvalue`, the rest decided by a prior on
/// the prediction: in twist coordinates `ε`, the minimum of
/// `(ε − ε_m)ᵀ H_s (ε − ε_m) + w ε_θ² + p |ε|²`, where `H_s` is `information` without its weak
/// eigen-directions, `ε_m` the match, `w` = `heading_weight` (a heading prior, in the units of
/// `information`: points times lever arm squared \[m²\]) and `p` a vanishing regulariser.
/// With `w` = 0 the match is kept along the strong directions and the prediction along the
/// others (Zhang et al.'s remapping). With a heading prior, a direction that mixes heading and
/// translation (a turn about a pillar's centre) is pinned by the two together: the scan fixes
/// where the pillar is, the prior which way the drone faces, and so the sideways position.
pub fn remap(
    predicted: &Pose2,
    matched: &Pose2,
    information: &Matrix3<f64>,
    min_eigenvalue: f64,
    heading_weight: f64,
) -> Pose2 {
    let eps = se2_log(&(predicted.inverse() * matched));
    let eigen = information.symmetric_eigen();
    let v = eigen.eigenvectors;
    // in the eigenbasis (y = Vᵀε) the scan's part is diagonal, the heading prior w q qᵀ with
    // q = the eigenvectors' heading components: Sherman–Morrison, exact even where the
    // diagonal is only the regulariser (no ill-conditioned 3×3 inverse)
    let strong = eigen
        .eigenvalues
        .map(|l| if l >= min_eigenvalue { l } else { 0.0 });
    let diagonal = strong.map(|l| l + REGULARISER);
    let b = strong.component_mul(&(v.transpose() * eps));
    // a weak direction is turned by the heading prior only when it is mostly a turn (a
    // pillar's arc), not a slide with a little turn in it (a wall seen slightly askew), which
    // a small heading error would send far along the slide
    let min_turn = 1.0 / (1.0 + MAX_LEVER_M * MAX_LEVER_M).sqrt();
    let q = Vector3::from_fn(|i, _| {
        let turn = v[(2, i)];
        if strong[i] > 0.0 || turn.abs() >= min_turn {
            turn
        } else {
            0.0
        }
    });
    let inv_b = b.component_div(&diagonal);
    let inv_q = q.component_div(&diagonal);
    let w = heading_weight.max(0.0);
    let y = inv_b - inv_q * (w * q.dot(&inv_b) / (1.0 + w * q.dot(&inv_q)));
    predicted * se2_exp(&(v * y))
}

/// Weight of the prior that keeps directions neither the scan nor the heading prior pins at
/// the prediction (in points): small enough not to move the pinned ones.
const REGULARISER: f64 = 1e-9;

/// Longest lever arm of a weak direction the heading prior pins \[m\].
const MAX_LEVER_M: f64 = 3.0;

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
        let fixed = se2_log(&(predicted.inverse() * remap(&predicted, &matched, &h, 5.0, 0.0)));
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
        let kept = remap(&predicted, &matched, &h, 5.0, 0.0);
        assert!((kept.translation.vector - matched.translation.vector).norm() < 1e-9);
    }

    #[test]
    fn a_heading_prior_pins_the_turn_about_a_pillar() {
        // a pillar of radius 0.2 m, 2 m ahead, seen over ±60° of its arc (radial normals)
        let centre = Point2::new(2.0, 0.0);
        let (points, normals): (Vec<_>, Vec<_>) = (0..101)
            .map(|i| {
                let a = std::f64::consts::PI + (f64::from(i) / 50.0 - 1.0) * 1.05;
                let n = Vector2::new(a.cos(), a.sin());
                (centre + n * 0.2, Some(n))
            })
            .unzip();
        let h = scan_information(&points, &normals);
        assert!(weakest(&h) < 1.0, "the turn about the pillar is free: {h}");
        // the true correction is a pure shift; ICP also turned 0.1 rad about the pillar
        let predicted = Pose2::new(Vector2::new(1.0, -2.0), 0.3);
        let truth = predicted * se2_exp(&Vector3::new(0.03, -0.04, 0.0));
        let about = Pose2::new(centre.coords, 0.0);
        let matched = truth * about * Pose2::new(Vector2::zeros(), 0.1) * about.inverse();
        let error = |p: &Pose2| (p.translation.vector - truth.translation.vector).norm();
        let without = remap(&predicted, &matched, &h, 20.0, 0.0);
        let with = remap(&predicted, &matched, &h, 20.0, 1e6);
        // without the prior the sideways part of the true shift is lost with the turn
        assert!(error(&without) > 0.02, "{}", error(&without));
        assert!(error(&with) < 0.003, "{}", error(&with));
        assert!((with.rotation.angle() - truth.rotation.angle()).abs() < 1e-3);
        // a wall seen slightly askew: the slide along it is not turned into a heading
        let wall: Vec<Point2<f64>> = (0..81)
            .map(|i| Point2::new(1.0, -2.0 + 0.05 * f64::from(i)))
            .collect();
        let wall_normals = vec![Some(Vector2::new(-1.0, 0.0)); wall.len()];
        let h = scan_information(&wall, &wall_normals);
        let slid = predicted * se2_exp(&Vector3::new(0.01, 0.5, 0.01));
        let kept = se2_log(&(predicted.inverse() * remap(&predicted, &slid, &h, 20.0, 1e6)));
        assert!(kept.y.abs() < 1e-3, "{kept}");
    }
}
