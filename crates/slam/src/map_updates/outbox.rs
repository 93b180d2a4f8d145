//! [`UpdateOutbox`]: turns a growing ICP-SLAM map into map update messages, in batches.

use super::{quantised, MapUpdate, RobotStatus, UpdateBody};
use crate::lidar::{LiveMap, MapKeyframe};
use crate::session::Update;
use crate::SlamError;
use serde::{Deserialize, Serialize};
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{LaserScan, Pose2};
use slamkit_lidar::pose_graph::Edge;

/// When a robot sends what changed in its map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct UpdateConfig {
    /// New keyframes are sent once this many are waiting (deflate codes each scan against its
    /// batch-mates: on the Intel log a keyframe cost 254 bytes sent alone, 150 in batches of
    /// 8, 140 of 16, 135 of 32)...
    pub batch_keyframes: usize,
    /// ...or once the oldest change waiting is this old \[s of sensor time\].
    pub max_delay_s: f64,
    /// A keyframe sent before is sent again once loop closure moved it this far from the pose
    /// sent \[m\] (the receivers' keyframes are within this of the robot's; on the Intel log
    /// 1 cm cost 183 kB of edges messages, 2 cm 118 kB, 3 cm 98 kB)...
    pub moved_m: f64,
    /// ...or turned it this much \[rad\].
    pub moved_rad: f64,
}

impl Default for UpdateConfig {
    fn default() -> Self {
        Self {
            batch_keyframes: 16,
            max_delay_s: 20.0,
            moved_m: 0.02,
            moved_rad: 0.01,
        }
    }
}

impl UpdateConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), SlamError> {
        if self.batch_keyframes == 0
            || !(self.max_delay_s >= 0.0 && self.moved_m >= 0.0 && self.moved_rad >= 0.0)
        {
            return Err(SlamError::Config(format!(
                "map updates: batch_keyframes {} must be > 0, max_delay_s {}, moved_m {} and \
                 moved_rad {} >= 0",
                self.batch_keyframes, self.max_delay_s, self.moved_m, self.moved_rad
            )));
        }
        Ok(())
    }
}

/// The sending side of map updates for one robot: given the session's map after each scan
/// ([`crate::LidarSlam::live_map`]), it answers the messages due.
///
/// ```
/// use slamkit_core::Pose2;
/// use slamkit_lidar::sim_scan::SegmentWorld;
/// use slamkit_slam::map_updates::{RobotInbox, UpdateConfig, UpdateOutbox};
/// use slamkit_slam::{LidarSlam, LidarSlamConfig};
///
/// let world = SegmentWorld::room();
/// let mut slam = LidarSlam::new(LidarSlamConfig::default(), Pose2::identity())?;
/// let mut outbox = UpdateOutbox::new(UpdateConfig::default())?;
/// let mut inbox = RobotInbox::default();
/// for i in 0..30 {
///     let mut scan = world.scan(&Pose2::new([0.1 * i as f64, 0.0].into(), 0.0), 361, 4.7, 20.0);
///     scan.timestamp = 0.1 * i as f64;
///     slam.push_scan(scan.clone());
///     let map = slam.live_map().expect("a new ICP-SLAM map");
///     for message in outbox.poll(map, scan.timestamp) {
///         inbox.apply(message)?;
///     }
/// }
/// for message in outbox.flush(slam.live_map().expect("a new map")) {
///     inbox.apply(message)?;
/// }
/// assert_eq!(inbox.map().keyframes.len(), slam.map().keyframes.len());
/// # Ok::<(), slamkit_slam::SlamError>(())
/// ```
#[derive(Debug, Clone)]
pub struct UpdateOutbox {
    config: UpdateConfig,
    next_seq: u64,
    edges_sent: usize,
    /// The pose each keyframe sent has at the receivers.
    sent_poses: Vec<Pose2>,
    /// Sensor time of the oldest change not sent yet.
    waiting_since: Option<f64>,
}

impl UpdateOutbox {
    /// An outbox that has sent nothing.
    ///
    /// # Errors
    /// [`SlamError::Config`] for settings out of range.
    pub fn new(config: UpdateConfig) -> Result<Self, SlamError> {
        config.validate()?;
        Ok(Self {
            config,
            next_seq: 0,
            edges_sent: 0,
            sent_poses: Vec::new(),
            waiting_since: None,
        })
    }

    /// The messages due after the session took an observation at `timestamp` \[s\]: none while
    /// a batch fills, the batch once it is full or its oldest change is `max_delay_s` old.
    pub fn poll(&mut self, map: LiveMap<'_>, timestamp: f64) -> Vec<MapUpdate> {
        let new_keyframes = map.keyframes.len().saturating_sub(self.sent_poses.len());
        if new_keyframes == 0 && map.edges.len() <= self.edges_sent {
            return Vec::new();
        }
        let since = *self.waiting_since.get_or_insert(timestamp);
        if new_keyframes >= self.config.batch_keyframes
            || timestamp - since >= self.config.max_delay_s
        {
            self.flush(map)
        } else {
            Vec::new()
        }
    }

    /// Everything not sent yet: the new keyframes (one message), then the new edges and the
    /// keyframes that moved (another), each only when it has content.
    pub fn flush(&mut self, map: LiveMap<'_>) -> Vec<MapUpdate> {
        self.waiting_since = None;
        let mut messages = Vec::new();
        let old = self.sent_poses.len();
        let moved: Vec<(usize, Pose2)> = map
            .keyframes
            .iter()
            .zip(&mut self.sent_poses)
            .enumerate()
            .filter(|(_, (kf, sent))| {
                let d = sent.inverse() * kf.world_from_base;
                d.translation.vector.norm() > self.config.moved_m
                    || d.rotation.angle().abs() > self.config.moved_rad
            })
            .map(|(i, (kf, sent))| {
                *sent = quantised(&kf.world_from_base);
                (i, *sent)
            })
            .collect();
        if map.keyframes.len() > old {
            let keyframes: Vec<MapKeyframe> = map.keyframes[old..]
                .iter()
                .zip(map.scans.get(old..).unwrap_or_default())
                .map(|(kf, scan)| MapKeyframe {
                    world_from_base: quantised(&kf.world_from_base),
                    scan: LaserScan {
                        odometry: None,
                        ..scan.clone()
                    },
                })
                .collect();
            self.sent_poses
                .extend(keyframes.iter().map(|kf| kf.world_from_base));
            messages.push(self.message(UpdateBody::Keyframes {
                first: old,
                keyframes,
            }));
        }
        let edges: Vec<Edge> = map
            .edges
            .get(self.edges_sent..)
            .unwrap_or_default()
            .iter()
            .map(|e| Edge {
                from_from_to: quantised(&e.from_from_to),
                ..*e
            })
            .collect();
        self.edges_sent = map.edges.len();
        if !edges.is_empty() || !moved.is_empty() {
            messages.push(self.message(UpdateBody::Edges { edges, moved }));
        }
        messages
    }

    /// The status message for the session's latest `update` (sequence number: the messages
    /// sent so far).
    pub fn status(&self, update: &Update) -> MapUpdate {
        MapUpdate {
            seq: self.next_seq,
            body: UpdateBody::Status(RobotStatus {
                timestamp: update.timestamp,
                tracking: update.status,
                pose: update.pose.map(|p| quantised(&pose3_to_pose2(&p))),
                keyframes: self.sent_poses.len(),
            }),
        }
    }

    /// Keyframes and edges messages sent so far.
    pub fn sent(&self) -> u64 {
        self.next_seq
    }

    fn message(&mut self, body: UpdateBody) -> MapUpdate {
        let seq = self.next_seq;
        self.next_seq += 1;
        MapUpdate { seq, body }
    }
}
