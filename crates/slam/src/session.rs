//! What every session has in common: the [`Update`] it answers each observation with, and the
//! [`Session`] trait the shells (CLI, ROS 2 node, fleet process, Python) drive.

use crate::SlamError;
use serde::Serialize;
use slamkit_core::{Observation, Pose3};
use std::path::Path;

/// How well the session knows where the robot is after an observation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TrackingStatus {
    /// Not started: no usable observation yet, or (localising in a map) the global search has
    /// not found the robot yet. The pose, if any, is not to be trusted.
    Initialising,
    /// The observation was matched to the map: the pose is a measurement.
    Tracking,
    /// The observation could not be matched; the pose is a prediction (odometry, motion model).
    Predicted,
    /// Tracking was lost; the session is searching the map for the robot again.
    Lost,
}

/// What changed in the map with one observation.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct MapChange {
    /// Keyframes added to the map.
    pub keyframes_added: usize,
    /// Loop closures accepted (each moves earlier keyframes).
    pub loop_closures: usize,
    /// True when earlier keyframes moved (pose-graph optimisation, a resampled particle set):
    /// anything drawn from the map should be redrawn.
    pub map_moved: bool,
}

/// A session's answer to one observation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Update {
    /// Time of the observation \[s\].
    pub timestamp: f64,
    /// `map_from_base` at that time: the session's best estimate now (for a particle filter,
    /// its best particle's), `None` when it has none yet.
    pub pose: Option<Pose3>,
    /// How far to trust `pose`.
    pub status: TrackingStatus,
    /// What changed in the map.
    pub map: MapChange,
}

/// An online SLAM or localisation session for one robot rig.
///
/// Observations go in one at a time, in time order (a [`crate::Collator`] restores that order
/// when sources interleave). Kinds of observation the session does not use are counted and
/// ignored, so one stream can feed any session.
pub trait Session {
    /// Takes one observation; returns an update when it moved the estimate (a scan, a frame),
    /// `None` when the observation was only stored for the next one (a range or IMU reading) or
    /// not used.
    fn push(&mut self, observation: Observation) -> Option<Update>;

    /// Writes the map as it stands to `path` (a `.skmap` file), atomically.
    fn save(&self, path: &Path) -> Result<(), SlamError>;
}
