//! Timestamped trajectories and interpolation between their poses.
//!
//! Interpolation is what lets a trajectory be compared with another sampled at other times
//! (ground truth at 100 Hz, camera at 30 Hz) or with a sensor's timestamp: translation is
//! interpolated linearly and rotation by slerp, `q(α) = q_a (q_a⁻¹ q_b)^α` (K. Shoemake,
//! "Animating rotation with quaternion curves", SIGGRAPH 1985), along the shorter arc.

use crate::Pose3;
use nalgebra::{Translation3, UnitQuaternion};

/// A pose with the time it holds at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StampedPose {
    /// Time \[s\].
    pub timestamp: f64,
    /// `world_from_body` at that time.
    pub pose: Pose3,
}

/// A sequence of timestamped poses, in the order they were produced.
///
/// The order is kept as given: some real logs step backwards in time, and their file order is
/// the physical order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trajectory {
    /// The poses, in order.
    pub poses: Vec<StampedPose>,
}

impl Trajectory {
    /// An empty trajectory.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends a pose.
    pub fn push(&mut self, timestamp: f64, pose: Pose3) {
        self.poses.push(StampedPose { timestamp, pose });
    }

    /// Number of poses.
    pub fn len(&self) -> usize {
        self.poses.len()
    }

    /// True when there is no pose.
    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// Length of the path through all positions \[m\].
    pub fn path_length_m(&self) -> f64 {
        self.poses
            .windows(2)
            .map(|w| (w[1].pose.translation.vector - w[0].pose.translation.vector).norm())
            .sum()
    }

    /// True when every timestamp is finite and none is earlier than the one before it: the
    /// precondition for [`Self::interpolate`]'s fast path.
    pub fn is_sorted(&self) -> bool {
        self.poses.iter().all(|p| p.timestamp.is_finite())
            && self
                .poses
                .windows(2)
                .all(|w| w[0].timestamp <= w[1].timestamp)
    }

    /// Largest difference, pose by pose, of timestamps or homogeneous-matrix entries; `None`
    /// when the lengths differ. What a file round trip must keep near zero.
    pub fn max_difference(&self, other: &Trajectory) -> Option<f64> {
        if self.len() != other.len() {
            return None;
        }
        let diff = self
            .poses
            .iter()
            .zip(&other.poses)
            .map(|(p, q)| {
                let dm = (p.pose.to_homogeneous() - q.pose.to_homogeneous())
                    .abs()
                    .max();
                dm.max((p.timestamp - q.timestamp).abs())
            })
            .fold(0.0, f64::max);
        Some(diff)
    }

    /// A copy in time order. The sort is stable, so poses with equal timestamps keep their
    /// order; poses whose timestamp is NaN or infinite cannot be placed in time and are dropped.
    pub fn sorted_by_time(&self) -> Trajectory {
        let mut poses: Vec<StampedPose> = self
            .poses
            .iter()
            .filter(|p| p.timestamp.is_finite())
            .copied()
            .collect();
        poses.sort_by(|a, b| a.timestamp.total_cmp(&b.timestamp));
        Trajectory { poses }
    }

    /// The pose at time `t` \[s\], interpolated between the poses just before and after it.
    ///
    /// Returns `None` when `t` is not finite or lies outside `[first, last]` timestamp: the
    /// trajectory says nothing there, and extrapolating would invent motion. At a timestamp that
    /// occurs several times, the last of those poses is returned.
    ///
    /// Interpolation runs on the poses in time order. A sorted trajectory is binary-searched in
    /// O(log n); an unsorted one is sorted into a temporary copy first (O(n log n) per call), so
    /// callers querying an unsorted trajectory many times should call [`Self::sorted_by_time`]
    /// once and interpolate on the result.
    pub fn interpolate(&self, t: f64) -> Option<Pose3> {
        if !t.is_finite() {
            return None;
        }
        if self.is_sorted() {
            interpolate_sorted(&self.poses, t)
        } else {
            interpolate_sorted(&self.sorted_by_time().poses, t)
        }
    }
}

/// [`Trajectory::interpolate`] on poses already in time order with finite timestamps.
fn interpolate_sorted(poses: &[StampedPose], t: f64) -> Option<Pose3> {
    // first pose strictly after t; the one before it is at or before t
    let after = poses.partition_point(|p| p.timestamp <= t);
    let a = poses.get(after.checked_sub(1)?)?;
    if a.timestamp == t {
        return Some(a.pose);
    }
    let b = poses.get(after)?;
    let alpha = (t - a.timestamp) / (b.timestamp - a.timestamp);
    let translation = a
        .pose
        .translation
        .vector
        .lerp(&b.pose.translation.vector, alpha);
    let delta = a.pose.rotation.inverse() * b.pose.rotation;
    let rotation = a.pose.rotation * UnitQuaternion::from_scaled_axis(delta.scaled_axis() * alpha);
    Some(Pose3::from_parts(Translation3::from(translation), rotation))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Quaternion, Vector3};
    use std::f64::consts::PI;

    fn yaw_pose(x: f64, yaw: f64) -> Pose3 {
        Pose3::new(Vector3::new(x, 0.0, 1.0), Vector3::z() * yaw)
    }

    fn close(a: &Pose3, b: &Pose3) -> bool {
        (a.translation.vector - b.translation.vector).norm() < 1e-12
            && a.rotation.angle_to(&b.rotation) < 1e-12
    }

    fn traj(stamps_and_poses: &[(f64, Pose3)]) -> Trajectory {
        let mut tr = Trajectory::new();
        for (t, p) in stamps_and_poses {
            tr.push(*t, *p);
        }
        tr
    }

    #[test]
    fn max_difference_sees_time_translation_and_length() {
        let a = traj(&[(1.0, yaw_pose(0.0, 0.0)), (2.0, yaw_pose(1.0, 0.5))]);
        assert_eq!(a.max_difference(&a), Some(0.0));
        let shifted = traj(&[(1.0, yaw_pose(0.0, 0.0)), (2.25, yaw_pose(1.5, 0.5))]);
        assert_eq!(a.max_difference(&shifted), Some(0.5));
        let late = traj(&[(1.0, yaw_pose(0.0, 0.0)), (2.75, yaw_pose(1.0, 0.5))]);
        assert_eq!(a.max_difference(&late), Some(0.75));
        assert_eq!(a.max_difference(&traj(&[(1.0, yaw_pose(0.0, 0.0))])), None);
    }

    #[test]
    fn interpolates_translation_linearly_and_rotation_by_slerp() {
        let tr = traj(&[(1.0, yaw_pose(0.0, 0.0)), (3.0, yaw_pose(4.0, 1.0))]);
        let mid = tr.interpolate(1.5).unwrap();
        assert!(close(&mid, &yaw_pose(1.0, 0.25)), "{mid}");
    }

    #[test]
    fn rotation_takes_the_shorter_arc() {
        // 170° to -170° about z passes through 180°, not through 0
        let tr = traj(&[
            (0.0, yaw_pose(0.0, 170_f64.to_radians())),
            (1.0, yaw_pose(0.0, -170_f64.to_radians())),
        ]);
        assert!(close(&tr.interpolate(0.5).unwrap(), &yaw_pose(0.0, PI)));
        // q and -q are the same rotation: no motion in between
        let q = yaw_pose(0.0, 0.3).rotation;
        let minus_q = UnitQuaternion::new_unchecked(-Quaternion::from(q.coords));
        let tr = traj(&[
            (0.0, Pose3::from_parts(Translation3::identity(), q)),
            (1.0, Pose3::from_parts(Translation3::identity(), minus_q)),
        ]);
        assert!(tr.interpolate(0.5).unwrap().rotation.angle_to(&q) < 1e-12);
    }

    #[test]
    fn ends_and_outside_of_range() {
        let tr = traj(&[
            (1.0, yaw_pose(0.0, 0.0)),
            (2.0, yaw_pose(1.0, 0.5)),
            (4.0, yaw_pose(2.0, 1.0)),
        ]);
        assert!(close(&tr.interpolate(1.0).unwrap(), &yaw_pose(0.0, 0.0)));
        assert!(close(&tr.interpolate(2.0).unwrap(), &yaw_pose(1.0, 0.5)));
        assert!(close(&tr.interpolate(4.0).unwrap(), &yaw_pose(2.0, 1.0)));
        assert!(close(&tr.interpolate(3.0).unwrap(), &yaw_pose(1.5, 0.75)));
        for t in [0.999, 4.001, f64::NAN, f64::INFINITY] {
            assert_eq!(tr.interpolate(t), None, "{t}");
        }
        assert_eq!(Trajectory::new().interpolate(0.0), None);
        let single = traj(&[(5.0, yaw_pose(1.0, 0.0))]);
        assert!(close(
            &single.interpolate(5.0).unwrap(),
            &yaw_pose(1.0, 0.0)
        ));
        assert_eq!(single.interpolate(5.1), None);
    }

    #[test]
    fn unsorted_input_interpolates_in_time_order() {
        let sorted = traj(&[
            (1.0, yaw_pose(0.0, 0.0)),
            (2.0, yaw_pose(1.0, 0.5)),
            (4.0, yaw_pose(2.0, 1.0)),
        ]);
        let shuffled = traj(&[
            (4.0, yaw_pose(2.0, 1.0)),
            (f64::NAN, yaw_pose(9.0, 0.0)),
            (1.0, yaw_pose(0.0, 0.0)),
            (2.0, yaw_pose(1.0, 0.5)),
        ]);
        assert!(sorted.is_sorted());
        assert!(!shuffled.is_sorted());
        assert_eq!(shuffled.sorted_by_time(), sorted);
        for t in [1.0, 1.3, 2.0, 2.5, 3.9, 4.0] {
            assert!(
                close(
                    &shuffled.interpolate(t).unwrap(),
                    &sorted.interpolate(t).unwrap()
                ),
                "{t}"
            );
        }
    }

    #[test]
    fn repeated_timestamp_gives_the_last_pose() {
        let tr = traj(&[
            (1.0, yaw_pose(0.0, 0.0)),
            (2.0, yaw_pose(1.0, 0.0)),
            (2.0, yaw_pose(3.0, 0.0)),
            (3.0, yaw_pose(5.0, 0.0)),
        ]);
        assert!(close(&tr.interpolate(2.0).unwrap(), &yaw_pose(3.0, 0.0)));
        assert!(close(&tr.interpolate(2.5).unwrap(), &yaw_pose(4.0, 0.0)));
    }
}
