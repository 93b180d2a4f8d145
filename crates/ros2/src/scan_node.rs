//! What the planar lidar nodes share (`slamkit ros2 lidar` and `slamkit ros2 drone`): the
//! DDS readers and writers, the reader thread, the map thread, and the session thread that
//! ties scans to odometry ([`crate::pairing`]), applies the laser's mounting from
//! `/tf_static`, feeds the session (`ScanSession`) and publishes its pose, path and map.
//!
//! Three threads: one takes samples off the DDS readers as they come (so a slow scan match
//! never overflows a reader's history and drops scans), one runs the session and publishes,
//! one redraws the map every `map_update_interval_s` from the scans at the session's current
//! poses (a loop closure moves them all) without holding up the scans.
//!
//! A drone's range finders and IMU ([`DroneTopics`]) come on topics of their own, so their
//! readings and the scans are put back into time order ([`Collator`]) before the session
//! takes them; a reading that arrives while a scan waits for the odometry published after it
//! waits behind that scan, so the scan is never made late by readings newer than it.

use crate::dds::{
    advertise, dds, drain, latched_qos, published_ns, reliable_qos, sensor_qos, subscribe,
    PoseTopics, PoseWriters,
};
use crate::drone_readings::{DroneReadings, RangeSide};
use crate::grid_msg::occupancy_grid_msg;
use crate::lidar_node::{LidarNodeConfig, NodeMode, NodeStats, LATENCY_STAGE};
use crate::msgs::{self, Time};
use crate::Ros2Error;
use crossbeam_channel::{unbounded, Receiver, RecvTimeoutError, Sender};
use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::qos::History;
use ros2_client::{Node, Publisher, Subscription};
use slamkit_core::pose::{pose2_to_pose3, pose3_to_pose2};
use slamkit_core::{LaserScan, Observation, Pose2, Pose3};
use slamkit_io::bag::scans::{
    add_static_transforms, apply_mounting, mounting, odom_sample, to_laser_scan, StaticTree,
};
use slamkit_map::{OccupancyGrid, OccupancyGridConfig};
use slamkit_slam::lidar::grid_of_scans;
use slamkit_slam::{Collator, SlamError};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// What a planar lidar node needs of its session.
pub(crate) trait ScanSession {
    /// Takes a reading other than a scan (range finders, IMU), in time order with the scans.
    fn reading(&mut self, observation: Observation);
    /// Takes a scan (mounted, with its odometry), the last of `pushed` (every scan pushed
    /// so far); `map_from_base` when the session placed it.
    fn scan(&mut self, scan: LaserScan, pushed: &[LaserScan]) -> Option<Pose3>;
    /// A map to publish as it is, with no drawing (the particle filter's best map).
    fn live_grid(&self) -> Option<&OccupancyGrid> {
        None
    }
    /// The pose of every scan pushed so far for the map drawn now; `None`: left out.
    fn map_poses(&self) -> Vec<Option<Pose2>>;
    /// Height of the published map's plane \[m\] (a drone's layer; 0 on the ground).
    fn map_height_m(&self) -> f64 {
        0.0
    }
    /// The height layer of the last scan, published when it changes (a drone's).
    fn layer(&self) -> Option<i64> {
        None
    }
    /// The map to publish before any scan (localising in a saved map), if there is one.
    fn initial_grid(&self) -> Result<Option<OccupancyGrid>, SlamError>;
    /// The map drawn from `scans` (every scan pushed) at the final poses.
    fn output_grid(&self, scans: &[LaserScan]) -> Result<OccupancyGrid, SlamError>;
    /// Writes the map file.
    fn save(&self, path: &Path) -> Result<(), SlamError>;
}

/// A drone's other sensors: two `sensor_msgs/Range` topics and an IMU, and the published
/// height layer.
#[derive(Debug, Clone, PartialEq)]
pub struct DroneTopics {
    /// The up-looking range finder.
    pub range_up_topic: String,
    /// The down-looking range finder.
    pub range_down_topic: String,
    /// `sensor_msgs/Imu`; `None` for a drone without one.
    pub imu_topic: Option<String>,
    /// The current height layer out (`std_msgs/Int32`, reliable, transient local).
    pub layer_topic: String,
    /// Readings and scans are held this long of sensor time to be put in order \[s\].
    pub collate_window_s: f64,
}

impl Default for DroneTopics {
    fn default() -> Self {
        Self {
            range_up_topic: "/range_up".into(),
            range_down_topic: "/range_down".into(),
            imu_topic: Some("/imu".into()),
            layer_topic: "/slamkit/layer".into(),
            collate_window_s: 0.1,
        }
    }
}

/// A sample taken off a reader.
enum Incoming {
    Scan(i64, Instant, msgs::LaserScan),
    /// Boxed: two covariances make it five times the size of the rest.
    Odom(i64, Box<msgs::Odometry>),
    TfStatic(msgs::TfMessage),
    SaveMap(String),
    Range(RangeSide, msgs::Range),
    Imu(Box<msgs::Imu>),
    ReadError(String),
}

/// Work for the map thread.
enum MapJob {
    Scan(LaserScan),
    /// The poses, the stamp and the height of the map.
    Draw(Vec<Option<Pose2>>, Time, f64),
}

/// The node's DDS readers.
struct Readers {
    scan: Subscription<msgs::LaserScan>,
    odom: Option<Subscription<msgs::Odometry>>,
    tf_static: Subscription<msgs::TfMessage>,
    save: Subscription<String>,
    range_up: Option<Subscription<msgs::Range>>,
    range_down: Option<Subscription<msgs::Range>>,
    imu: Option<Subscription<msgs::Imu>>,
}

/// The node's DDS writers.
struct Writers {
    pose: PoseWriters,
    map: Publisher<msgs::OccupancyGrid>,
    map_metadata: Publisher<msgs::MapMetaData>,
    layer: Option<Publisher<i32>>,
}

fn open(
    config: &LidarNodeConfig,
    drone: Option<&DroneTopics>,
) -> Result<(Node, Readers, Writers), Ros2Error> {
    let mut node = config.discovery.node(&config.node_name)?;
    let n = &mut node;
    let sensor = sensor_qos();
    let scan = subscribe(n, &config.scan_topic, ("sensor_msgs", "LaserScan"), &sensor)?;
    let odom = match &config.odom_topic {
        Some(name) => Some(subscribe(n, name, ("nav_msgs", "Odometry"), &sensor)?),
        None => None,
    };
    let static_qos = latched_qos().history(History::KeepLast { depth: 100 });
    let tf_static = subscribe(
        n,
        &config.tf_static_topic,
        ("tf2_msgs", "TFMessage"),
        &static_qos,
    )?;
    let save = subscribe(
        n,
        &config.save_map_topic,
        ("std_msgs", "String"),
        &reliable_qos(10),
    )?;
    let range = ("sensor_msgs", "Range");
    let (mut range_up, mut range_down, mut imu, mut layer) = (None, None, None, None);
    if let Some(d) = drone {
        range_up = Some(subscribe(n, &d.range_up_topic, range, &sensor)?);
        range_down = Some(subscribe(n, &d.range_down_topic, range, &sensor)?);
        if let Some(name) = &d.imu_topic {
            imu = Some(subscribe(n, name, ("sensor_msgs", "Imu"), &sensor)?);
        }
        let int32 = ("std_msgs", "Int32");
        layer = Some(advertise(n, &d.layer_topic, int32, &latched_qos())?);
    }
    let topics = PoseTopics {
        tf: &config.tf_topic,
        pose: &config.pose_topic,
        path: config.path_topic.as_deref(),
    };
    let pose = PoseWriters::open(n, &topics)?;
    let grid = ("nav_msgs", "OccupancyGrid");
    let map = advertise(n, &config.map_topic, grid, &latched_qos())?;
    let metadata = ("nav_msgs", "MapMetaData");
    let map_metadata = advertise(n, &config.map_metadata_topic, metadata, &latched_qos())?;
    let readers = Readers {
        scan,
        odom,
        tf_static,
        save,
        range_up,
        range_down,
        imu,
    };
    let writers = Writers {
        pose,
        map,
        map_metadata,
        layer,
    };
    Ok((node, readers, writers))
}

/// Registers `reader` (when there is one) with the poll under `token`.
fn register<M: 'static + serde::de::DeserializeOwned>(
    poll: &Poll,
    reader: Option<&mut Subscription<M>>,
    token: usize,
) -> Result<(), Ros2Error> {
    match reader {
        Some(r) => poll
            .registry()
            .register(r, Token(token), Interest::READABLE)
            .map_err(dds("poll")),
        None => Ok(()),
    }
}

/// The reader thread: waits on the readers, forwards each sample, ends when `done` is set.
fn read_loop(
    mut readers: Readers,
    tx: Sender<Incoming>,
    done: &AtomicBool,
) -> Result<(), Ros2Error> {
    let mut poll = Poll::new().map_err(dds("poll"))?;
    register(&poll, Some(&mut readers.scan), 0)?;
    register(&poll, readers.odom.as_mut(), 1)?;
    register(&poll, Some(&mut readers.tf_static), 2)?;
    register(&poll, Some(&mut readers.save), 3)?;
    register(&poll, readers.range_up.as_mut(), 4)?;
    register(&poll, readers.range_down.as_mut(), 5)?;
    register(&poll, readers.imu.as_mut(), 6)?;
    let mut events = Events::with_capacity(16);
    while !done.load(Ordering::Relaxed) {
        poll.poll(&mut events, Some(Duration::from_millis(50)))
            .map_err(dds("poll"))?;
        // Edge-triggered: every reader is drained whatever woke the poll.
        if let Some(odom_reader) = &readers.odom {
            let odom = |m, i: &_| Incoming::Odom(published_ns(i), Box::new(m));
            drain(odom_reader, &tx, odom, Incoming::ReadError);
        }
        for (reader, side) in [
            (&readers.range_up, RangeSide::Up),
            (&readers.range_down, RangeSide::Down),
        ] {
            if let Some(reader) = reader {
                let range = |m, _: &_| Incoming::Range(side, m);
                drain(reader, &tx, range, Incoming::ReadError);
            }
        }
        if let Some(imu_reader) = &readers.imu {
            let imu = |m, _: &_| Incoming::Imu(Box::new(m));
            drain(imu_reader, &tx, imu, Incoming::ReadError);
        }
        let scan = |m, i: &_| Incoming::Scan(published_ns(i), Instant::now(), m);
        drain(&readers.scan, &tx, scan, Incoming::ReadError);
        let tf = |m, _: &_| Incoming::TfStatic(m);
        drain(&readers.tf_static, &tx, tf, Incoming::ReadError);
        let save = |m, _: &_| Incoming::SaveMap(m);
        drain(&readers.save, &tx, save, Incoming::ReadError);
    }
    Ok(())
}

/// `grid` as a map message at `stamp`, its plane at `height_m`.
fn map_msg(grid: &OccupancyGrid, frame: &str, stamp: Time, height_m: f64) -> msgs::OccupancyGrid {
    let mut msg = occupancy_grid_msg(grid, frame, stamp);
    msg.info.origin.position.z = height_m;
    msg
}

/// The map thread: keeps a copy of every scan, draws them at the poses it is sent.
fn map_loop(
    jobs: Receiver<MapJob>,
    out: Sender<msgs::OccupancyGrid>,
    config: OccupancyGridConfig,
    map_frame: &str,
) {
    let mut scans = Vec::new();
    while let Ok(job) = jobs.recv() {
        match job {
            MapJob::Scan(scan) => scans.push(scan),
            MapJob::Draw(poses, stamp, height_m) => {
                let posed = scans
                    .iter()
                    .zip(poses)
                    .filter_map(|(scan, pose)| Some((scan, pose?)));
                if let Ok(grid) = grid_of_scans(posed, config.clone()) {
                    if out
                        .send(map_msg(&grid, map_frame, stamp, height_m))
                        .is_err()
                    {
                        return;
                    }
                }
            }
        }
    }
}

/// Runs a planar lidar node on `session` until `stop` is set (or the input has been idle
/// `idle_exit_s`); with `drone`, also reads the drone's range finders and IMU. Returns the
/// session, every scan it was pushed (in order) and the counters.
pub(crate) fn run_scan_node<S: ScanSession>(
    config: &LidarNodeConfig,
    drone: Option<&DroneTopics>,
    session: S,
    stop: &AtomicBool,
) -> Result<(S, Vec<LaserScan>, NodeStats), Ros2Error> {
    let grid_config = OccupancyGridConfig {
        resolution_m: config.resolution_m,
        ..OccupancyGridConfig::default()
    };
    grid_config
        .validate()
        .map_err(|e| Ros2Error::Config(e.to_string()))?;
    let (_node, readers, writers) = open(config, drone)?;
    let (in_tx, in_rx) = unbounded();
    let (job_tx, job_rx) = unbounded();
    let (map_tx, map_rx) = unbounded();
    let readers_done = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let reader = scope.spawn(|| read_loop(readers, in_tx, &readers_done));
        let map_frame = config.map_frame.as_str();
        let drawer = scope.spawn(move || map_loop(job_rx, map_tx, grid_config, map_frame));
        let mut core = Core::new(config, drone, session, writers, job_tx);
        let result = core.run(&in_rx, &map_rx, stop);
        readers_done.store(true, Ordering::Relaxed);
        let read_result = reader
            .join()
            .unwrap_or_else(|_| Err(Ros2Error::Dds("the reader thread panicked".into())));
        core.close_map_thread();
        let _ = drawer.join();
        // The last map, drawn from the final poses, is published before returning.
        core.publish_final_map();
        result.and(read_result)?;
        Ok((core.session, core.scans, core.stats))
    })
}

/// The session thread's state.
struct Core<'a, S> {
    config: &'a LidarNodeConfig,
    session: S,
    writers: Writers,
    job_tx: Sender<MapJob>,
    jobs_open: bool,
    pairing: crate::pairing::OdometryPairing,
    /// A drone's readings, and the collator that orders them with the scans.
    drone: Option<(DroneReadings, Collator)>,
    /// Readings that came while a scan waited for its odometry, in arrival order.
    held: Vec<Observation>,
    /// Each waiting scan's stamp in seconds, when it was taken off its reader, and its stamp
    /// as sent (the session's seconds as `f64` would lose nanoseconds), in order.
    received: VecDeque<(f64, Instant, Time)>,
    statics: StaticTree,
    base_frame: Option<String>,
    laser_frame: Option<String>,
    scans: Vec<LaserScan>,
    stats: NodeStats,
    last_draw: Option<Instant>,
    last_message: Option<Instant>,
    last_stamp: Time,
    last_layer: Option<i64>,
}

impl<'a, S: ScanSession> Core<'a, S> {
    fn new(
        config: &'a LidarNodeConfig,
        drone: Option<&DroneTopics>,
        session: S,
        writers: Writers,
        job_tx: Sender<MapJob>,
    ) -> Self {
        let wait = if config.odom_topic.is_some() {
            Duration::from_secs_f64(config.odometry_wait_s.max(0.0))
        } else {
            Duration::ZERO
        };
        Self {
            config,
            session,
            writers,
            job_tx,
            jobs_open: true,
            pairing: crate::pairing::OdometryPairing::new(wait),
            drone: drone.map(|d| (DroneReadings::default(), Collator::new(d.collate_window_s))),
            held: Vec::new(),
            received: VecDeque::new(),
            statics: StaticTree::new(),
            base_frame: None,
            laser_frame: None,
            scans: Vec::new(),
            stats: NodeStats::default(),
            last_draw: None,
            last_message: None,
            last_stamp: Time::default(),
            last_layer: None,
        }
    }

    fn run(
        &mut self,
        incoming: &Receiver<Incoming>,
        maps: &Receiver<msgs::OccupancyGrid>,
        stop: &AtomicBool,
    ) -> Result<(), Ros2Error> {
        if self.config.mode == NodeMode::Localization {
            if let Some(grid) = self.session.initial_grid()? {
                let height = self.session.map_height_m();
                let frame = &self.config.map_frame;
                self.publish_map(map_msg(&grid, frame, Time::default(), height));
            }
        }
        while !stop.load(Ordering::Relaxed) {
            match incoming.recv_timeout(Duration::from_millis(20)) {
                Ok(msg) => {
                    self.last_message = Some(Instant::now());
                    self.take(msg);
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            let ready = self.pairing.release(Instant::now());
            self.process(ready);
            while let Ok(map) = maps.try_recv() {
                self.publish_map(map);
            }
            self.maybe_draw();
            let idle = self.config.idle_exit_s.map(Duration::from_secs_f64);
            if let (Some(idle), Some(last)) = (idle, self.last_message) {
                if self.stats.scans_received > 0 && last.elapsed() >= idle {
                    break;
                }
            }
        }
        let rest = self.pairing.finish();
        self.process(rest);
        let rest = match &mut self.drone {
            Some((_, collator)) => collator.finish(),
            None => Vec::new(),
        };
        rest.into_iter().for_each(|o| self.apply(o));
        if let Some((_, collator)) = &self.drone {
            self.stats.dropped_out_of_order = collator.dropped_late();
        }
        Ok(())
    }

    fn refuse(&mut self, why: String) {
        self.stats.undecodable.add(why);
    }

    fn take(&mut self, msg: Incoming) {
        match msg {
            Incoming::Scan(published, received, msg) => {
                self.stats.scans_received += 1;
                match msg.to_bag().and_then(|m| to_laser_scan(&m)) {
                    Ok(scan) => {
                        let t = scan.timestamp;
                        self.received.push_back((t, received, msg.header.stamp));
                        self.laser_frame.get_or_insert(msg.header.frame_id);
                        let ready = self.pairing.add_scan(published, scan, received);
                        self.process(ready);
                    }
                    Err(why) => self.refuse(format!("scan: {why}")),
                }
            }
            Incoming::Odom(published, msg) => {
                self.stats.odometry_received += 1;
                match msg.to_bag().and_then(|m| odom_sample(&m)) {
                    Ok(sample) => {
                        self.base_frame.get_or_insert(msg.child_frame_id);
                        let ready = self.pairing.add_odom(published, sample);
                        self.process(ready);
                    }
                    Err(why) => self.refuse(format!("odometry: {why}")),
                }
            }
            Incoming::TfStatic(msg) => {
                self.stats.tf_static_received += 1;
                let added = msg
                    .to_bag()
                    .and_then(|m| add_static_transforms(&mut self.statics, m));
                if let Err(why) = added {
                    self.refuse(format!("tf_static: {why}"));
                }
            }
            Incoming::SaveMap(stem) => {
                if let Err(why) = self.save_map(&stem) {
                    self.refuse(format!("save_map {stem}: {why}"));
                }
            }
            Incoming::Range(side, msg) => {
                self.stats.ranges_received += 1;
                let Some((readings, _)) = &mut self.drone else {
                    return;
                };
                match msg.to_bag().and_then(|m| readings.range(side, &m)) {
                    Ok(reading) => self.reading(reading),
                    Err(why) => self.refuse(format!("range: {why}")),
                }
            }
            Incoming::Imu(msg) => {
                self.stats.imu_received += 1;
                let Some((readings, _)) = &mut self.drone else {
                    return;
                };
                match msg.to_bag().and_then(|m| readings.imu(&m)) {
                    Ok(reading) => self.reading(reading),
                    Err(why) => self.refuse(format!("imu: {why}")),
                }
            }
            Incoming::ReadError(why) => self.refuse(format!("DDS read: {why}")),
        }
    }

    /// A reading waits behind the scans waiting for their odometry, else goes to the collator.
    fn reading(&mut self, observation: Observation) {
        if self.pairing.waiting() > 0 {
            self.held.push(observation);
        } else {
            self.collate(observation);
        }
    }

    /// Puts an observation in time order with the others and applies those now in order
    /// (a node without a collator applies it at once).
    fn collate(&mut self, observation: Observation) {
        let ready = match &mut self.drone {
            Some((_, collator)) => collator.push(observation),
            None => vec![observation],
        };
        ready.into_iter().for_each(|o| self.apply(o));
    }

    /// Mounts the paired scans and sends them on, then the readings that waited behind them.
    fn process(&mut self, scans: Vec<LaserScan>) {
        for mut scan in scans {
            let base = self.base_frame.as_deref().or(Some(&self.config.base_frame));
            let m = mounting(&self.statics, base, self.laser_frame.as_deref());
            apply_mounting(std::slice::from_mut(&mut scan), &m);
            self.stats.mounting = Some(m);
            self.collate(Observation::Scan(scan));
        }
        if self.pairing.waiting() == 0 {
            for reading in std::mem::take(&mut self.held) {
                self.collate(reading);
            }
        }
    }

    /// Gives the session one observation in order, and publishes what a scan gives.
    fn apply(&mut self, observation: Observation) {
        let scan = match observation {
            Observation::Scan(scan) => scan,
            reading => return self.session.reading(reading),
        };
        let (received, stamp) = self.scan_stamp(scan.timestamp);
        let odom = scan.odometry;
        if self.jobs_open && self.job_tx.send(MapJob::Scan(scan.clone())).is_err() {
            self.jobs_open = false;
        }
        self.scans.push(scan.clone());
        let pose = self.session.scan(scan, &self.scans);
        self.stats.scans_processed += 1;
        self.last_stamp = stamp;
        if let Some(map_from_base) = pose {
            self.publish_pose(&map_from_base, odom.as_ref(), stamp);
        }
        if let Some(t) = received {
            self.stats.latency.record_since(LATENCY_STAGE, t);
        }
        let layer = self.session.layer();
        if layer.is_some() && layer != self.last_layer {
            self.last_layer = layer;
            // the map on /map is the new layer's at once
            self.last_draw = None;
            if let (Some(writer), Some(l)) = (&self.writers.layer, layer) {
                let _ = writer.publish(i32::try_from(l).unwrap_or(i32::MAX));
            }
        }
    }

    /// When the scan stamped `t` was received and its stamp as sent (scans a collator dropped
    /// as out of order are forgotten on the way).
    fn scan_stamp(&mut self, t: f64) -> (Option<Instant>, Time) {
        match self.received.iter().position(|(s, _, _)| *s == t) {
            Some(i) => {
                let found = self.received.drain(..=i).next_back();
                found.map_or((None, Time::from_secs_f64(t)), |(_, r, s)| (Some(r), s))
            }
            None => (None, Time::from_secs_f64(t)),
        }
    }

    /// `map → odom` (REP 105: `map_from_odom = map_from_base · odom_from_base⁻¹`, in the
    /// ground plane: the odometry is planar) when the scan had odometry, else `map → base`.
    fn publish_pose(&mut self, map_from_base: &Pose3, odom: Option<&Pose2>, stamp: Time) {
        let (child, map_from_child) = match odom {
            Some(odom_from_base) => (
                self.config.odom_frame.as_str(),
                pose2_to_pose3(&(pose3_to_pose2(map_from_base) * odom_from_base.inverse())),
            ),
            None => (
                self.base_frame
                    .as_deref()
                    .unwrap_or(&self.config.base_frame),
                *map_from_base,
            ),
        };
        let child = child.to_string();
        let map = self.config.map_frame.clone();
        let tf = (map.as_str(), child.as_str(), &map_from_child);
        self.writers.pose.publish(tf, &map, map_from_base, stamp);
    }

    /// Sends the current poses to the map thread every `map_update_interval_s`.
    fn maybe_draw(&mut self) {
        if self.config.mode == NodeMode::Localization || self.stats.scans_processed == 0 {
            return;
        }
        let due = self.last_draw.map_or(true, |t| {
            t.elapsed().as_secs_f64() >= self.config.map_update_interval_s
        });
        if !due {
            return;
        }
        self.last_draw = Some(Instant::now());
        let height = self.session.map_height_m();
        if let Some(grid) = self.session.live_grid() {
            let msg = map_msg(grid, &self.config.map_frame, self.last_stamp, height);
            self.publish_map(msg);
        } else if self.jobs_open {
            let job = MapJob::Draw(self.session.map_poses(), self.last_stamp, height);
            self.jobs_open = self.job_tx.send(job).is_ok();
        }
    }

    fn publish_map(&mut self, map: msgs::OccupancyGrid) {
        let info = map.info;
        if self.writers.map.publish(map).is_ok() {
            self.stats.maps_published += 1;
        }
        let _ = self.writers.map_metadata.publish(info);
    }

    fn close_map_thread(&mut self) {
        let (closed, _) = unbounded();
        self.job_tx = closed;
        self.jobs_open = false;
    }

    fn publish_final_map(&mut self) {
        if self.config.mode == NodeMode::Localization || self.scans.is_empty() {
            return;
        }
        if let Ok(grid) = self.session.output_grid(&self.scans) {
            let height = self.session.map_height_m();
            let msg = map_msg(&grid, &self.config.map_frame, self.last_stamp, height);
            self.publish_map(msg);
        }
    }

    /// Saves the map as `stem.skmap`, `stem.pgm` and `stem.yaml`.
    fn save_map(&mut self, stem: &str) -> Result<(), Ros2Error> {
        let stem = PathBuf::from(stem);
        self.session.save(&stem.with_extension("skmap"))?;
        let grid = self.session.output_grid(&self.scans)?;
        slamkit_map::grid_io::save_map_yaml(&grid, &stem.with_extension("yaml"))
            .map_err(|e| Ros2Error::MapFile(e.to_string()))?;
        self.stats.maps_saved += 1;
        Ok(())
    }
}
