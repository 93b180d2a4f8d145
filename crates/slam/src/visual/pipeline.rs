//! A [`VisualSlam`] session fed from a source of observations with the work overlapped on
//! three threads: the source's iterator (image decoding) on one, frame preparation
//! ([`FramePreparer`]) on another, tracking on the caller's, joined by bounded crossbeam
//! channels so a slow stage holds the ones before it back instead of letting queues (and
//! memory) grow. The session's point map fills on a fourth ([`super::point_map`]).
//!
//! In real-time mode the source is played at its own clock (the observations' time stamps)
//! and each frame is offered without waiting: a frame arriving while the preparer still has
//! [`REALTIME_QUEUE`] frames waiting is dropped and counted, as a live camera driver with a
//! ring of that many buffers would. Otherwise every frame is processed.
//!
//! Per-frame time (`frame` in the session's timings) is the prepare and track work of one
//! frame, image decoding excluded; decoding is timed here under `decode`. All are CPU times of
//! their threads (one core each), so they measure the work of a frame, not how long other
//! processes on the machine held the core.

use std::time::{Duration, Instant};

use cpu_time::ThreadTime;
use crossbeam_channel::{bounded, Receiver, Sender, TrySendError};
use serde::Serialize;
use slamkit_core::{Observation, StageTimings, Trajectory};
use slamkit_vo::FrameStatus;

use super::{FramePreparer, PreparedObservation, VisualSlam, VisualUpdate};
use crate::SlamError;

/// Decoded frames the real-time reader may queue ahead of the preparer (a camera driver's
/// buffer ring; V4L2 drivers commonly keep four).
pub const REALTIME_QUEUE: usize = 4;

/// How the source is played.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunOptions {
    /// Play at the rate of the time stamps and drop frames the session cannot take.
    pub realtime: bool,
}

/// Frame counts of a run, besides the session's own ([`super::VisualStats`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RunStats {
    /// Items the source gave.
    pub frames: usize,
    /// Observations handed to the session.
    pub read: usize,
    /// Frames dropped in real-time mode because the session was busy.
    pub dropped: usize,
    /// Frames the source could not give (unreadable or corrupt images), skipped.
    pub skipped: usize,
}

/// One frame's outcome.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameRecord {
    /// Position in the source.
    pub index: usize,
    /// Time stamp \[s\].
    pub timestamp: f64,
    /// What visual odometry made of it.
    pub status: FrameStatus,
}

/// What a run produced besides the session's state.
#[derive(Debug)]
pub struct VisualRun {
    /// One pose per frame the session initialised on or tracked, `world_from_camera` of the
    /// rig's reference camera (as loop closure left them, when it is on). A failed frame (unreadable, or one odometry could not track)
    /// has none, so scoring skips it rather than counting the pose held over it; its status
    /// is in `frames`.
    pub trajectory: Trajectory,
    /// Per-frame outcomes, in order.
    pub frames: Vec<FrameRecord>,
    /// Counts.
    pub stats: RunStats,
    /// Decoding time per frame (`decode`) \[ms\].
    pub timings: StageTimings,
    /// The source's errors, one line per skipped frame (index and message).
    pub skipped: Vec<String>,
}

/// Messages of the read → prepare channel.
struct Decoded {
    index: usize,
    observation: Observation,
}

/// Feeds every item of `source` through `session`; `progress` is called once per frame the
/// session answers. The session is left as the last frame left it (its point map and timings
/// through [`VisualSlam::finish`]).
///
/// # Errors
/// [`SlamError::Vo`] when the session's configuration cannot build a preparer,
/// [`SlamError::Thread`] when a thread cannot start or dies.
pub fn run<S, E>(
    session: &mut VisualSlam,
    source: S,
    options: RunOptions,
    mut progress: impl FnMut(&VisualUpdate),
) -> Result<VisualRun, SlamError>
where
    S: Iterator<Item = Result<Observation, E>> + Send,
    E: std::fmt::Display,
{
    let mut preparer = session.preparer()?;
    let queue = if options.realtime { REALTIME_QUEUE } else { 1 };
    let (tx_decoded, rx_decoded) = bounded::<Decoded>(queue);
    let (tx_prepared, rx_prepared) = bounded::<PreparedObservation>(2);
    std::thread::scope(|s| {
        let reader = std::thread::Builder::new()
            .name("vo-read".into())
            .spawn_scoped(s, move || read_stage(source, options, &tx_decoded))
            .map_err(|e| SlamError::Thread(e.to_string()))?;
        let prep = std::thread::Builder::new()
            .name("vo-prepare".into())
            .spawn_scoped(s, move || {
                prepare_stage(&mut preparer, &rx_decoded, &tx_prepared)
            })
            .map_err(|e| SlamError::Thread(e.to_string()))?;
        let mut trajectory = Trajectory::new();
        let mut frames = Vec::new();
        for prepared in &rx_prepared {
            if let Some(u) = session.track(prepared) {
                if let Some(pose) = u.tracked_pose() {
                    trajectory.push(u.update.timestamp, pose);
                }
                progress(&u);
                frames.push(FrameRecord {
                    index: u.index,
                    timestamp: u.update.timestamp,
                    status: u.frame,
                });
            }
        }
        if let Some(corrected) = session.corrected_trajectory() {
            trajectory = corrected;
        }
        prep.join()
            .map_err(|_| SlamError::Thread("the prepare thread panicked".into()))?;
        let (stats, timings, skipped) = reader
            .join()
            .map_err(|_| SlamError::Thread("the read thread panicked".into()))?;
        Ok(VisualRun {
            trajectory,
            frames,
            stats,
            timings,
            skipped,
        })
    })
}

/// Reads (decodes) every item of the source; returns the counts, the decoding times and the
/// source's errors.
fn read_stage<S, E>(
    source: S,
    options: RunOptions,
    tx: &Sender<Decoded>,
) -> (RunStats, StageTimings, Vec<String>)
where
    S: Iterator<Item = Result<Observation, E>>,
    E: std::fmt::Display,
{
    let start = Instant::now();
    let mut t0 = None;
    let mut stats = RunStats::default();
    let mut timings = StageTimings::default();
    let mut errors = Vec::new();
    let mut source = source.enumerate();
    loop {
        let decode_start = ThreadTime::now();
        let Some((index, item)) = source.next() else {
            break;
        };
        stats.frames += 1;
        let observation = match item {
            Ok(o) => o,
            Err(e) => {
                stats.skipped += 1;
                errors.push(format!("frame {index}: {e}"));
                continue;
            }
        };
        timings.record("decode", decode_start.elapsed().as_secs_f64() * 1e3);
        let msg = Decoded { index, observation };
        if options.realtime {
            let timestamp = msg.observation.timestamp();
            let first = *t0.get_or_insert(timestamp);
            let due = Duration::try_from_secs_f64(timestamp - first).unwrap_or_default();
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
            match tx.try_send(msg) {
                Ok(()) => stats.read += 1,
                Err(TrySendError::Full(_)) => stats.dropped += 1,
                Err(TrySendError::Disconnected(_)) => break,
            }
        } else if tx.send(msg).is_ok() {
            stats.read += 1;
        } else {
            break;
        }
    }
    (stats, timings, errors)
}

fn prepare_stage(
    preparer: &mut FramePreparer,
    rx: &Receiver<Decoded>,
    tx: &Sender<PreparedObservation>,
) {
    for d in rx {
        if tx.send(preparer.prepare(d.index, d.observation)).is_err() {
            break;
        }
    }
}
