//! [`RobotInbox`]: one robot's map rebuilt from its map update messages, whatever order and
//! repetitions they arrive in.

use super::{MapUpdate, RobotStatus, UpdateBody};
use crate::lidar::{LidarMap, MapScan};
use crate::SlamError;
use slamkit_core::Pose2;
use std::collections::BTreeMap;

/// What [`RobotInbox::apply`] did with a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Applied {
    /// Applied to the map (with any held messages that then followed in sequence).
    New,
    /// Already applied or held: nothing changed.
    Duplicate,
    /// Ahead of a gap: held until the messages before it arrive.
    Held,
    /// A status message: it only told how many messages the robot has sent.
    Status,
}

/// One robot's map as its messages tell it: applied in sequence order only, so the map is the
/// same for the same number of messages applied, whatever order and repetitions they arrived
/// in.
#[derive(Debug, Clone, Default)]
pub struct RobotInbox {
    /// The messages applied, in sequence order (to recognise a duplicate).
    applied: Vec<MapUpdate>,
    /// Messages ahead of a gap.
    held: BTreeMap<u64, MapUpdate>,
    /// How many messages the robot says it has sent.
    announced: u64,
    status: Option<RobotStatus>,
    map: LidarMap,
}

impl RobotInbox {
    /// Takes one message.
    ///
    /// # Errors
    /// [`SlamError::Map`] for a message that disagrees with the one of the same number already
    /// taken, or does not fit the map (keyframes out of order, an edge or a moved keyframe
    /// naming a keyframe the map lacks); the map is left as it was before that message.
    pub fn apply(&mut self, update: MapUpdate) -> Result<Applied, SlamError> {
        if let UpdateBody::Status(status) = update.body {
            self.announced = self.announced.max(update.seq);
            if self
                .status
                .map_or(true, |s| s.timestamp <= status.timestamp)
            {
                self.status = Some(status);
            }
            return Ok(Applied::Status);
        }
        self.announced = self.announced.max(update.seq + 1);
        let known = self
            .applied
            .get(update.seq as usize)
            .or_else(|| self.held.get(&update.seq));
        if let Some(known) = known {
            return if same(known, &update) {
                Ok(Applied::Duplicate)
            } else {
                Err(SlamError::Map(format!(
                    "map update {} differs from the one of that number taken before",
                    update.seq
                )))
            };
        }
        if update.seq > self.applied.len() as u64 {
            self.held.insert(update.seq, update);
            return Ok(Applied::Held);
        }
        self.apply_next(update)?;
        while let Some(next) = self.held.remove(&(self.applied.len() as u64)) {
            self.apply_next(next)?;
        }
        Ok(Applied::New)
    }

    /// The sequence numbers the robot has sent (as far as its messages and status tell) that
    /// have not arrived: what to fetch.
    pub fn missing(&self) -> Vec<u64> {
        (self.applied.len() as u64..self.announced)
            .filter(|s| !self.held.contains_key(s))
            .collect()
    }

    /// Messages applied to the map.
    pub fn applied(&self) -> u64 {
        self.applied.len() as u64
    }

    /// The robot's newest status, if one arrived.
    pub fn status(&self) -> Option<&RobotStatus> {
        self.status.as_ref()
    }

    /// The map so far: the keyframes at their newest poses, the edges, and one scan per
    /// keyframe (so [`LidarMap::trajectory`] is the keyframes' path).
    pub fn map(&self) -> &LidarMap {
        &self.map
    }

    fn apply_next(&mut self, update: MapUpdate) -> Result<(), SlamError> {
        let n = self.map.keyframes.len();
        match &update.body {
            UpdateBody::Keyframes { first, keyframes } => {
                if *first != n {
                    return Err(SlamError::Map(format!(
                        "map update {} starts at keyframe {first}, the map has {n}",
                        update.seq
                    )));
                }
                for (i, kf) in keyframes.iter().enumerate() {
                    self.map.keyframes.push(kf.clone());
                    self.map.scans.push(MapScan {
                        timestamp: kf.scan.timestamp,
                        keyframe: Some(n + i),
                        keyframe_from_base: Pose2::identity(),
                    });
                }
            }
            UpdateBody::Edges { edges, moved } => {
                let outside = edges
                    .iter()
                    .any(|e| e.from >= n || e.to >= n || e.from == e.to)
                    || moved.iter().any(|(k, _)| *k >= n);
                if outside {
                    return Err(SlamError::Map(format!(
                        "map update {} names a keyframe beyond the map's {n}, or joins one to \
                         itself",
                        update.seq
                    )));
                }
                self.map.edges.extend_from_slice(edges);
                for (k, pose) in moved {
                    self.map.keyframes[*k].world_from_base = *pose;
                }
            }
            UpdateBody::Status(_) => {}
        }
        self.applied.push(update);
        Ok(())
    }
}

/// Two messages of one number hold the same content (scans compared by their bytes: a range
/// that is not a number is equal to itself here).
fn same(a: &MapUpdate, b: &MapUpdate) -> bool {
    match (a.to_bytes(), b.to_bytes()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}
