//! Encoding and decoding of map update messages (the layout is in [`super`]'s documentation).

use super::{MapUpdate, RobotStatus, UpdateBody, ANGLE_STEP_RAD, POSITION_STEP_M, UPDATE_MAGIC};
use crate::lidar::map::{
    get_edge_weights, put_edge_weights, quantise_range, range_from_mm, INVALID_RANGE,
};
use crate::lidar::MapKeyframe;
use crate::map_file::codec::{Reader, Writer};
use crate::map_file::{MapFileError, FORMAT_VERSION};
use crate::session::TrackingStatus;
use flate2::read::DeflateDecoder;
use flate2::write::DeflateEncoder;
use flate2::Compression;
use slamkit_core::{LaserScan, Pose2};
use slamkit_lidar::pose_graph::Edge;
use std::io::{Read, Write};

/// A message whose body inflates past this is refused (a corrupt stream, not a batch).
const MAX_BODY_BYTES: u64 = 64 << 20;
/// Positions beyond this are refused \[m\] (they would not fit the grid's integers).
const MAX_POSITION_M: f64 = 1e9;
const KEYFRAMES: u8 = 0;
const EDGES: u8 = 1;
const STATUS: u8 = 2;

/// A pose as whole grid steps `[x, y, θ]`; positions beyond [`MAX_POSITION_M`] saturate (the
/// encoder refuses them first).
pub(super) fn grid_pose(pose: &Pose2) -> [i64; 3] {
    let t = pose.translation.vector;
    [
        (t.x / POSITION_STEP_M).round() as i64,
        (t.y / POSITION_STEP_M).round() as i64,
        (pose.rotation.angle() / ANGLE_STEP_RAD).round() as i64,
    ]
}

/// The pose of grid steps `x, y, a`.
pub(super) fn pose_from_grid(x: i64, y: i64, a: i64) -> Pose2 {
    Pose2::new(
        [x as f64 * POSITION_STEP_M, y as f64 * POSITION_STEP_M].into(),
        a as f64 * ANGLE_STEP_RAD,
    )
}

/// Writes poses one after another, each as the difference from the one before.
struct PoseDeltas {
    last: [i64; 3],
}

impl PoseDeltas {
    fn new() -> Self {
        Self { last: [0; 3] }
    }

    fn put(&mut self, w: &mut Writer, pose: &Pose2) -> Result<(), MapFileError> {
        let t = pose.translation.vector;
        if !(t.x.abs() < MAX_POSITION_M && t.y.abs() < MAX_POSITION_M) {
            return Err(MapFileError::Malformed(format!(
                "a pose at ({}, {}) is not a finite position within {MAX_POSITION_M} m",
                t.x, t.y
            )));
        }
        let grid = grid_pose(pose);
        for (v, last) in grid.iter().zip(&mut self.last) {
            w.signed_varint(v - *last);
            *last = *v;
        }
        Ok(())
    }

    fn get(&mut self, r: &mut Reader<'_>) -> Result<Pose2, MapFileError> {
        for last in &mut self.last {
            let d = r.signed_varint()?;
            *last = last
                .checked_add(d)
                .ok_or_else(|| MapFileError::Malformed("a pose difference overflows".into()))?;
        }
        let [x, y, a] = self.last;
        Ok(pose_from_grid(x, y, a))
    }
}

impl MapUpdate {
    /// The message's bytes.
    ///
    /// # Errors
    /// [`MapFileError::Malformed`] for a pose that is not finite or lies beyond 10⁹ m, or
    /// counts beyond 2³².
    pub fn to_bytes(&self) -> Result<Vec<u8>, MapFileError> {
        let mut body = Writer::new();
        let kind = match &self.body {
            UpdateBody::Keyframes { first, keyframes } => {
                body.varint(*first as u64);
                put_keyframes(&mut body, keyframes)?;
                KEYFRAMES
            }
            UpdateBody::Edges { edges, moved } => {
                put_edges(&mut body, edges, moved)?;
                EDGES
            }
            UpdateBody::Status(status) => {
                put_status(&mut body, status)?;
                STATUS
            }
        };
        let mut w = Writer::new();
        w.bytes(&UPDATE_MAGIC);
        w.bytes(&FORMAT_VERSION.0.to_le_bytes());
        w.bytes(&FORMAT_VERSION.1.to_le_bytes());
        w.u8(kind);
        w.varint(self.seq);
        let mut encoder = DeflateEncoder::new(w.into_bytes(), Compression::best());
        encoder.write_all(&body.into_bytes())?;
        Ok(encoder.finish()?)
    }

    /// Parses a message: magic and version first, then the content.
    ///
    /// # Errors
    /// [`MapFileError::NotAMap`] without the magic bytes, [`MapFileError::NewerVersion`] for
    /// a newer major version, [`MapFileError::Malformed`] for anything else wrong.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, MapFileError> {
        if bytes.get(..UPDATE_MAGIC.len()) != Some(&UPDATE_MAGIC[..]) {
            return Err(MapFileError::NotAMap);
        }
        let mut r = Reader::new(&bytes[UPDATE_MAGIC.len()..], "the update message");
        let major = u16::from_le_bytes([r.u8()?, r.u8()?]);
        let minor = u16::from_le_bytes([r.u8()?, r.u8()?]);
        if major > FORMAT_VERSION.0 {
            return Err(MapFileError::NewerVersion(major, minor, FORMAT_VERSION.0));
        }
        let kind = r.u8()?;
        let seq = r.varint()?;
        let compressed = r.take(r.remaining())?;
        let mut data = Vec::new();
        DeflateDecoder::new(compressed)
            .take(MAX_BODY_BYTES + 1)
            .read_to_end(&mut data)
            .map_err(|e| MapFileError::Malformed(format!("update body: {e}")))?;
        if data.len() as u64 > MAX_BODY_BYTES {
            return Err(MapFileError::Malformed("update body too large".into()));
        }
        let mut r = Reader::new(&data, "the update body");
        let body = match kind {
            KEYFRAMES => {
                let first = usize::try_from(r.varint()?)
                    .map_err(|_| MapFileError::Malformed("keyframe index too large".into()))?;
                UpdateBody::Keyframes {
                    first,
                    keyframes: get_keyframes(&mut r)?,
                }
            }
            EDGES => {
                let (edges, moved) = get_edges(&mut r)?;
                UpdateBody::Edges { edges, moved }
            }
            STATUS => UpdateBody::Status(get_status(&mut r)?),
            other => {
                return Err(MapFileError::Malformed(format!(
                    "unknown update kind {other}"
                )))
            }
        };
        r.finish()?;
        Ok(Self { seq, body })
    }
}

/// A count as a varint.
fn put_count(w: &mut Writer, n: usize) {
    w.varint(n as u64);
}

/// A count of items of at least one byte each, checked against the bytes left.
fn get_count(r: &mut Reader<'_>) -> Result<usize, MapFileError> {
    let n = r.varint()?;
    if n > r.remaining() as u64 {
        return Err(MapFileError::Malformed(format!(
            "a count of {n} beyond the {} bytes left",
            r.remaining()
        )));
    }
    Ok(n as usize)
}

fn put_keyframes(w: &mut Writer, keyframes: &[MapKeyframe]) -> Result<(), MapFileError> {
    put_count(w, keyframes.len());
    let mut poses = PoseDeltas::new();
    for kf in keyframes {
        poses.put(w, &kf.world_from_base)?;
        put_scan(w, &kf.scan)?;
    }
    Ok(())
}

fn get_keyframes(r: &mut Reader<'_>) -> Result<Vec<MapKeyframe>, MapFileError> {
    let n = get_count(r)?;
    let mut poses = PoseDeltas::new();
    let mut keyframes = Vec::with_capacity(n);
    for _ in 0..n {
        let world_from_base = poses.get(r)?;
        keyframes.push(MapKeyframe {
            world_from_base,
            scan: get_scan(r)?,
        });
    }
    Ok(keyframes)
}

/// A scan: time, mounting, beam geometry, the ranges' common step in millimetres, and each
/// range in steps plus one (0: not a number), as the difference from the beam before.
/// Odometry is not sent.
fn put_scan(w: &mut Writer, scan: &LaserScan) -> Result<(), MapFileError> {
    w.f64(scan.timestamp);
    PoseDeltas::new().put(w, &scan.base_from_laser)?;
    w.f64(scan.angle_min_rad);
    w.f64(scan.angle_increment_rad);
    w.f64(scan.max_range_m);
    put_count(w, scan.ranges_m.len());
    let mm: Vec<u32> = scan.ranges_m.iter().map(|r| quantise_range(*r)).collect();
    // the ranges' common step (10 for a lidar that reports whole centimetres): lossless, and
    // the differences shrink by it
    let step = mm
        .iter()
        .filter(|v| **v != INVALID_RANGE)
        .fold(0, |g, v| gcd(g, *v))
        .max(1);
    w.varint(u64::from(step));
    let mut last = 0i64;
    for v in mm {
        let v = match v {
            INVALID_RANGE => 0,
            mm => i64::from(mm / step) + 1,
        };
        w.signed_varint(v - last);
        last = v;
    }
    Ok(())
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

fn get_scan(r: &mut Reader<'_>) -> Result<LaserScan, MapFileError> {
    let timestamp = r.f64()?;
    let base_from_laser = PoseDeltas::new().get(r)?;
    let angle_min_rad = r.f64()?;
    let angle_increment_rad = r.f64()?;
    let max_range_m = r.f64()?;
    let beams = get_count(r)?;
    let step = i64::try_from(r.varint()?)
        .ok()
        .filter(|s| (1..i64::from(INVALID_RANGE)).contains(s))
        .ok_or_else(|| MapFileError::Malformed("a range step out of bounds".into()))?;
    let mut ranges_m = Vec::with_capacity(beams);
    let mut last = 0i64;
    for _ in 0..beams {
        last = last
            .checked_add(r.signed_varint()?)
            .filter(|v| *v >= 0)
            .ok_or_else(|| MapFileError::Malformed("a range out of bounds".into()))?;
        ranges_m.push(match last {
            0 => f64::NAN,
            v => (v - 1)
                .checked_mul(step)
                .and_then(|mm| u32::try_from(mm).ok())
                .filter(|mm| *mm != INVALID_RANGE)
                .map(range_from_mm)
                .ok_or_else(|| MapFileError::Malformed("a range out of bounds".into()))?,
        });
    }
    Ok(LaserScan {
        timestamp,
        angle_min_rad,
        angle_increment_rad,
        ranges_m,
        max_range_m,
        odometry: None,
        base_from_laser,
    })
}

fn put_edges(w: &mut Writer, edges: &[Edge], moved: &[(usize, Pose2)]) -> Result<(), MapFileError> {
    put_count(w, edges.len());
    for e in edges {
        w.varint(e.from as u64);
        w.varint(e.to as u64);
        PoseDeltas::new().put(w, &e.from_from_to)?;
        put_edge_weights(w, e);
    }
    put_count(w, moved.len());
    let mut poses = PoseDeltas::new();
    let mut last = 0usize;
    for (i, (keyframe, pose)) in moved.iter().enumerate() {
        if i > 0 && *keyframe <= last {
            return Err(MapFileError::Malformed(
                "moved keyframes must be in increasing order".into(),
            ));
        }
        w.varint((keyframe - last) as u64);
        last = *keyframe;
        poses.put(w, pose)?;
    }
    Ok(())
}

type EdgesAndMoved = (Vec<Edge>, Vec<(usize, Pose2)>);

fn get_edges(r: &mut Reader<'_>) -> Result<EdgesAndMoved, MapFileError> {
    let index = |v: u64| {
        usize::try_from(v).map_err(|_| MapFileError::Malformed("keyframe index too large".into()))
    };
    let n = get_count(r)?;
    let mut edges = Vec::with_capacity(n);
    for _ in 0..n {
        let from = index(r.varint()?)?;
        let to = index(r.varint()?)?;
        let from_from_to = PoseDeltas::new().get(r)?;
        let (information, robust_scale) = get_edge_weights(r, from, to)?;
        edges.push(Edge {
            from,
            to,
            from_from_to,
            information,
            robust_scale,
        });
    }
    let n = get_count(r)?;
    let mut moved = Vec::with_capacity(n);
    let mut poses = PoseDeltas::new();
    let mut last = 0usize;
    for i in 0..n {
        let step = index(r.varint()?)?;
        if i > 0 && step == 0 {
            return Err(MapFileError::Malformed(
                "moved keyframes must be in increasing order".into(),
            ));
        }
        last = last
            .checked_add(step)
            .ok_or_else(|| MapFileError::Malformed("keyframe index too large".into()))?;
        moved.push((last, poses.get(r)?));
    }
    Ok((edges, moved))
}

fn put_status(w: &mut Writer, status: &RobotStatus) -> Result<(), MapFileError> {
    w.f64(status.timestamp);
    w.u8(match status.tracking {
        TrackingStatus::Initialising => 0,
        TrackingStatus::Tracking => 1,
        TrackingStatus::Predicted => 2,
        TrackingStatus::Lost => 3,
    });
    match &status.pose {
        Some(pose) => {
            w.u8(1);
            PoseDeltas::new().put(w, pose)?;
        }
        None => w.u8(0),
    }
    put_count(w, status.keyframes);
    Ok(())
}

fn get_status(r: &mut Reader<'_>) -> Result<RobotStatus, MapFileError> {
    let timestamp = r.f64()?;
    let tracking = match r.u8()? {
        0 => TrackingStatus::Initialising,
        1 => TrackingStatus::Tracking,
        2 => TrackingStatus::Predicted,
        3 => TrackingStatus::Lost,
        other => {
            return Err(MapFileError::Malformed(format!(
                "unknown tracking status {other}"
            )))
        }
    };
    let pose = match r.u8()? {
        0 => None,
        1 => Some(PoseDeltas::new().get(r)?),
        flag => return Err(MapFileError::Malformed(format!("pose flag {flag}"))),
    };
    let keyframes = usize::try_from(r.varint()?)
        .map_err(|_| MapFileError::Malformed("keyframe count too large".into()))?;
    Ok(RobotStatus {
        timestamp,
        tracking,
        pose,
        keyframes,
    })
}
