//! Recordings a viewer opens: a run written as an MCAP file (`--record FILE.mcap`) with
//! Foxglove's well-known schemas in JSON encoding, so Foxglove opens it directly with no
//! slamkit installed (the rerun viewer reads MCAP too, but draws Foxglove's schemas only in
//! their Protobuf encoding; it lists these messages raw): scans (`foxglove.LaserScan`), poses
//! (`foxglove.PoseInFrame`), the trajectory (`foxglove.PosesInFrame`), transforms
//! (`foxglove.FrameTransform`) and the map as it grows (`foxglove.Grid`, ROS occupancy values:
//! −1 unknown, 0 free, 100 occupied); from a camera, its images (`foxglove.CompressedImage`)
//! and the point map (`foxglove.PointCloud`).
//!
//! The file is written beside its final name and renamed into place by [`Recorder::finish`], so
//! a run that fails or is killed never leaves a half-written recording under that name.

mod demo;
mod nav;
mod visual;

pub use demo::record_demo;
pub use nav::NavRecording;
pub(crate) use visual::{encode_jpeg, EncodedImage};
pub use visual::{VisualRecording, IMAGE_TOPIC, LIVE_PATH_FRAMES};

use crate::SlamError;
use mcap::records::MessageHeader;
use serde_json::{json, Value};
use slamkit_core::{LaserScan, PointCloud, Pose3};
use slamkit_eval::report_html::base64;
use slamkit_map::TriGrid;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// A Foxglove schema: its name and the JSON Schema of its messages (the fields slamkit fills).
struct Schema {
    name: &'static str,
    properties: fn() -> Value,
}

fn time_schema() -> Value {
    json!({ "type": "object", "properties": {
        "sec": { "type": "integer" }, "nsec": { "type": "integer" } } })
}

fn pose_schema() -> Value {
    let xyz = |keys: &[&str]| {
        let props: serde_json::Map<String, Value> = keys
            .iter()
            .map(|k| (k.to_string(), json!({ "type": "number" })))
            .collect();
        json!({ "type": "object", "properties": props })
    };
    json!({ "type": "object", "properties": {
        "position": xyz(&["x", "y", "z"]), "orientation": xyz(&["x", "y", "z", "w"]) } })
}

const LASER_SCAN: Schema = Schema {
    name: "foxglove.LaserScan",
    properties: || {
        json!({
            "timestamp": time_schema(), "frame_id": { "type": "string" }, "pose": pose_schema(),
            "start_angle": { "type": "number" }, "end_angle": { "type": "number" },
            "ranges": { "type": "array", "items": { "type": "number" } },
            "intensities": { "type": "array", "items": { "type": "number" } },
        })
    },
};

const POSE_IN_FRAME: Schema = Schema {
    name: "foxglove.PoseInFrame",
    properties: || json!({ "timestamp": time_schema(), "frame_id": { "type": "string" }, "pose": pose_schema() }),
};

const POSES_IN_FRAME: Schema = Schema {
    name: "foxglove.PosesInFrame",
    properties: || {
        json!({ "timestamp": time_schema(), "frame_id": { "type": "string" },
                "poses": { "type": "array", "items": pose_schema() } })
    },
};

const FRAME_TRANSFORM: Schema = Schema {
    name: "foxglove.FrameTransform",
    properties: || {
        let p = pose_schema();
        json!({
            "timestamp": time_schema(), "parent_frame_id": { "type": "string" },
            "child_frame_id": { "type": "string" },
            "translation": p["properties"]["position"], "rotation": p["properties"]["orientation"],
        })
    },
};

const GRID: Schema = Schema {
    name: "foxglove.Grid",
    properties: || {
        json!({
            "timestamp": time_schema(), "frame_id": { "type": "string" }, "pose": pose_schema(),
            "column_count": { "type": "integer" },
            "cell_size": { "type": "object", "properties": {
                "x": { "type": "number" }, "y": { "type": "number" } } },
            "row_stride": { "type": "integer" }, "cell_stride": { "type": "integer" },
            "fields": { "type": "array", "items": { "type": "object", "properties": {
                "name": { "type": "string" }, "offset": { "type": "integer" },
                "type": { "type": "integer" } } } },
            "data": { "type": "string", "contentEncoding": "base64" },
        })
    },
};

const COMPRESSED_IMAGE: Schema = Schema {
    name: "foxglove.CompressedImage",
    properties: || {
        json!({
            "timestamp": time_schema(), "frame_id": { "type": "string" },
            "data": { "type": "string", "contentEncoding": "base64" },
            "format": { "type": "string" },
        })
    },
};

const POINT_CLOUD: Schema = Schema {
    name: "foxglove.PointCloud",
    properties: || {
        json!({
            "timestamp": time_schema(), "frame_id": { "type": "string" }, "pose": pose_schema(),
            "point_stride": { "type": "integer" },
            "fields": { "type": "array", "items": { "type": "object", "properties": {
                "name": { "type": "string" }, "offset": { "type": "integer" },
                "type": { "type": "integer" } } } },
            "data": { "type": "string", "contentEncoding": "base64" },
        })
    },
};

/// Foxglove's `PackedElementField` numeric types.
const UINT8: u8 = 1;
const INT8: u8 = 2;
const FLOAT32: u8 = 7;

/// A run being recorded to an MCAP file.
pub struct Recorder {
    writer: mcap::Writer<BufWriter<File>>,
    path: PathBuf,
    partial: PathBuf,
    schemas: BTreeMap<&'static str, u16>,
    channels: BTreeMap<String, u16>,
    counts: BTreeMap<String, u64>,
    last_log_time_ns: u64,
}

impl Recorder {
    /// Starts a recording that [`Recorder::finish`] puts at `path`.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be created.
    pub fn create(path: &Path) -> Result<Self, SlamError> {
        let mut name = path.file_name().unwrap_or_default().to_os_string();
        name.push(".partial");
        let partial = path.with_file_name(name);
        let file = File::create(&partial).map_err(|e| recording(path, e))?;
        let writer = mcap::WriteOptions::new()
            .compression(None)
            .profile("")
            .create(BufWriter::new(file))
            .map_err(|e| recording(path, e))?;
        Ok(Self {
            writer,
            path: path.to_path_buf(),
            partial,
            schemas: BTreeMap::new(),
            channels: BTreeMap::new(),
            counts: BTreeMap::new(),
            last_log_time_ns: 0,
        })
    }

    /// A scan on `topic`, in `frame` (the robot's base: the laser's mounting is the scan's
    /// pose in it), at the scan's time.
    pub fn scan(&mut self, topic: &str, frame: &str, scan: &LaserScan) -> Result<(), SlamError> {
        let n = scan.ranges_m.len();
        let end = scan.angle_min_rad + scan.angle_increment_rad * n.saturating_sub(1) as f64;
        // Foxglove draws no point for a range outside the valid band; JSON has no NaN.
        let ranges: Vec<f64> = scan
            .ranges_m
            .iter()
            .map(|&r| if r.is_finite() { r } else { 0.0 })
            .collect();
        let mount = slamkit_core::pose::pose2_to_pose3(&scan.base_from_laser);
        let message = json!({
            "timestamp": stamp(scan.timestamp), "frame_id": frame, "pose": pose_json(&mount),
            "start_angle": scan.angle_min_rad, "end_angle": end, "ranges": ranges,
            "intensities": [],
        });
        self.write(topic, &LASER_SCAN, scan.timestamp, &message)
    }

    /// A pose of `frame`'s child on `topic`, at time `t` \[s\].
    pub fn pose(
        &mut self,
        topic: &str,
        frame: &str,
        t: f64,
        pose: &Pose3,
    ) -> Result<(), SlamError> {
        let message = json!({ "timestamp": stamp(t), "frame_id": frame, "pose": pose_json(pose) });
        self.write(topic, &POSE_IN_FRAME, t, &message)
    }

    /// Poses in `frame` on `topic` (a trajectory so far), at time `t` \[s\].
    pub fn poses(
        &mut self,
        topic: &str,
        frame: &str,
        t: f64,
        poses: &[Pose3],
    ) -> Result<(), SlamError> {
        let poses: Vec<Value> = poses.iter().map(pose_json).collect();
        let message = json!({ "timestamp": stamp(t), "frame_id": frame, "poses": poses });
        self.write(topic, &POSES_IN_FRAME, t, &message)
    }

    /// `parent_from_child` on `/tf`, at time `t` \[s\].
    pub fn transform(
        &mut self,
        t: f64,
        parent: &str,
        child: &str,
        parent_from_child: &Pose3,
    ) -> Result<(), SlamError> {
        let p = pose_json(parent_from_child);
        let message = json!({
            "timestamp": stamp(t), "parent_frame_id": parent, "child_frame_id": child,
            "translation": p["position"], "rotation": p["orientation"],
        });
        self.write("/tf", &FRAME_TRANSFORM, t, &message)
    }

    /// `grid` on `topic` in `frame`, at time `t` \[s\] (ROS occupancy values: −1 unknown, 0
    /// free, 100 occupied).
    pub fn grid(
        &mut self,
        topic: &str,
        frame: &str,
        t: f64,
        grid: &TriGrid,
    ) -> Result<(), SlamError> {
        // Both count rows up from the grid's origin, x fastest.
        let cells: Vec<u8> = grid.cells().iter().map(|c| c.ros_value() as u8).collect();
        let o = grid.origin_m();
        let message = json!({
            "timestamp": stamp(t), "frame_id": frame,
            "pose": pose_json(&Pose3::translation(o.x, o.y, 0.0)),
            "column_count": grid.width(),
            "cell_size": { "x": grid.resolution_m(), "y": grid.resolution_m() },
            "row_stride": grid.width(), "cell_stride": 1,
            "fields": [{ "name": "occupancy", "offset": 0, "type": INT8 }],
            "data": base64(&cells),
        });
        self.write(topic, &GRID, t, &message)
    }

    /// An already encoded image (`format`: `jpeg` or `png`) of the camera `frame` on `topic`,
    /// at time `t` \[s\].
    pub fn compressed_image(
        &mut self,
        topic: &str,
        frame: &str,
        t: f64,
        format: &str,
        bytes: &[u8],
    ) -> Result<(), SlamError> {
        let message = json!({
            "timestamp": stamp(t), "frame_id": frame, "data": base64(bytes), "format": format,
        });
        self.write(topic, &COMPRESSED_IMAGE, t, &message)
    }

    /// `cloud` in `frame` on `topic`, at time `t` \[s\]: positions as 32-bit floats, and
    /// colours (opaque RGBA bytes) when the cloud has them.
    pub fn point_cloud(
        &mut self,
        topic: &str,
        frame: &str,
        t: f64,
        cloud: &PointCloud,
    ) -> Result<(), SlamError> {
        let colors = cloud.colors.as_ref();
        let stride = if colors.is_some() { 16 } else { 12 };
        let mut data = Vec::with_capacity(cloud.points.len() * stride);
        for (i, p) in cloud.points.iter().enumerate() {
            for v in [p.x, p.y, p.z] {
                data.extend_from_slice(&(v as f32).to_le_bytes());
            }
            if let Some(c) = colors.and_then(|c| c.get(i)) {
                data.extend_from_slice(&[c[0], c[1], c[2], 255]);
            }
        }
        let mut fields = vec![
            json!({ "name": "x", "offset": 0, "type": FLOAT32 }),
            json!({ "name": "y", "offset": 4, "type": FLOAT32 }),
            json!({ "name": "z", "offset": 8, "type": FLOAT32 }),
        ];
        if colors.is_some() {
            for (k, name) in ["red", "green", "blue", "alpha"].iter().enumerate() {
                fields.push(json!({ "name": name, "offset": 12 + k, "type": UINT8 }));
            }
        }
        let message = json!({
            "timestamp": stamp(t), "frame_id": frame, "pose": pose_json(&Pose3::identity()),
            "point_stride": stride, "fields": fields, "data": base64(&data),
        });
        self.write(topic, &POINT_CLOUD, t, &message)
    }

    /// Ends the recording: writes MCAP's summary and puts the file at its name; returns the
    /// messages written per topic.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be completed or renamed.
    pub fn finish(mut self) -> Result<BTreeMap<String, u64>, SlamError> {
        let path = self.path.clone();
        self.writer.finish().map_err(|e| recording(&path, e))?;
        drop(self.writer);
        std::fs::rename(&self.partial, &path).map_err(|e| recording(&path, e))?;
        Ok(self.counts)
    }

    fn write(
        &mut self,
        topic: &str,
        schema: &Schema,
        t: f64,
        message: &Value,
    ) -> Result<(), SlamError> {
        let path = self.path.clone();
        let channel = match self.channels.get(topic) {
            Some(&id) => id,
            None => {
                let schema_id = match self.schemas.get(schema.name) {
                    Some(&id) => id,
                    None => {
                        let text = json!({
                            "title": schema.name, "type": "object",
                            "properties": (schema.properties)(),
                        });
                        let id = self
                            .writer
                            .add_schema(schema.name, "jsonschema", text.to_string().as_bytes())
                            .map_err(|e| recording(&path, e))?;
                        self.schemas.insert(schema.name, id);
                        id
                    }
                };
                let id = self
                    .writer
                    .add_channel(schema_id, topic, "json", &BTreeMap::new())
                    .map_err(|e| recording(&path, e))?;
                self.channels.insert(topic.to_string(), id);
                id
            }
        };
        let count = self.counts.entry(topic.to_string()).or_default();
        // Log time is when the message was recorded, so it never goes back; a log whose
        // timestamps step back (the Intel log's do, by milliseconds) keeps them in the message.
        let time_ns = nanoseconds(t).max(self.last_log_time_ns);
        self.last_log_time_ns = time_ns;
        let header = MessageHeader {
            channel_id: channel,
            sequence: *count as u32,
            log_time: time_ns,
            publish_time: time_ns,
        };
        *count += 1;
        let bytes = message.to_string();
        self.writer
            .write_to_known_channel(&header, bytes.as_bytes())
            .map_err(|e| recording(&path, e))
    }
}

/// How many times a lidar recording writes the whole map over a run (and once more at its
/// end): each snapshot rebuilds the grid from every scan so far, so a fixed number of them costs
/// a few passes over the log whatever its length.
pub const MAP_SNAPSHOTS: usize = 10;

/// Scans between two map snapshots of a live run ([`LidarRecording::live`]), whose length is
/// not known in advance: each snapshot redraws every scan so far on the session's thread, so
/// they are spaced out (500 scans: under a minute of a 10 Hz lidar).
pub const LIVE_SNAPSHOT_SCANS: usize = 500;

/// A [`LidarSlam`](crate::LidarSlam) run being recorded: every scan with the pose it got (on
/// `/scan`, `/pose` and `map → base_link` on `/tf`), and the map and the path so far on `/map`
/// and `/path`, [`MAP_SNAPSHOTS`] times over the run and at its end.
pub struct LidarRecording {
    recorder: Recorder,
    every: usize,
    path: Vec<Pose3>,
}

impl LidarRecording {
    /// Starts recording a run of `scans` scans to `path`.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be created.
    pub fn create(path: &Path, scans: usize) -> Result<Self, SlamError> {
        Ok(Self {
            recorder: Recorder::create(path)?,
            every: scans.div_ceil(MAP_SNAPSHOTS).max(1),
            path: Vec::new(),
        })
    }

    /// Starts recording a live run (a ROS 2 node's) to `path`: the map and the path every
    /// [`LIVE_SNAPSHOT_SCANS`] scans and at the end.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be created.
    pub fn live(path: &Path) -> Result<Self, SlamError> {
        Ok(Self {
            recorder: Recorder::create(path)?,
            every: LIVE_SNAPSHOT_SCANS,
            path: Vec::new(),
        })
    }

    /// Records the last of `scans` (those pushed so far) and the `update` it gave.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be written, or the map not rebuilt.
    pub fn push(
        &mut self,
        session: &crate::LidarSlam,
        scans: &[LaserScan],
        update: &crate::session::Update,
    ) -> Result<(), SlamError> {
        let Some(scan) = scans.last() else {
            return Ok(());
        };
        self.recorder.scan("/scan", "base_link", scan)?;
        if let Some(pose) = &update.pose {
            self.recorder.pose("/pose", "map", update.timestamp, pose)?;
            self.recorder
                .transform(update.timestamp, "map", "base_link", pose)?;
            self.path.push(*pose);
        }
        if scans.len() % self.every == 0 {
            self.snapshot(session, scans, update.timestamp)?;
        }
        Ok(())
    }

    /// Records the final map and path, and ends the recording; returns the messages written
    /// per topic.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be completed.
    pub fn finish(
        mut self,
        session: &crate::LidarSlam,
        scans: &[LaserScan],
    ) -> Result<BTreeMap<String, u64>, SlamError> {
        if let Some(last) = scans.last() {
            self.snapshot(session, scans, last.timestamp)?;
        }
        self.recorder.finish()
    }

    fn snapshot(
        &mut self,
        session: &crate::LidarSlam,
        scans: &[LaserScan],
        t: f64,
    ) -> Result<(), SlamError> {
        let grid = TriGrid::from_occupancy_grid(&session.output_grid(scans)?);
        self.recorder.grid("/map", "map", t, &grid)?;
        self.recorder.poses("/path", "map", t, &self.path)
    }
}

fn recording(path: &Path, error: impl std::fmt::Display) -> SlamError {
    SlamError::Recording {
        path: path.to_path_buf(),
        message: error.to_string(),
    }
}

/// Time in nanoseconds; a negative or non-finite time (a damaged log) is clamped to 0.
fn nanoseconds(t: f64) -> u64 {
    if t.is_finite() && t > 0.0 {
        (t * 1e9).round() as u64
    } else {
        0
    }
}

fn stamp(t: f64) -> Value {
    let ns = nanoseconds(t);
    json!({ "sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000 })
}

fn pose_json(pose: &Pose3) -> Value {
    let (t, q) = (pose.translation.vector, pose.rotation.quaternion());
    json!({ "position": { "x": t.x, "y": t.y, "z": t.z },
            "orientation": { "x": q.i, "y": q.j, "z": q.k, "w": q.w } })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recording_appears_only_when_finished_and_counts_its_messages() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.mcap");
        let mut recorder = Recorder::create(&path).unwrap();
        let scan = LaserScan {
            timestamp: 2.5,
            angle_min_rad: -1.0,
            angle_increment_rad: 0.5,
            ranges_m: vec![1.0, f64::NAN, 2.0, 3.0, 4.0],
            max_range_m: 10.0,
            odometry: None,
            base_from_laser: slamkit_core::Pose2::identity(),
        };
        recorder.scan("/scan", "base_link", &scan).unwrap();
        recorder
            .pose("/pose", "map", 2.5, &Pose3::identity())
            .unwrap();
        recorder
            .pose("/pose", "map", 2.6, &Pose3::identity())
            .unwrap();
        assert!(!path.exists());
        let counts = recorder.finish().unwrap();
        assert_eq!(counts["/scan"], 1);
        assert_eq!(counts["/pose"], 2);
        let bytes = std::fs::read(&path).unwrap();
        let messages: Vec<_> = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap())
            .collect();
        assert_eq!(messages.len(), 3);
        let scan_json: Value = serde_json::from_slice(&messages[0].data).unwrap();
        assert_eq!(messages[0].channel.topic, "/scan");
        assert_eq!(
            messages[0].channel.schema.as_ref().unwrap().name,
            "foxglove.LaserScan"
        );
        assert_eq!(scan_json["end_angle"], 1.0);
        assert_eq!(scan_json["ranges"][1], 0.0);
        assert_eq!(scan_json["timestamp"]["nsec"], 500_000_000);
    }
}
