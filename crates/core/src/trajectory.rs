//! Timestamped trajectories and interpolation between their poses.

use crate::Pose3;

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
}
