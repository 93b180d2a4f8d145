//! Map updates: what a robot of a fleet sends about its 2D lidar map, incrementally, instead of
//! its sensor stream (issue 22, item 1).
//!
//! A robot's map only ever gains keyframes and pose-graph edges; loop closure moves the
//! keyframes it already has. So a robot sends three kinds of message:
//! * **keyframes**: a batch of new consecutive keyframes, each its scan (ranges in whole
//!   millimetres, as the `.skmap` file keeps them) and its pose;
//! * **edges**: the new pose-graph edges, and the keyframes whose pose moved (loop closure) more
//!   than a tolerance since it was last sent, at their new pose;
//! * **status**: the robot's pose and tracking status, and how many messages it has sent, so a
//!   peer knows what it lacks even when the last messages were lost.
//!
//! Keyframes and edges messages carry a sequence number (0, 1, 2, ... per robot, both kinds on
//! one count). A receiver ([`RobotInbox`]) applies them in sequence order only: a message that
//! arrives early is held until the ones before it arrive, a duplicate is recognised and
//! ignored, and a gap is listed ([`RobotInbox::missing`]) so the receiver can fetch it by
//! number. The map a receiver holds is therefore a function of how many messages it has
//! applied, whatever the order and repetitions they came in.
//!
//! The place recognition of [`crate::merge`] matches keyframe submaps (correlative search and
//! ICP on the scans themselves), so the scans are the place descriptors here: no separate
//! descriptor is sent.
//!
//! Wire format of one message (little-endian; every message stands alone):
//! ```text
//! magic     4 bytes   "SKMU"
//! version   u16 major, u16 minor      the map file's (crate::map_file::FORMAT_VERSION): a
//!                                     reader refuses a newer major version
//! kind      u8                        0 keyframes, 1 edges, 2 status
//! sequence  varint                    (status: the number of messages sent so far)
//! body      raw deflate               the records below
//! ```
//! Records use LEB128 varints; poses are whole multiples of [`POSITION_STEP_M`] and
//! [`ANGLE_STEP_RAD`], each pose of a list coded as the difference from the one before it
//! (neighbouring keyframes are close), and ranges as the difference from the beam before;
//! deflate then finds what repeats across the batch. On the Intel log this costs 4.75 % of the
//! bytes of the scans as ROS 2 would send them ([`laser_scan_cdr_bytes`]; measured by the
//! `map_updates_intel` test).

pub mod inbox;
pub mod outbox;
mod wire;

pub use inbox::{Applied, RobotInbox};
pub use outbox::{UpdateConfig, UpdateOutbox};

use crate::lidar::MapKeyframe;
use crate::session::TrackingStatus;
use slamkit_core::Pose2;
use slamkit_lidar::pose_graph::Edge;

/// The first bytes of every update message.
pub const UPDATE_MAGIC: [u8; 4] = *b"SKMU";
/// Poses in messages are whole multiples of this \[m\] (0.1 mm).
pub const POSITION_STEP_M: f64 = 1e-4;
/// ... and of this \[rad\] (0.0006°).
pub const ANGLE_STEP_RAD: f64 = 1e-5;

/// Which stream of a robot a message belongs to (the last part of its Zenoh key).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// New keyframes.
    Keyframes,
    /// New pose-graph edges and moved keyframes.
    Edges,
    /// The robot's pose and message count.
    Status,
}

impl Stream {
    /// The stream's name in keys: `keyframes`, `edges`, `status`.
    pub fn name(self) -> &'static str {
        match self {
            Stream::Keyframes => "keyframes",
            Stream::Edges => "edges",
            Stream::Status => "status",
        }
    }
}

/// What a robot says about itself in a status message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotStatus {
    /// Time of the robot's newest observation \[s\].
    pub timestamp: f64,
    /// How well it knows where it is.
    pub tracking: TrackingStatus,
    /// `map_from_base` now, in the robot's own map frame.
    pub pose: Option<Pose2>,
    /// Keyframes in its map.
    pub keyframes: usize,
}

/// The content of a message.
#[derive(Debug, Clone, PartialEq)]
pub enum UpdateBody {
    /// Keyframes `first`, `first + 1`, ... of the robot's map.
    Keyframes {
        /// Index of the first.
        first: usize,
        /// The keyframes (ranges in whole millimetres, poses on the message grid).
        keyframes: Vec<MapKeyframe>,
    },
    /// New edges, and keyframes that moved.
    Edges {
        /// Pose-graph edges, in the order the robot added them.
        edges: Vec<Edge>,
        /// `(keyframe, map_from_base)` for each keyframe that moved, in increasing keyframe
        /// order.
        moved: Vec<(usize, Pose2)>,
    },
    /// The robot's status.
    Status(RobotStatus),
}

/// One message: a sequence number and its content.
#[derive(Debug, Clone, PartialEq)]
pub struct MapUpdate {
    /// Position in the robot's sequence (status: the number of keyframes and edges messages
    /// sent before it).
    pub seq: u64,
    /// The content.
    pub body: UpdateBody,
}

impl MapUpdate {
    /// The stream the message belongs to.
    pub fn stream(&self) -> Stream {
        match self.body {
            UpdateBody::Keyframes { .. } => Stream::Keyframes,
            UpdateBody::Edges { .. } => Stream::Edges,
            UpdateBody::Status(_) => Stream::Status,
        }
    }
}

/// A pose moved onto the grid messages carry poses on ([`POSITION_STEP_M`],
/// [`ANGLE_STEP_RAD`]): what the receiver decodes, so the sender can keep what each receiver
/// holds.
///
/// ```
/// use slamkit_core::Pose2;
/// use slamkit_slam::map_updates::quantised;
/// let p = quantised(&Pose2::new([1.23456789, -2.0].into(), 0.1234567));
/// assert!((p.translation.vector.x - 1.2346).abs() < 1e-12);
/// assert_eq!(quantised(&p), p);
/// ```
pub fn quantised(pose: &Pose2) -> Pose2 {
    let [x, y, a] = wire::grid_pose(pose);
    wire::pose_from_grid(x, y, a)
}

/// The bytes of one `sensor_msgs/LaserScan` of `beams` ranges and no intensities as ROS 2
/// serialises it (CDR with its 4-byte encapsulation header: stamp, frame id `laser`, seven
/// `float32`, the ranges as `float32`, an empty intensities sequence): the raw stream that
/// map updates replace.
///
/// ```
/// // the Intel log's 180 beams
/// assert_eq!(slamkit_slam::map_updates::laser_scan_cdr_bytes(180), 780);
/// ```
pub fn laser_scan_cdr_bytes(beams: usize) -> usize {
    let encapsulation = 4;
    let stamp = 8;
    let frame_id = 4 + 8; // length, "laser\0" padded to 4
    let floats = 7 * 4;
    let ranges = 4 + 4 * beams;
    let intensities = 4;
    encapsulation + stamp + frame_id + floats + ranges + intensities
}

#[cfg(test)]
mod tests;
