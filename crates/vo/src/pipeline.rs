//! The threaded pipeline: four threads — read (decode images), prepare (preprocess, detect,
//! describe, depth), track (motion estimation) and map (points from the depth image into the
//! voxel point map) — joined by bounded
//! crossbeam channels, so a slow stage holds the ones before it back instead of letting queues
//! (and memory) grow.
//!
//! In real-time mode the reader plays the dataset at its own clock (frame time stamps) and
//! offers each frame to the pipeline without waiting: a frame arriving while the prepare stage
//! still has [`REALTIME_QUEUE`] frames waiting is dropped and counted, as a live camera driver
//! with a ring of that many buffers would; and the tracker hands a pose and its points to the
//! point map without waiting either, so a slow map update (a hash table growing) skips that
//! frame's points instead of holding tracking back. Otherwise every frame is processed and
//! mapped.
//!
//! Per-frame time (`frame` in the timings) is the prepare and track work of one frame, image
//! decoding excluded; each stage's own time is recorded under its name. Prepare and track times
//! are the CPU time of their threads (one core each), so they measure the work of a frame, not
//! how long other processes on the machine held the core.

use std::time::{Duration, Instant};

use cpu_time::ThreadTime;

use crossbeam_channel::{bounded, Receiver, Sender, TrySendError};
use serde::Serialize;
use slamkit_core::{Pose3, StageTimings, Trajectory};
use slamkit_io::{Dataset, IoError};

use crate::config::VoConfig;
use crate::error::VoError;
use crate::frame::{MapSource, PreparedFrame, Preprocessor, Rig, SensorImages};
use crate::odometry::{FailReason, FrameStatus, Odometry};
use crate::voxel_map::VoxelMap;

/// Decoded frames the real-time reader may queue ahead of the prepare stage (a camera driver's
/// buffer ring; V4L2 drivers commonly keep four).
pub const REALTIME_QUEUE: usize = 4;

/// How the dataset is played.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunOptions {
    /// Play at the frame rate of the time stamps and drop frames the pipeline cannot take.
    pub realtime: bool,
}

/// Frame counts of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RunStats {
    /// Frames in the dataset.
    pub frames: usize,
    /// Frames read and handed to the pipeline.
    pub read: usize,
    /// Frames dropped in real-time mode because the pipeline was busy.
    pub dropped: usize,
    /// Frames tracked but left out of the point map in real-time mode because the mapper was
    /// busy.
    pub unmapped: usize,
    /// Frames tracked or used to (re)start tracking.
    pub processed: usize,
    /// Frames that failed (unreadable, too dark, no depth, no motion).
    pub failed: usize,
    /// Tracking (re)starts.
    pub initialisations: usize,
}

/// One frame's outcome.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameRecord {
    /// Position in the dataset.
    pub index: usize,
    /// Time stamp \[s\].
    pub timestamp: f64,
    /// What happened.
    pub status: FrameStatus,
}

/// Everything a run produces.
#[derive(Debug)]
pub struct VoRun {
    /// One pose per frame that went through the pipeline, `world_from_camera` of the dataset's
    /// camera (the depth camera for registered RGB-D, the left camera for stereo).
    pub trajectory: Trajectory,
    /// Per-frame outcomes, in frame order.
    pub frames: Vec<FrameRecord>,
    /// Counts.
    pub stats: RunStats,
    /// Per-stage timings \[ms\].
    pub timings: StageTimings,
    /// The world point map.
    pub map: VoxelMap,
}

/// Messages of the read → prepare channel.
struct Decoded {
    index: usize,
    timestamp: f64,
    images: Result<SensorImages, String>,
}

/// Messages of the prepare → track channel.
struct Prepared {
    index: usize,
    timestamp: f64,
    frame: Result<PreparedFrame, FailReason>,
    prepare_ms: f64,
}

/// Messages of the track → map channel.
struct Tracked {
    world_from_camera: Pose3,
    points: Option<MapSource>,
}

/// Runs visual odometry over `dataset`; `progress` is called once per frame that reaches the
/// tracker.
///
/// # Errors
/// [`VoError`] for an invalid configuration or an empty dataset; bad frames are counted, not
/// errors.
pub fn run(
    dataset: &Dataset,
    config: &VoConfig,
    options: RunOptions,
    progress: impl Fn() + Send + Sync,
) -> Result<VoRun, VoError> {
    if dataset.is_empty() {
        return Err(VoError::EmptyDataset {
            path: root(dataset),
        });
    }
    let mut pre = Preprocessor::new(config, rig(dataset))?;
    // the tracked camera's frame vs the dataset's (depth) camera, for registered RGB-D
    let camera_from_tracked = config
        .register_depth
        .as_ref()
        .map_or(Pose3::identity(), |r| r.color_from_depth().inverse());
    let first = dataset
        .ground_truth()
        .and_then(|gt| gt.poses.first())
        .map_or(Pose3::identity(), |p| p.pose);
    let mut odometry = Odometry::new(config, first * camera_from_tracked);
    let queue = if options.realtime { REALTIME_QUEUE } else { 1 };
    let (tx_decoded, rx_decoded) = bounded::<Decoded>(queue);
    let (tx_prepared, rx_prepared) = bounded::<Prepared>(2);
    let (tx_tracked, rx_tracked) = bounded::<Tracked>(4);
    let mut map = VoxelMap::new(config.voxel_map.clone());
    std::thread::scope(|s| {
        let reader = s.spawn(move || read_stage(dataset, options, &tx_decoded));
        let preparer = s.spawn(move || prepare_stage(&mut pre, &rx_decoded, &tx_prepared));
        let mapper = s.spawn(|| map_stage(&mut map, &rx_tracked));
        let tracked = track_stage(
            &mut odometry,
            (&rx_prepared, &tx_tracked),
            camera_from_tracked,
            options,
            &progress,
        );
        drop(tx_tracked);
        let (read, dropped, mut timings) = reader.join().unwrap_or_default();
        timings.merge(&preparer.join().unwrap_or_default());
        timings.merge(&mapper.join().unwrap_or_default());
        let (trajectory, frames, track_timings, unmapped) = tracked;
        timings.merge(&track_timings);
        let failed = frames
            .iter()
            .filter(|f| matches!(f.status, FrameStatus::Failed(_)))
            .count();
        let initialisations = frames
            .iter()
            .filter(|f| matches!(f.status, FrameStatus::Initialised { .. }))
            .count();
        let stats = RunStats {
            frames: dataset.len(),
            read,
            dropped,
            unmapped,
            processed: frames.len() - failed,
            failed,
            initialisations,
        };
        Ok((trajectory, frames, stats, timings))
    })
    .map(|(trajectory, frames, stats, timings)| VoRun {
        trajectory,
        frames,
        stats,
        timings,
        map,
    })
}

fn root(dataset: &Dataset) -> String {
    match dataset {
        Dataset::Rgbd(s) => s.root.display().to_string(),
        Dataset::Stereo(s) => s.root.display().to_string(),
    }
}

/// The rig of a dataset.
pub fn rig(dataset: &Dataset) -> Rig {
    match dataset {
        Dataset::Rgbd(s) => Rig::Rgbd {
            color: s.color_camera.intrinsics,
            depth: s.depth_camera.intrinsics,
        },
        Dataset::Stereo(s) => Rig::Stereo {
            left: s.left_camera.intrinsics,
            baseline_m: s.baseline_m(),
        },
    }
}

fn load(dataset: &Dataset, index: usize) -> Option<(f64, Result<SensorImages, String>)> {
    match dataset {
        Dataset::Rgbd(s) => decode(s.frames.get(index)?, |f| f.timestamp, |f| s.load(f)),
        Dataset::Stereo(s) => decode(s.frames.get(index)?, |f| f.timestamp, |f| s.load(f)),
    }
}

/// The time stamp and decoded images of `frame`.
fn decode<F, I: Into<SensorImages>>(
    frame: &F,
    timestamp: impl Fn(&F) -> f64,
    load: impl Fn(&F) -> Result<I, IoError>,
) -> Option<(f64, Result<SensorImages, String>)> {
    Some((
        timestamp(frame),
        load(frame).map(Into::into).map_err(|e| e.to_string()),
    ))
}

/// Reads every frame; returns (frames handed on, frames dropped, decoding times).
fn read_stage(
    dataset: &Dataset,
    options: RunOptions,
    tx: &Sender<Decoded>,
) -> (usize, usize, StageTimings) {
    let start = Instant::now();
    let t0 = dataset.timestamps().first().copied().unwrap_or(0.0);
    let (mut read, mut dropped) = (0, 0);
    let mut timings = StageTimings::default();
    for index in 0..dataset.len() {
        let decode_start = ThreadTime::now();
        let Some((timestamp, images)) = load(dataset, index) else {
            break;
        };
        timings.record("decode", decode_start.elapsed().as_secs_f64() * 1e3);
        let msg = Decoded {
            index,
            timestamp,
            images,
        };
        if options.realtime {
            let due = Duration::from_secs_f64((timestamp - t0).max(0.0));
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
            match tx.try_send(msg) {
                Ok(()) => read += 1,
                Err(TrySendError::Full(_)) => dropped += 1,
                Err(TrySendError::Disconnected(_)) => break,
            }
        } else if tx.send(msg).is_ok() {
            read += 1;
        } else {
            break;
        }
    }
    (read, dropped, timings)
}

fn prepare_stage(
    pre: &mut Preprocessor,
    rx: &Receiver<Decoded>,
    tx: &Sender<Prepared>,
) -> StageTimings {
    let mut timings = StageTimings::default();
    for d in rx {
        let start = ThreadTime::now();
        let frame = d
            .images
            .map_err(FailReason::Unreadable)
            .and_then(|images| pre.prepare(d.index, d.timestamp, images));
        let prepare_ms = start.elapsed().as_secs_f64() * 1e3;
        timings.record("prepare", prepare_ms);
        if tx
            .send(Prepared {
                index: d.index,
                timestamp: d.timestamp,
                frame,
                prepare_ms,
            })
            .is_err()
        {
            break;
        }
    }
    timings
}

/// Tracks the prepared frames; returns the trajectory, the frame records, the timings and the
/// number of frames left out of the map.
fn track_stage(
    odometry: &mut Odometry,
    (rx, tx): (&Receiver<Prepared>, &Sender<Tracked>),
    camera_from_tracked: Pose3,
    options: RunOptions,
    progress: &(impl Fn() + Send + Sync),
) -> (Trajectory, Vec<FrameRecord>, StageTimings, usize) {
    let mut timings = StageTimings::default();
    let mut unmapped = 0;
    let mut trajectory = Trajectory::new();
    let mut frames = Vec::new();
    let tracked_from_camera = camera_from_tracked.inverse();
    for p in rx {
        let start = ThreadTime::now();
        let (status, points) = match p.frame {
            Ok(mut frame) => {
                let points = std::mem::take(&mut frame.map_source);
                let status = odometry.track(frame);
                let ok = !matches!(status, FrameStatus::Failed(_));
                (status, ok.then_some(points))
            }
            Err(reason) => (odometry.skip(reason), None),
        };
        let track_ms = start.elapsed().as_secs_f64() * 1e3;
        timings.record("track", track_ms);
        timings.record("frame", p.prepare_ms + track_ms);
        let world_from_tracked = odometry.pose();
        trajectory.push(p.timestamp, world_from_tracked * tracked_from_camera);
        frames.push(FrameRecord {
            index: p.index,
            timestamp: p.timestamp,
            status,
        });
        progress();
        let msg = Tracked {
            world_from_camera: world_from_tracked,
            points,
        };
        let sent = if options.realtime {
            match tx.try_send(msg) {
                Err(TrySendError::Full(_)) => {
                    unmapped += 1;
                    Ok(())
                }
                other => other.map_err(|_| ()),
            }
        } else {
            tx.send(msg).map_err(|_| ())
        };
        if sent.is_err() {
            break;
        }
    }
    (trajectory, frames, timings, unmapped)
}

fn map_stage(map: &mut VoxelMap, rx: &Receiver<Tracked>) -> StageTimings {
    let mut timings = StageTimings::default();
    for t in rx {
        if let Some(source) = &t.points {
            timings.time("map", || {
                let (points, colors) = source.points();
                map.insert(&t.world_from_camera, &points, &colors);
            });
        }
    }
    timings
}
