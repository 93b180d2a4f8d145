//! [`Merger`]: the receiving side of a fleet. It subscribes to every robot's messages,
//! rebuilds each robot's map ([`RobotInbox`]: in sequence order, duplicates ignored), asks
//! the robots by query for their status and for the sequence numbers it lacks, and merges the
//! robots' maps. It times each publication's way from the robot (the robot's Zenoh timestamp)
//! to its arrival here.

use crate::keys::{fleet_keys, parse, robot_keys};
use crate::robot::{SEQS_PARAMETER, STATUS_PARAMETER};
use crate::FleetError;
use slamkit_core::StageTimings;
use slamkit_slam::lidar::LidarMap;
use slamkit_slam::map_updates::{Applied, MapUpdate, RobotInbox};
use slamkit_slam::merge::{merge_maps, MergeConfig, MergeOutcome};
use std::collections::BTreeMap;
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant, SystemTime};
use zenoh::sample::Sample;
use zenoh::Wait;

/// Sequence numbers asked for in one query.
const PER_QUERY: usize = 256;

/// The stage of [`Merger::timings`] that holds each publication's way from the robot to the
/// merger \[ms\] (the robot's clock against the merger's: one machine, or synchronised clocks).
pub const PUBLISH_TO_RECEIPT: &str = "publish_to_receipt";

/// What arrived from one robot.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Traffic {
    /// Messages taken (published and fetched, duplicates included).
    pub messages: usize,
    /// Their bytes, keys included.
    pub bytes: usize,
    /// Of those, the messages that came as answers to queries.
    pub fetched: usize,
}

/// Collects a fleet's map updates and merges the robots' maps.
pub struct Merger {
    session: zenoh::Session,
    fleet: String,
    _subscriber: zenoh::pubsub::Subscriber<()>,
    arrivals: Receiver<(SystemTime, Sample)>,
    inboxes: BTreeMap<String, RobotInbox>,
    traffic: BTreeMap<String, Traffic>,
    rejected: usize,
    timings: StageTimings,
    /// When the oldest keyframes or edges message applied since [`Merger::mark_merged`]
    /// arrived.
    unmerged_since: Option<Instant>,
    /// When the newest one arrived.
    last_new: Option<Instant>,
}

impl Merger {
    /// A merger of `fleet` on `session`, subscribed to every robot's messages.
    ///
    /// # Errors
    /// [`FleetError::Name`] for a fleet name that cannot stand in a key, [`FleetError::Zenoh`]
    /// when the subscriber cannot be declared.
    pub fn new(session: zenoh::Session, fleet: &str) -> Result<Self, FleetError> {
        crate::keys::check_name(fleet)?;
        let (sender, arrivals) = channel();
        let subscriber = session
            .declare_subscriber(fleet_keys(fleet))
            .callback(move |sample| {
                // the receiver is gone only once the merger is dropped
                let _ = sender.send((SystemTime::now(), sample));
            })
            .wait()
            .map_err(FleetError::zenoh)?;
        Ok(Self {
            session,
            fleet: fleet.to_string(),
            _subscriber: subscriber,
            arrivals,
            inboxes: BTreeMap::new(),
            traffic: BTreeMap::new(),
            rejected: 0,
            timings: StageTimings::default(),
            unmerged_since: None,
            last_new: None,
        })
    }

    /// Takes every message waiting, after waiting up to `timeout` for the first; returns how
    /// many it took.
    ///
    /// # Errors
    /// [`FleetError::Zenoh`] when the subscription is closed.
    pub fn receive(&mut self, timeout: Duration) -> Result<usize, FleetError> {
        let mut taken = 0;
        let mut next = match self.arrivals.recv_timeout(timeout) {
            Ok(arrival) => Some(arrival),
            Err(RecvTimeoutError::Timeout) => None,
            Err(RecvTimeoutError::Disconnected) => {
                return Err(FleetError::Zenoh("the subscription was closed".into()))
            }
        };
        while let Some((arrived, sample)) = next {
            if let Some(sent) = sample.timestamp() {
                let sent = sent.get_time().to_system_time();
                if let Ok(way) = arrived.duration_since(sent) {
                    self.timings
                        .record(PUBLISH_TO_RECEIPT, way.as_secs_f64() * 1e3);
                }
            }
            self.take(&sample, false);
            taken += 1;
            next = self.arrivals.try_recv().ok();
        }
        Ok(taken)
    }

    /// Asks every robot of the fleet for its latest status (so a merger that started late, or
    /// lost the last messages, learns how many each robot has sent), waiting up to `timeout`;
    /// returns how many answered.
    ///
    /// # Errors
    /// [`FleetError::Zenoh`] when the query cannot be sent.
    pub fn ask_status(&mut self, timeout: Duration) -> Result<usize, FleetError> {
        let selector = format!("{}?{STATUS_PARAMETER}", fleet_keys(&self.fleet));
        self.query(selector, timeout)
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
                arrived += self.query(selector, timeout)?;
            }
        }
        Ok(arrived)
    }

    fn query(&mut self, selector: String, timeout: Duration) -> Result<usize, FleetError> {
        let replies = self
            .session
            .get(selector)
            .consolidation(zenoh::query::ConsolidationMode::None)
            // not its own merged map's queryable, which a status query's `*` would match
            .allowed_destination(zenoh::sample::Locality::Remote)
            .timeout(timeout)
            .wait()
            .map_err(FleetError::zenoh)?;
        let mut arrived = 0;
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                self.take(sample, true);
                arrived += 1;
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

    /// What arrived from each robot.
    pub fn traffic(&self) -> &BTreeMap<String, Traffic> {
        &self.traffic
    }

    /// Messages that could not be decoded or did not fit their robot's map.
    pub fn rejected(&self) -> usize {
        self.rejected
    }

    /// The times measured: [`PUBLISH_TO_RECEIPT`] \[ms\].
    pub fn timings(&self) -> &StageTimings {
        &self.timings
    }

    /// The Zenoh session it runs on.
    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// When the oldest keyframes or edges message applied since the last
    /// [`mark_merged`](Self::mark_merged) arrived (`None`: nothing new since).
    pub fn unmerged_since(&self) -> Option<Instant> {
        self.unmerged_since
    }

    /// When the newest keyframes or edges message was applied.
    pub fn last_new(&self) -> Option<Instant> {
        self.last_new
    }

    /// Notes that every message applied so far is in a merge.
    pub fn mark_merged(&mut self) {
        self.unmerged_since = None;
    }

    /// The names and maps of the robots that have keyframes, in name order: a merge's inputs.
    pub fn maps(&self) -> (Vec<String>, Vec<LidarMap>) {
        self.inboxes
            .iter()
            .filter(|(_, inbox)| !inbox.map().keyframes.is_empty())
            .map(|(name, inbox)| (name.clone(), inbox.map().clone()))
            .unzip()
    }

    /// Merges the maps of the robots that have keyframes, in name order; returns their names
    /// (the merge's input order) and the outcome.
    ///
    /// # Errors
    /// [`FleetError::Slam`] when fewer than two robots have keyframes, or for settings out of
    /// range.
    pub fn merge(&self, config: &MergeConfig) -> Result<(Vec<String>, MergeOutcome), FleetError> {
        let (names, maps) = self.maps();
        Ok((names, merge_maps(&maps, config)?))
    }

    fn take(&mut self, sample: &Sample, fetched: bool) {
        let key = sample.key_expr().as_str();
        if key.starts_with(&format!("slamkit/{}/merged/", self.fleet)) {
            return; // the merged map, this merger's own publication
        }
        let Ok((robot, _)) = parse(key) else {
            self.rejected += 1;
            return;
        };
        let payload = sample.payload().to_bytes();
        let traffic = self.traffic.entry(robot.clone()).or_default();
        traffic.messages += 1;
        traffic.bytes += payload.len() + key.len();
        traffic.fetched += usize::from(fetched);
        let inbox = self.inboxes.entry(robot).or_default();
        match MapUpdate::from_bytes(&payload).map(|u| inbox.apply(u)) {
            Ok(Ok(Applied::New)) => {
                let now = Instant::now();
                self.unmerged_since.get_or_insert(now);
                self.last_new = Some(now);
            }
            Ok(Ok(_)) => {}
            _ => self.rejected += 1,
        }
    }
}
