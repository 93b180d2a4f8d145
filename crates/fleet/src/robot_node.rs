//! [`RobotNode`]: one robot of a fleet as a process runs it (`slamkit fleet robot`): ICP-SLAM
//! on a recorded log, played at a chosen rate, its map updates published as they are due and
//! its status every second. Every message is kept in a store file; a robot process killed and
//! started again with the same store runs the log again from the start as fast as it can
//! (the same input gives the same messages, which it checks against the stored ones) without
//! sending what it had sent, then goes on at the chosen rate from its next sequence number.
//! All along it keeps the fleet's newest merged map in a file ([`MergedMapInbox`]), which it
//! can localise and plan in.

use crate::merged_map::MergedMapInbox;
use crate::robot::RobotPublisher;
use crate::{FleetError, PeerConfig};
use serde_json::{json, Value};
use slamkit_io::carmen::CarmenLog;
use slamkit_slam::lidar::LidarMap;
use slamkit_slam::map_updates::{
    laser_scan_cdr_bytes, MapUpdate, RobotInbox, UpdateConfig, UpdateOutbox,
};
use slamkit_slam::session::Update;
use slamkit_slam::LidarSlam;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The files [`RobotNode::write`] writes, and the report. (The store and the merged map,
/// `updates.skmu` and `merged.skmap` by default, are written as they change, not with these.)
pub const ROBOT_FILES: &[&str] = &["trajectory.tum", "map.skmap", "sent.skmap", "report.json"];

/// A status goes out this often \[s of wall time\] while the robot runs and after.
const STATUS_EVERY: Duration = Duration::from_secs(1);
/// The longest sleep between two looks at the stop flag.
const NAP: Duration = Duration::from_millis(50);

/// Settings of a robot process.
#[derive(Debug, Clone)]
pub struct RobotNodeConfig {
    /// The fleet's name (`slamkit/<fleet>/...`).
    pub fleet: String,
    /// The robot's name in the fleet.
    pub robot: String,
    /// Where it listens and whom it connects to.
    pub peer: PeerConfig,
    /// Log seconds played per wall second (1: real time; 0: as fast as the CPU allows).
    pub rate: f64,
    /// When its map updates are sent.
    pub updates: UpdateConfig,
    /// The file every message is kept in; a restarted robot with the same file resumes.
    pub store: PathBuf,
    /// The file the fleet's newest merged map is kept in.
    pub merged_map: PathBuf,
    /// Fraction of publications dropped on purpose, and the seed of the draws (tests of
    /// recovery: a dropped message is still stored and served to queries).
    pub loss: Option<(f64, u64)>,
    /// A stretch of the log, `(from, length)` in log seconds after its first scan, through
    /// which the robot is off the network: its Zenoh session closed, what it maps meanwhile
    /// kept and sent to nobody, then a new session (tests of a robot out of Wi-Fi range that
    /// comes back). A stretch past the log's end is waited out at the log's rate.
    pub disconnect: Option<(f64, f64)>,
}

impl RobotNodeConfig {
    /// Robot `robot` of `fleet` on `peer`, its messages kept in `<out>/updates.skmu` and the
    /// merged map in `<out>/merged.skmap`, playing its log in real time with the default
    /// [`UpdateConfig`] and no loss on purpose.
    ///
    /// ```
    /// let config = slamkit_fleet::RobotNodeConfig::new("lab", "r1", Default::default(), "out/r1".as_ref());
    /// assert_eq!(config.store, std::path::Path::new("out/r1/updates.skmu"));
    /// assert_eq!(config.merged_map, std::path::Path::new("out/r1/merged.skmap"));
    /// ```
    pub fn new(fleet: &str, robot: &str, peer: PeerConfig, out: &Path) -> Self {
        Self {
            fleet: fleet.to_string(),
            robot: robot.to_string(),
            peer,
            rate: 1.0,
            updates: UpdateConfig::default(),
            store: out.join("updates.skmu"),
            merged_map: out.join("merged.skmap"),
            loss: None,
            disconnect: None,
        }
    }
}

/// A robot mapping and publishing.
pub struct RobotNode {
    config: RobotNodeConfig,
    slam: LidarSlam,
    publisher: RobotPublisher,
    merged: MergedMapInbox,
    outbox: UpdateOutbox,
    /// The map as the robot's messages tell it: what a merger holds once it has them all.
    sent: RobotInbox,
    resumed_from: u64,
    last_update: Option<Update>,
    last_status: Option<Instant>,
    started: Instant,
    scans_done: usize,
    /// Times the robot left the network ([`RobotNodeConfig::disconnect`]: at most once).
    disconnections: usize,
}

impl RobotNode {
    /// Opens the peer and the store (serving what it holds at once) for `slam`, a new
    /// ICP-SLAM session.
    ///
    /// # Errors
    /// [`FleetError::Name`] for a name that cannot stand in a key, [`FleetError::Slam`] for a
    /// session that is not a new ICP-SLAM map or settings out of range, [`FleetError::Store`]
    /// and [`FleetError::Message`] for a store file that cannot be read, [`FleetError::Zenoh`]
    /// when the peer cannot open.
    pub fn start(config: RobotNodeConfig, slam: LidarSlam) -> Result<Self, FleetError> {
        let config_error = |what: String| FleetError::Slam(slamkit_slam::SlamError::Config(what));
        if slam.live_map().is_none() {
            return Err(config_error(
                "a fleet robot maps with ICP-SLAM from scratch (not the particle filter, not in a \
                 saved map)"
                    .into(),
            ));
        }
        if !config.rate.is_finite() || config.rate < 0.0 {
            return Err(config_error(format!("rate {} must be >= 0", config.rate)));
        }
        if let Some((from, length)) = config.disconnect {
            if !(from.is_finite() && length.is_finite() && from >= 0.0 && length > 0.0) {
                return Err(config_error(format!(
                    "disconnect from {from} s for {length} s: both must be finite, the length > 0"
                )));
            }
        }
        if let Some((p, _)) = config.loss {
            if !(0.0..1.0).contains(&p) {
                return Err(config_error(format!("loss {p} must be in [0, 1)")));
            }
        }
        crate::keys::check_name(&config.fleet)?;
        crate::keys::check_name(&config.robot)?;
        for file in [&config.store, &config.merged_map] {
            if let Some(dir) = file.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir).map_err(|source| FleetError::Store {
                    path: dir.to_path_buf(),
                    source,
                })?;
            }
        }
        let outbox = UpdateOutbox::new(config.updates.clone())?;
        let session = config.peer.open()?;
        let merged = MergedMapInbox::new(session.clone(), &config.fleet, &config.merged_map)?;
        let mut publisher = RobotPublisher::new(session, &config.fleet, &config.robot)?
            .with_store_file(&config.store)?;
        if let Some((p, seed)) = config.loss {
            publisher = publisher.with_loss(p, seed);
        }
        let resumed_from = publisher.stored();
        Ok(Self {
            config,
            slam,
            publisher,
            merged,
            outbox,
            sent: RobotInbox::default(),
            resumed_from,
            last_update: None,
            last_status: None,
            started: Instant::now(),
            scans_done: 0,
            disconnections: 0,
        })
    }

    /// Plays `log` through the session at the configured rate (the part its stored messages
    /// cover as fast as it can), publishing the map updates as they are due and taking the
    /// merged maps that come; at the end sends what is left and its status. `progress` is
    /// called after each scan. Returns `false` when `stop` cut the run short.
    ///
    /// # Errors
    /// [`FleetError::Message`] for a message that differs from the one of its number in the
    /// store (another log or other settings than before the restart), and the publisher's
    /// errors.
    pub fn play(
        &mut self,
        log: &CarmenLog,
        stop: &AtomicBool,
        mut progress: impl FnMut(usize),
    ) -> Result<bool, FleetError> {
        // the wall time and log time the pace counts from, once caught up with the store
        let mut pace: Option<(Instant, f64)> = None;
        let first = log.scans.first().map_or(0.0, |s| s.timestamp);
        for scan in &log.scans {
            if stop.load(Ordering::Relaxed) {
                return Ok(false);
            }
            self.connect_as_due(scan.timestamp - first)?;
            let caught_up = self.outbox.sent() >= self.resumed_from;
            if caught_up && self.config.rate > 0.0 {
                let (wall, t0) = *pace.get_or_insert((Instant::now(), scan.timestamp));
                let due = wall
                    + Duration::from_secs_f64(((scan.timestamp - t0) / self.config.rate).max(0.0));
                while Instant::now() < due {
                    if stop.load(Ordering::Relaxed) {
                        return Ok(false);
                    }
                    self.network()?;
                    std::thread::sleep(NAP.min(due.saturating_duration_since(Instant::now())));
                }
            }
            let update = self.slam.push_scan(scan.clone());
            let due = match self.slam.live_map() {
                Some(map) => self.outbox.poll(map, update.timestamp),
                None => Vec::new(),
            };
            self.last_update = Some(update);
            self.send(&due)?;
            if self.outbox.sent() >= self.resumed_from {
                self.network()?;
            } else if self.publisher.online() {
                self.merged.poll()?;
            }
            self.scans_done += 1;
            progress(self.scans_done);
        }
        let rest = match self.slam.live_map() {
            Some(map) => self.outbox.flush(map),
            None => Vec::new(),
        };
        self.send(&rest)?;
        // a disconnection that outlasts the log is waited out at the log's pace
        if let (Some((from, length)), Some(last)) = (self.config.disconnect, log.scans.last()) {
            let left = from + length - (last.timestamp - first);
            if !self.publisher.online() && left > 0.0 && self.config.rate > 0.0 {
                let until = Instant::now() + Duration::from_secs_f64(left / self.config.rate);
                while Instant::now() < until {
                    if stop.load(Ordering::Relaxed) {
                        return Ok(false);
                    }
                    std::thread::sleep(NAP.min(until.saturating_duration_since(Instant::now())));
                }
            }
            self.connect_as_due(f64::INFINITY)?;
        }
        self.last_status = None;
        self.status_if_due()?;
        Ok(true)
    }

    /// Leaves or rejoins the network as [`RobotNodeConfig::disconnect`] says for log time
    /// `t` (seconds after the first scan).
    fn connect_as_due(&mut self, t: f64) -> Result<(), FleetError> {
        let Some((from, length)) = self.config.disconnect else {
            return Ok(());
        };
        let away = t >= from && t < from + length;
        if away && self.publisher.online() && self.disconnections == 0 {
            self.publisher.disconnect()?;
            self.disconnections += 1;
        } else if !away && !self.publisher.online() {
            let session = self.config.peer.open()?;
            self.merged.reconnect(session.clone())?;
            self.publisher.reconnect(session)?;
            self.last_status = None;
        }
        Ok(())
    }

    /// The robot's status when due and the merged maps that came, while on the network.
    fn network(&mut self) -> Result<(), FleetError> {
        if self.publisher.online() {
            self.status_if_due()?;
            self.merged.poll()?;
        }
        Ok(())
    }

    /// After the log: keeps answering queries, sending its status every second and taking
    /// the merged maps that come, until `stop` is set.
    ///
    /// # Errors
    /// The publisher's errors, and [`FleetError::Store`] when the merged map cannot be
    /// written.
    pub fn serve(&mut self, stop: &AtomicBool) -> Result<(), FleetError> {
        while !stop.load(Ordering::Relaxed) {
            self.network()?;
            std::thread::sleep(NAP);
        }
        Ok(())
    }

    fn send(&mut self, messages: &[MapUpdate]) -> Result<(), FleetError> {
        for message in messages {
            self.publisher.publish(message)?;
            self.sent.apply(message.clone())?;
        }
        Ok(())
    }

    fn status_if_due(&mut self) -> Result<(), FleetError> {
        let due = self
            .last_status
            .map_or(true, |t| t.elapsed() >= STATUS_EVERY);
        if let (true, Some(update)) = (due, &self.last_update) {
            self.publisher.publish(&self.outbox.status(update))?;
            self.last_status = Some(Instant::now());
        }
        Ok(())
    }

    /// The session.
    pub fn slam(&self) -> &LidarSlam {
        &self.slam
    }

    /// The map the robot's messages build: the session's keyframes at the poses last sent
    /// (within [`UpdateConfig::moved_m`] of the session's), what a merger that has every
    /// message holds.
    pub fn sent_map(&self) -> &LidarMap {
        self.sent.map()
    }

    /// Writes into the folder `dir` (which must exist) the session's `trajectory.tum` and
    /// `map.skmap`, and `sent.skmap`, the map its messages build ([`sent_map`](Self::sent_map));
    /// returns the run's [`report`](Self::report).
    ///
    /// # Errors
    /// [`FleetError::Slam`] when a file cannot be written.
    pub fn write(&self, dir: &Path, log: &CarmenLog) -> Result<Value, FleetError> {
        let trajectory = self.slam.trajectory();
        slamkit_io::trajectory_file::write_tum(&dir.join("trajectory.tum"), &trajectory)
            .map_err(slamkit_slam::SlamError::from)?;
        let path = dir.join("map.skmap");
        self.slam
            .map_file()
            .and_then(|f| f.save(&path))
            .map_err(|source| slamkit_slam::SlamError::MapFile { path, source })?;
        let notes = json!({ "method": "fleet robot: the map its updates build", "robot": self.config.robot });
        self.sent.map().save(&dir.join("sent.skmap"), notes)?;
        Ok(self.report(log))
    }

    /// The run's report: the session's ([`LidarSlam::run_report`] on `log`) with the fleet's
    /// counts: messages and bytes sent, the bytes of the map updates per second of the log
    /// against those of the scans as ROS 2 `LaserScan`s, and the merged maps taken so far.
    pub fn report(&self, log: &CarmenLog) -> Value {
        let mut report = self.slam.run_report(log);
        let scans = &log.scans[..self.scans_done.min(log.scans.len())];
        let log_seconds = match (scans.first(), scans.last()) {
            (Some(a), Some(b)) => b.timestamp - a.timestamp,
            _ => 0.0,
        };
        let update_bytes = self.publisher.stored_bytes();
        let raw_bytes: usize = scans
            .iter()
            .map(|s| laser_scan_cdr_bytes(s.ranges_m.len()))
            .sum();
        report["fleet"] = json!({
            "fleet": self.config.fleet,
            "robot": self.config.robot,
            "rate": self.config.rate,
            "resumed_from_message": self.resumed_from,
            "messages_stored": self.publisher.stored(),
            "messages_published": self.publisher.sent_messages(),
            "messages_dropped_on_purpose": self.publisher.dropped(),
            "disconnected_log_seconds": self.config.disconnect,
            "messages_held_back_while_disconnected": self.publisher.held_back(),
            "bytes_published": self.publisher.sent_bytes(),
            "update_bytes": update_bytes,
            "log_seconds": log_seconds,
            "update_bytes_per_log_second": update_bytes as f64 / log_seconds,
            "laser_scan_bytes_per_log_second": raw_bytes as f64 / log_seconds,
            "update_fraction_of_laser_scans": update_bytes as f64 / raw_bytes as f64,
            "sent_map_keyframes": self.sent.map().keyframes.len(),
            "merged_map": self.merged.receipts(),
            "merged_map_file": self.merged.path(),
        });
        report["wall_seconds"] = json!(self.started.elapsed().as_secs_f64());
        report
    }
}
