//! [`Merger`]: the receiving side of a fleet. It subscribes to every robot's messages,
//! rebuilds each robot's map ([`RobotInbox`]: in sequence order, duplicates ignored), asks a
//! robot by query for the sequence numbers it lacks, and merges the robots' maps.

use crate::keys::{fleet_keys, parse, robot_keys};
use crate::robot::SEQS_PARAMETER;
use crate::FleetError;
use slamkit_slam::map_updates::{MapUpdate, RobotInbox};
use slamkit_slam::merge::{merge_maps, MergeConfig, MergeOutcome};
use std::collections::BTreeMap;
use std::time::Duration;
use zenoh::handlers::{FifoChannel, FifoChannelHandler};
use zenoh::sample::Sample;
use zenoh::Wait;

/// Messages the subscriber holds before Zenoh waits for the merger to take them.
const QUEUE: usize = 65_536;
/// Sequence numbers asked for in one query.
const PER_QUERY: usize = 256;

/// Collects a fleet's map updates and merges the robots' maps.
pub struct Merger {
    session: zenoh::Session,
    fleet: String,
    subscriber: zenoh::pubsub::Subscriber<FifoChannelHandler<Sample>>,
    inboxes: BTreeMap<String, RobotInbox>,
    rejected: usize,
}

impl Merger {
    /// A merger of `fleet` on `session`, subscribed to every robot's messages.
    ///
    /// # Errors
    /// [`FleetError::Name`] for a fleet name that cannot stand in a key, [`FleetError::Zenoh`]
    /// when the subscriber cannot be declared.
    pub fn new(session: zenoh::Session, fleet: &str) -> Result<Self, FleetError> {
        crate::keys::check_name(fleet)?;
        let subscriber = session
            .declare_subscriber(fleet_keys(fleet))
            .with(FifoChannel::new(QUEUE))
            .wait()
            .map_err(FleetError::zenoh)?;
        Ok(Self {
            session,
            fleet: fleet.to_string(),
            subscriber,
            inboxes: BTreeMap::new(),
            rejected: 0,
        })
    }

    /// Takes every message waiting, after waiting up to `timeout` for the first; returns how
    /// many it took.
    ///
    /// # Errors
    /// [`FleetError::Zenoh`] when the subscription is closed.
    pub fn receive(&mut self, timeout: Duration) -> Result<usize, FleetError> {
        let mut taken = 0;
        let mut next = self
            .subscriber
            .recv_timeout(timeout)
            .map_err(FleetError::zenoh)?;
        while let Some(sample) = next {
            self.take(&sample);
            taken += 1;
            next = self.subscriber.try_recv().map_err(FleetError::zenoh)?;
        }
        Ok(taken)
    }

    /// Asks each robot for the sequence numbers its inbox lacks, waiting up to `timeout` for
    /// the answers; returns how many messages arrived.
    ///
    /// # Errors
    /// [`FleetError::Zenoh`] when a query cannot be sent.
    pub fn fetch_missing(&mut self, timeout: Duration) -> Result<usize, FleetError> {
        let wanted: Vec<(String, Vec<u64>)> = self
            .inboxes
            .iter()
            .map(|(robot, inbox)| (robot.clone(), inbox.missing()))
            .filter(|(_, missing)| !missing.is_empty())
            .collect();
        let mut arrived = 0;
        for (robot, missing) in wanted {
            for chunk in missing.chunks(PER_QUERY) {
                let list: Vec<String> = chunk.iter().map(u64::to_string).collect();
                let selector = format!(
                    "{}?{SEQS_PARAMETER}={}",
                    robot_keys(&self.fleet, &robot),
                    list.join(",")
                );
                let replies = self
                    .session
                    .get(selector)
                    .consolidation(zenoh::query::ConsolidationMode::None)
                    .timeout(timeout)
                    .wait()
                    .map_err(FleetError::zenoh)?;
                while let Ok(reply) = replies.recv() {
                    if let Ok(sample) = reply.result() {
                        self.take(sample);
                        arrived += 1;
                    }
                }
            }
        }
        Ok(arrived)
    }

    /// Sequence numbers known to be missing, over all robots.
    pub fn missing(&self) -> usize {
        self.inboxes.values().map(|i| i.missing().len()).sum()
    }

    /// Each robot heard from, by name, with its rebuilt map.
    pub fn robots(&self) -> &BTreeMap<String, RobotInbox> {
        &self.inboxes
    }

    /// Messages that could not be decoded or did not fit their robot's map.
    pub fn rejected(&self) -> usize {
        self.rejected
    }

    /// Merges the maps of the robots that have keyframes, in name order; returns their names
    /// (the merge's input order) and the outcome.
    ///
    /// # Errors
    /// [`FleetError::Slam`] when fewer than two robots have keyframes, or for settings out of
    /// range.
    pub fn merge(&self, config: &MergeConfig) -> Result<(Vec<String>, MergeOutcome), FleetError> {
        let (names, maps): (Vec<String>, Vec<_>) = self
            .inboxes
            .iter()
            .filter(|(_, inbox)| !inbox.map().keyframes.is_empty())
            .map(|(name, inbox)| (name.clone(), inbox.map().clone()))
            .unzip();
        Ok((names, merge_maps(&maps, config)?))
    }

    fn take(&mut self, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let Ok((robot, _)) = parse(key) else {
            self.rejected += 1;
            return;
        };
        let payload = sample.payload().to_bytes();
        let inbox = self.inboxes.entry(robot).or_default();
        let applied = MapUpdate::from_bytes(&payload).map(|u| inbox.apply(u));
        if !matches!(applied, Ok(Ok(_))) {
            self.rejected += 1;
        }
    }
}
