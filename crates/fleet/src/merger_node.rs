//! [`MergerNode`]: a fleet's merger as a process runs it (`slamkit fleet merger`). It takes the
//! robots' map updates as they come, fetches what is missing, merges the robots' maps every
//! `merge_every_s` while updates arrive, and publishes each merged map on
//! `slamkit/<fleet>/merged/map` (the `.skmap` file's bytes) and its report on
//! `slamkit/<fleet>/merged/report` (JSON), both with one Zenoh timestamp and both also
//! answered to queries; every second it publishes that timestamp on
//! `slamkit/<fleet>/merged/status`, so a robot that holds an older map (it joined late, or
//! missed the publication) asks for the latest ([`crate::merged_map`]). Started after the
//! robots, or again after a crash, it asks every robot for its status and fetches everything
//! they sent: the same merged map as if it had run all along.

use crate::keys::{check_name, merged_key, Merged as Key};
use crate::merger::{Merger, PUBLISH_TO_RECEIPT};
use crate::{FleetError, PeerConfig};
use serde_json::{json, Value};
use slamkit_slam::lidar::LidarMap;
use slamkit_slam::map_file::MapFile;
use slamkit_slam::merge::output::{merged_map_file, write_merge_file};
use slamkit_slam::merge::{merge_maps, MergeConfig, MergeOutcome};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::time::Timestamp;
use zenoh::Wait;

/// The stage of [`MergerNode::timings`] from the arrival of the oldest update a merge holds
/// that the one before did not, to the publication of that merge \[ms\].
pub const RECEIPT_TO_MERGED: &str = "receipt_to_merged_published";

/// How long one query waits for its answers.
const QUERY_TIMEOUT: Duration = Duration::from_secs(2);
/// How long the merger waits for messages in one step.
const STEP: Duration = Duration::from_millis(100);
/// How long, when stopping, the merger goes on fetching what the robots say they sent.
const FINAL_FETCH: Duration = Duration::from_secs(15);
/// The merged status goes out this often.
const STATUS_EVERY: Duration = Duration::from_secs(1);

/// The latest merged publications (key, bytes) and their timestamp, shared with the queryable
/// that answers them.
type Publications = Arc<Mutex<(Vec<(String, Vec<u8>)>, Option<Timestamp>)>>;

/// Settings of a merger process.
#[derive(Debug, Clone)]
pub struct MergerNodeConfig {
    /// The fleet's name (`slamkit/<fleet>/...`).
    pub fleet: String,
    /// Where it listens and whom it connects to.
    pub peer: PeerConfig,
    /// The merge's settings.
    pub merge: MergeConfig,
    /// While updates arrive, a merge at most this often \[s\] (each merge runs from scratch:
    /// on two parts of 1,200 Intel scans it took 3 s of CPU).
    pub merge_every_s: f64,
}

impl MergerNodeConfig {
    /// The merger of `fleet` on `peer`, with the default [`MergeConfig`], merging at most
    /// every 10 s.
    ///
    /// ```
    /// let config = slamkit_fleet::MergerNodeConfig::new("lab", Default::default());
    /// assert_eq!(config.merge_every_s, 10.0);
    /// ```
    pub fn new(fleet: &str, peer: PeerConfig) -> Self {
        Self {
            fleet: fleet.to_string(),
            peer,
            merge: MergeConfig::default(),
            merge_every_s: 10.0,
        }
    }
}

/// The latest merge: its inputs and outcome, and the map file sent to the robots.
struct Merged {
    names: Vec<String>,
    maps: Vec<LidarMap>,
    outcome: MergeOutcome,
    file: MapFile,
}

/// A running merger.
pub struct MergerNode {
    config: MergerNodeConfig,
    merger: Merger,
    /// The latest merged publications, answered to queries.
    latest: Publications,
    _queryable: zenoh::query::Queryable<()>,
    merged: Option<Merged>,
    last_merge: Option<Instant>,
    last_status: Option<Instant>,
    merges: usize,
    timings: slamkit_core::StageTimings,
    started: Instant,
}

impl MergerNode {
    /// Opens the peer, subscribes, answers queries for the merged map, and asks the robots
    /// already running for their status.
    ///
    /// # Errors
    /// [`FleetError::Name`] for a fleet name that cannot stand in a key,
    /// [`FleetError::Slam`] for merge settings out of range, [`FleetError::Zenoh`] when the
    /// peer cannot open (an endpoint taken, say).
    pub fn start(config: MergerNodeConfig) -> Result<Self, FleetError> {
        check_name(&config.fleet)?;
        config.merge.validate()?;
        if config.merge_every_s.is_nan() || config.merge_every_s < 0.0 {
            return Err(FleetError::Slam(slamkit_slam::SlamError::Config(format!(
                "merge_every_s {} must be >= 0",
                config.merge_every_s
            ))));
        }
        let session = config.peer.open()?;
        let latest: Publications = Arc::default();
        let served = Arc::clone(&latest);
        let queryable = session
            .declare_queryable(format!("slamkit/{}/merged/**", config.fleet))
            .callback(move |query| {
                let (replies, stamp) = served.lock().map(|l| l.clone()).unwrap_or_default();
                for (key, bytes) in replies {
                    let wanted = zenoh::key_expr::KeyExpr::try_from(key.as_str())
                        .is_ok_and(|k| query.key_expr().intersects(&k));
                    if wanted {
                        // an answer that cannot go out is asked for again
                        let _ = query.reply(key, bytes).timestamp(stamp).wait();
                    }
                }
            })
            .wait()
            .map_err(FleetError::zenoh)?;
        let mut merger = Merger::new(session, &config.fleet)?;
        merger.ask_status(QUERY_TIMEOUT)?;
        Ok(Self {
            config,
            merger,
            latest,
            _queryable: queryable,
            merged: None,
            last_merge: None,
            last_status: None,
            merges: 0,
            timings: slamkit_core::StageTimings::default(),
            started: Instant::now(),
        })
    }

    /// Runs until `stop` is set: takes updates, fetches the missing ones, merges every
    /// `merge_every_s` while updates arrive. Then it asks every robot for its status, fetches
    /// what is still missing (for up to 15 s) and merges what changed since the last merge.
    ///
    /// # Errors
    /// [`FleetError::Zenoh`] when Zenoh fails, [`FleetError::Slam`] when a merge fails.
    pub fn run(&mut self, stop: &AtomicBool) -> Result<(), FleetError> {
        while !stop.load(Ordering::Relaxed) {
            self.merger.receive(STEP)?;
            if self.merger.missing() > 0 {
                self.merger.fetch_missing(QUERY_TIMEOUT)?;
            }
            let due = self.last_merge.map_or(true, |t| {
                t.elapsed().as_secs_f64() >= self.config.merge_every_s
            });
            if due && self.merger.unmerged_since().is_some() {
                self.merge()?;
            }
            self.status_if_due()?;
        }
        let until = Instant::now() + FINAL_FETCH;
        self.merger.receive(STEP)?;
        self.merger.ask_status(QUERY_TIMEOUT)?;
        while self.merger.missing() > 0 && Instant::now() < until {
            self.merger.fetch_missing(QUERY_TIMEOUT)?;
            self.merger.receive(STEP)?;
        }
        if self.merger.unmerged_since().is_some() {
            self.merge()?;
        }
        Ok(())
    }

    /// Merges the robots' maps as they stand and publishes the merged map and its report
    /// (nothing while fewer than two robots have keyframes).
    fn merge(&mut self) -> Result<(), FleetError> {
        let (names, maps) = self.merger.maps();
        if maps.len() < 2 {
            return Ok(());
        }
        let since = self.merger.unmerged_since();
        self.merger.mark_merged();
        let outcome = merge_maps(&maps, &self.config.merge)?;
        let key = |what| merged_key(&self.config.fleet, what);
        let encoding_failed = |source| FleetError::Message {
            key: key(Key::Map),
            source,
        };
        let file = merged_map_file(&outcome, &names, "fleet merger").map_err(encoding_failed)?;
        let map_bytes = file.to_bytes().map_err(encoding_failed)?;
        let report = outcome.report(&names, &[]).to_string().into_bytes();
        let publications = vec![(key(Key::Map), map_bytes), (key(Key::Report), report)];
        let stamp = self.merger.session().new_timestamp();
        for (key, bytes) in &publications {
            self.merger
                .session()
                .put(key.clone(), bytes.clone())
                .timestamp(stamp)
                .wait()
                .map_err(FleetError::zenoh)?;
        }
        if let Some(since) = since {
            self.timings.record_since(RECEIPT_TO_MERGED, since);
        }
        if let Ok(mut latest) = self.latest.lock() {
            *latest = (publications, Some(stamp));
        }
        self.merged = Some(Merged {
            names,
            maps,
            outcome,
            file,
        });
        self.last_merge = Some(Instant::now());
        self.last_status = None;
        self.merges += 1;
        self.status_if_due()
    }

    /// Publishes the latest merged map's timestamp when a second has passed since the last
    /// time (nothing before the first merge).
    fn status_if_due(&mut self) -> Result<(), FleetError> {
        let due = self
            .last_status
            .map_or(true, |t| t.elapsed() >= STATUS_EVERY);
        let stamp = self.latest.lock().ok().and_then(|l| l.1);
        if let (true, Some(stamp)) = (due, stamp) {
            self.merger
                .session()
                .put(
                    merged_key(&self.config.fleet, Key::Status),
                    stamp.to_string(),
                )
                .wait()
                .map_err(FleetError::zenoh)?;
            self.last_status = Some(Instant::now());
        }
        Ok(())
    }

    /// The merger underneath: each robot's map and traffic.
    pub fn merger(&self) -> &Merger {
        &self.merger
    }

    /// Merges published so far.
    pub fn merges(&self) -> usize {
        self.merges
    }

    /// [`RECEIPT_TO_MERGED`] \[ms\], with the merger's [`PUBLISH_TO_RECEIPT`].
    pub fn timings(&self) -> slamkit_core::StageTimings {
        let mut all = self.timings.clone();
        all.merge(self.merger.timings());
        all
    }

    /// Writes the latest merge into the folder `dir` as `slamkit map merge` does
    /// ([`write_merge_file`]; its `map.skmap` holds the bytes sent to the robots) and returns the report: the merge's, with each robot's traffic, the
    /// latencies (median, p95) and the merges run.
    ///
    /// # Errors
    /// [`FleetError::Slam`] when no merge was made (fewer than two robots had keyframes) or
    /// a file cannot be written.
    pub fn write(&self, dir: &Path) -> Result<Value, FleetError> {
        let merged = self.merged.as_ref().ok_or_else(|| {
            FleetError::Slam(slamkit_slam::SlamError::Map(format!(
                "no merge: {} robot(s) with keyframes heard from, a merge needs two",
                self.merger.maps().0.len()
            )))
        })?;
        let mut report = write_merge_file(
            &merged.file,
            &merged.outcome,
            &merged.maps,
            &merged.names,
            dir,
        )?;
        let timings = self.timings().summary();
        let fleet = json!({
            "fleet": self.config.fleet,
            "robots": self.merger.traffic(),
            "missing": self.merger.missing(),
            "rejected": self.merger.rejected(),
            "merges": self.merges,
            "publish_to_receipt_ms": timings.get(PUBLISH_TO_RECEIPT),
            "receipt_to_merged_ms": timings.get(RECEIPT_TO_MERGED),
            "merge_every_s": self.config.merge_every_s,
            "run_seconds": self.started.elapsed().as_secs_f64(),
        });
        report["fleet"] = fleet;
        report["config"] = json!(self.config.merge);
        report["timings_ms"] = json!(merged.outcome.timings.summary());
        Ok(report)
    }
}
