//! The 2D lidar node (`slamkit ros2 lidar`): `sensor_msgs/LaserScan` and `nav_msgs/Odometry`
//! in (ROS 2's sensor-data QoS: best effort, volatile), `/tf_static` for the laser's mounting;
//! a [`LidarSlam`] session, the one `slamkit lidar` runs on files; out: `nav_msgs/OccupancyGrid`
//! on `/map` and `nav_msgs/MapMetaData` on `/map_metadata` (reliable, transient local, as
//! `map_server` and `slam_toolbox` publish them), the `map → odom` transform on `/tf` (REP 105:
//! `map_from_odom = map_from_base · odom_from_base⁻¹` at the scan's stamp; `map → base` when
//! there is no odometry) and `geometry_msgs/PoseWithCovarianceStamped` on `/pose` for every
//! scan (as `slam_toolbox` does; the covariance is zero: the session does not estimate one).
//!
//! Three threads: one takes samples off the DDS readers as they come (so a slow scan match
//! never overflows a reader's history and drops scans), one runs the session and publishes,
//! one redraws the map every `map_update_interval_s` from the scans at the session's current
//! poses (a loop closure moves them all) without holding up the scans.
//!
//! Scans are tied to odometry in publication order ([`crate::pairing`]), so a log played into
//! the node gives the trajectory of the file run. A `std_msgs/String` on the save topic
//! (`/slamkit/save_map`) names a file stem: the map is saved there as `.skmap`, `.pgm` and
//! `.yaml` while the node runs.

use crate::dds::{
    advertise, dds, drain, latched_qos, published_ns, reliable_qos, sensor_qos, subscribe,
    Discovery, PoseTopics, PoseWriters, Refusals,
};
use crate::grid_msg::occupancy_grid_msg;
use crate::msgs::{self, Time};
use crate::Ros2Error;
use crossbeam_channel::{unbounded, Receiver, RecvTimeoutError, Sender};
use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::qos::History;
use ros2_client::{Node, Publisher, Subscription};
use slamkit_core::pose::pose2_to_pose3;
use slamkit_core::{LaserScan, Pose2, StageTimings};
use slamkit_io::bag::scans::{
    add_static_transforms, apply_mounting, mounting, odom_sample, to_laser_scan, Mounting,
    StaticTree,
};
use slamkit_map::OccupancyGridConfig;
use slamkit_slam::lidar::grid_of_scans;
use slamkit_slam::{LidarSlam, Session};
use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The stage of [`NodeStats::latency`]: a scan from its reader to its published pose.
pub const LATENCY_STAGE: &str = "scan_receive_to_publish";

/// Whether the node builds a map or localises in a saved one (`slam_toolbox`'s `mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeMode {
    /// A new map (or the continuation of a saved one).
    Mapping,
    /// Localisation in a saved map, which is published once and never changes.
    Localization,
}

/// Settings of the lidar node; the defaults are ROS 2's usual names.
#[derive(Debug, Clone, PartialEq)]
pub struct LidarNodeConfig {
    /// DDS domain and discovery.
    pub discovery: Discovery,
    /// The node's name.
    pub node_name: String,
    /// `sensor_msgs/LaserScan` topic.
    pub scan_topic: String,
    /// `nav_msgs/Odometry` topic; `None` for a robot without wheel odometry.
    pub odom_topic: Option<String>,
    /// Static transforms (the laser's mounting).
    pub tf_static_topic: String,
    /// Transforms out.
    pub tf_topic: String,
    /// The map out.
    pub map_topic: String,
    /// The map's metadata out.
    pub map_metadata_topic: String,
    /// The pose out.
    pub pose_topic: String,
    /// A `std_msgs/String` naming a file stem saves the map there.
    pub save_map_topic: String,
    /// The map frame (REP 105).
    pub map_frame: String,
    /// The odometry frame.
    pub odom_frame: String,
    /// The robot's frame when the odometry names none, and the child of `map` without odometry.
    pub base_frame: String,
    /// Mapping or localisation.
    pub mode: NodeMode,
    /// Seconds between map redraws (`slam_toolbox`'s `map_update_interval`).
    pub map_update_interval_s: f64,
    /// Side of a cell of the published map \[m\] (`resolution`).
    pub resolution_m: f64,
    /// Longest a scan waits for the odometry published after it \[s\].
    pub odometry_wait_s: f64,
    /// Stop once no message came for this long after the first scan \[s\] (a played log's end).
    pub idle_exit_s: Option<f64>,
}

impl Default for LidarNodeConfig {
    fn default() -> Self {
        Self {
            discovery: Discovery::default(),
            node_name: "slamkit".into(),
            scan_topic: "/scan".into(),
            odom_topic: Some("/odom".into()),
            tf_static_topic: "/tf_static".into(),
            tf_topic: "/tf".into(),
            map_topic: "/map".into(),
            map_metadata_topic: "/map_metadata".into(),
            pose_topic: "/pose".into(),
            save_map_topic: "/slamkit/save_map".into(),
            map_frame: "map".into(),
            odom_frame: "odom".into(),
            base_frame: "base_link".into(),
            mode: NodeMode::Mapping,
            map_update_interval_s: 5.0,
            resolution_m: OccupancyGridConfig::default().resolution_m,
            odometry_wait_s: 0.5,
            idle_exit_s: None,
        }
    }
}

/// Counters and timings of a node run.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct NodeStats {
    /// Scans received.
    pub scans_received: usize,
    /// Odometry messages received.
    pub odometry_received: usize,
    /// Static transform messages received.
    pub tf_static_received: usize,
    /// Messages that did not convert (the first few with why).
    pub undecodable: Refusals,
    /// Scans pushed into the session.
    pub scans_processed: usize,
    /// Maps published.
    pub maps_published: usize,
    /// Maps saved on request.
    pub maps_saved: usize,
    /// Per scan, [`LATENCY_STAGE`]: from taking it off the DDS reader to publishing its pose
    /// (it includes the wait for the next odometry reading).
    #[serde(skip)]
    pub latency: StageTimings,
    /// The laser's mounting used for the last scan.
    pub mounting: Option<Mounting>,
}

/// What a node run leaves: the session, every scan it was pushed (in order), the counters.
pub struct LidarNodeRun {
    /// The session, to save its map and trajectory.
    pub session: LidarSlam,
    /// The scans pushed, for the map of the session's poses.
    pub scans: Vec<LaserScan>,
    /// Counters.
    pub stats: NodeStats,
    /// Whether the node built a map or localised in a saved one.
    pub mode: NodeMode,
}

/// A sample taken off a reader.
enum Incoming {
    Scan(i64, Instant, msgs::LaserScan),
    /// Boxed: two covariances make it five times the size of the rest.
    Odom(i64, Box<msgs::Odometry>),
    TfStatic(msgs::TfMessage),
    SaveMap(String),
    ReadError(String),
}

/// Work for the map thread.
enum MapJob {
    Scan(LaserScan),
    Draw(Vec<Option<Pose2>>, Time),
}

/// The node's DDS readers.
struct Readers {
    scan: Subscription<msgs::LaserScan>,
    odom: Option<Subscription<msgs::Odometry>>,
    tf_static: Subscription<msgs::TfMessage>,
    save: Subscription<String>,
}

/// The node's DDS writers.
struct Writers {
    pose: PoseWriters,
    map: Publisher<msgs::OccupancyGrid>,
    map_metadata: Publisher<msgs::MapMetaData>,
}

fn open(config: &LidarNodeConfig) -> Result<(Node, Readers, Writers), Ros2Error> {
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
    let topics = PoseTopics {
        tf: &config.tf_topic,
        pose: &config.pose_topic,
        path: None,
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
    };
    let writers = Writers {
        pose,
        map,
        map_metadata,
    };
    Ok((node, readers, writers))
}

/// The reader thread: waits on the readers, forwards each sample, ends when `done` is set.
fn read_loop(
    mut readers: Readers,
    tx: Sender<Incoming>,
    done: &AtomicBool,
) -> Result<(), Ros2Error> {
    let mut poll = Poll::new().map_err(dds("poll"))?;
    let registry = poll.registry();
    registry
        .register(&mut readers.scan, Token(0), Interest::READABLE)
        .map_err(dds("poll scan"))?;
    if let Some(odom) = readers.odom.as_mut() {
        registry
            .register(odom, Token(1), Interest::READABLE)
            .map_err(dds("poll odom"))?;
    }
    registry
        .register(&mut readers.tf_static, Token(2), Interest::READABLE)
        .map_err(dds("poll tf_static"))?;
    registry
        .register(&mut readers.save, Token(3), Interest::READABLE)
        .map_err(dds("poll save_map"))?;
    let mut events = Events::with_capacity(16);
    while !done.load(Ordering::Relaxed) {
        poll.poll(&mut events, Some(Duration::from_millis(50)))
            .map_err(dds("poll"))?;
        // Edge-triggered: every reader is drained whatever woke the poll.
        if let Some(odom_reader) = &readers.odom {
            let odom = |m, i: &_| Incoming::Odom(published_ns(i), Box::new(m));
            drain(odom_reader, &tx, odom, Incoming::ReadError);
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
            MapJob::Draw(poses, stamp) => {
                let posed = scans
                    .iter()
                    .zip(poses)
                    .filter_map(|(scan, pose)| Some((scan, pose?)));
                if let Ok(grid) = grid_of_scans(posed, config.clone()) {
                    if out
                        .send(occupancy_grid_msg(&grid, map_frame, stamp))
                        .is_err()
                    {
                        return;
                    }
                }
            }
        }
    }
}

/// Runs the lidar node until `stop` is set (or the input has been idle `idle_exit_s`).
///
/// # Errors
/// DDS could not start, a topic or node name is not a valid ROS name, or the map thread's
/// settings are invalid.
pub fn run_lidar_node(
    config: &LidarNodeConfig,
    session: LidarSlam,
    stop: &AtomicBool,
) -> Result<LidarNodeRun, Ros2Error> {
    let grid_config = OccupancyGridConfig {
        resolution_m: config.resolution_m,
        ..OccupancyGridConfig::default()
    };
    grid_config
        .validate()
        .map_err(|e| Ros2Error::Config(e.to_string()))?;
    let (_node, readers, writers) = open(config)?;
    let (in_tx, in_rx) = unbounded();
    let (job_tx, job_rx) = unbounded();
    let (map_tx, map_rx) = unbounded();
    let readers_done = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let reader = scope.spawn(|| read_loop(readers, in_tx, &readers_done));
        let map_frame = config.map_frame.as_str();
        let drawer = scope.spawn(move || map_loop(job_rx, map_tx, grid_config, map_frame));
        let mut core = Core::new(config, session, writers, job_tx);
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
        Ok(core.into_run())
    })
}

/// The session thread's state.
struct Core<'a> {
    config: &'a LidarNodeConfig,
    session: LidarSlam,
    writers: Writers,
    job_tx: Sender<MapJob>,
    jobs_open: bool,
    pairing: crate::pairing::OdometryPairing,
    /// When each waiting scan was taken off its reader, and its stamp as sent (the session's
    /// seconds as `f64` would lose nanoseconds), in order.
    received: VecDeque<(Instant, Time)>,
    statics: StaticTree,
    base_frame: Option<String>,
    laser_frame: Option<String>,
    scans: Vec<LaserScan>,
    stats: NodeStats,
    last_draw: Option<Instant>,
    last_message: Option<Instant>,
    last_stamp: Time,
}

impl<'a> Core<'a> {
    fn new(
        config: &'a LidarNodeConfig,
        session: LidarSlam,
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
            received: VecDeque::new(),
            statics: StaticTree::new(),
            base_frame: None,
            laser_frame: None,
            scans: Vec::new(),
            stats: NodeStats::default(),
            last_draw: None,
            last_message: None,
            last_stamp: Time::default(),
        }
    }

    fn run(
        &mut self,
        incoming: &Receiver<Incoming>,
        maps: &Receiver<msgs::OccupancyGrid>,
        stop: &AtomicBool,
    ) -> Result<(), Ros2Error> {
        if self.config.mode == NodeMode::Localization {
            let grid = self.session.output_grid(&[])?;
            self.publish_map(occupancy_grid_msg(
                &grid,
                &self.config.map_frame,
                Time::default(),
            ));
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
                        self.received.push_back((received, msg.header.stamp));
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
            Incoming::ReadError(why) => self.refuse(format!("DDS read: {why}")),
        }
    }

    /// Pushes paired scans into the session and publishes what each gives.
    fn process(&mut self, scans: Vec<LaserScan>) {
        for mut scan in scans {
            let (received, stamp) = match self.received.pop_front() {
                Some((t, stamp)) => (Some(t), stamp),
                None => (None, Time::from_secs_f64(scan.timestamp)),
            };
            let base = self.base_frame.as_deref().or(Some(&self.config.base_frame));
            let m = mounting(&self.statics, base, self.laser_frame.as_deref());
            apply_mounting(std::slice::from_mut(&mut scan), &m);
            self.stats.mounting = Some(m);
            let odom = scan.odometry;
            if self.jobs_open && self.job_tx.send(MapJob::Scan(scan.clone())).is_err() {
                self.jobs_open = false;
            }
            self.scans.push(scan.clone());
            let update = self.session.push_scan(scan);
            self.stats.scans_processed += 1;
            self.last_stamp = stamp;
            if let Some(map_from_base) = update.pose {
                self.publish_pose(&map_from_base, odom.as_ref(), stamp);
            }
            if let Some(t) = received {
                self.stats.latency.record_since(LATENCY_STAGE, t);
            }
        }
    }

    fn publish_pose(
        &mut self,
        map_from_base: &slamkit_core::Pose3,
        odom: Option<&Pose2>,
        stamp: Time,
    ) {
        let (child, map_from_child) = match odom {
            Some(odom_from_base) => (
                self.config.odom_frame.as_str(),
                map_from_base * pose2_to_pose3(odom_from_base).inverse(),
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
        if let Some(grid) = self.session.particle_grid() {
            let msg = occupancy_grid_msg(grid, &self.config.map_frame, self.last_stamp);
            self.publish_map(msg);
        } else if self.jobs_open {
            let job = MapJob::Draw(self.session.poses(), self.last_stamp);
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
            let msg = occupancy_grid_msg(&grid, &self.config.map_frame, self.last_stamp);
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

    fn into_run(self) -> LidarNodeRun {
        LidarNodeRun {
            session: self.session,
            scans: self.scans,
            stats: self.stats,
            mode: self.config.mode,
        }
    }
}
