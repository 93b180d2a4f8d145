//! Rigid-body poses in 2D and 3D, and conversions between them.

use nalgebra::{Isometry2, Isometry3, Translation3, UnitQuaternion, Vector3};

/// A rigid transform in the plane: `target_from_source`.
pub type Pose2 = Isometry2<f64>;
/// A rigid transform in space: `target_from_source`.
pub type Pose3 = Isometry3<f64>;

/// Lifts a planar pose into 3D: z = 0, rotation about the z axis.
pub fn pose2_to_pose3(pose: &Pose2) -> Pose3 {
    Pose3::from_parts(
        Translation3::new(pose.translation.x, pose.translation.y, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), pose.rotation.angle()),
    )
}

/// Projects a 3D pose onto the plane: keeps x, y and the yaw angle.
pub fn pose3_to_pose2(pose: &Pose3) -> Pose2 {
    let (_, _, yaw) = pose.rotation.euler_angles();
    Pose2::new(
        nalgebra::Vector2::new(pose.translation.x, pose.translation.y),
        yaw,
    )
}

/// Wraps an angle into (−π, π].
pub fn wrap_angle(angle_rad: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut a = angle_rad % two_pi;
    if a <= -std::f64::consts::PI {
        a += two_pi;
    } else if a > std::f64::consts::PI {
        a -= two_pi;
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn planar_round_trip() {
        let p = Pose2::new(nalgebra::Vector2::new(1.5, -2.0), 2.5);
        let back = pose3_to_pose2(&pose2_to_pose3(&p));
        assert!((back.translation.vector - p.translation.vector).norm() < 1e-12);
        assert!((back.rotation.angle() - 2.5).abs() < 1e-12);
    }

    #[test]
    fn wrap_angle_range() {
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.5) - 0.5).abs() < 1e-12);
        assert!((wrap_angle(-7.0) - (-7.0 + 2.0 * PI)).abs() < 1e-12);
    }
}
