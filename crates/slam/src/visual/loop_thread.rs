//! Loop closing ([`LoopClosing`]: keyframes, place recognition, verification, pose-graph
//! optimisation) on a thread of its own, so that a verification or an optimisation never
//! holds a frame's tracking back (issue 20, item 4).
//!
//! The tracker sends every tracked frame with its pose and place features down a bounded
//! channel and goes on; the loop-closing thread answers a closed loop with a correction of
//! the map frame (`corrected_from_world`), which the tracker takes at its next safe point
//! (before tracking the next frame, [`LoopThread::take_correction`]) and applies to its whole
//! state at once.
//!
//! A correction arrives some frames after the keyframe that closed the loop, and the frames
//! tracked meanwhile were sent in the world as it was before. Each frame therefore carries
//! the number of corrections the tracker had taken when it was tracked (its epoch); the
//! thread moves it by the corrections issued since, so every pose it keeps is in its own,
//! newest frame. The tracker's poses are only ever moved rigidly, so nothing about the motion
//! between frames depends on when a correction lands.
//!
//! Relocalisation after lost tracking, and the results (trajectory, map, closures, counts),
//! first wait for the thread to take every frame sent ([`LoopThread::flush`]), then read its
//! state under a lock.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;

use cpu_time::ThreadTime;
use crossbeam_channel::{bounded, unbounded, Receiver, Sender};
use slamkit_core::{Pose3, StageTimings};
use slamkit_vo::covisibility::PlaceFeatures;
use slamkit_vo::loop_closure::LoopClosureConfig;
use slamkit_vo::relocalisation::Relocalisation;

use super::loop_closing::{Correction, Joined, LoopClosing};
use crate::SlamError;

/// Frames the loop-closing thread may have waiting before the tracker waits for it: two
/// seconds of a 30 Hz camera, far more than a pose-graph optimisation of a room's keyframes
/// takes (≈ 1 ms for 44 keyframes on 7-Scenes), about 2 MB of ORB features.
const QUEUE: usize = 64;

/// What the tracker sends.
enum Request {
    /// A tracked frame, its pose in the world after `epoch` corrections.
    Frame {
        epoch: usize,
        timestamp: f64,
        world_from_tracked: Pose3,
        place: Option<PlaceFeatures>,
        // boxed: a relocalisation's verified loop is most of the message
        joined: Box<Joined>,
    },
    /// Answered once every request before it is done.
    Flush(Sender<()>),
}

/// The tracker's end of the loop-closing thread.
pub(super) struct LoopThread {
    sender: Option<Sender<Request>>,
    corrections: Receiver<Correction>,
    state: Arc<Mutex<LoopClosing>>,
    worker: Option<JoinHandle<StageTimings>>,
    /// Corrections the tracker has taken.
    epoch: usize,
}

impl LoopThread {
    /// Starts the thread.
    ///
    /// # Errors
    /// [`SlamError::Vo`] for an invalid configuration, [`SlamError::Thread`] when the thread
    /// cannot start.
    pub(super) fn start(config: &LoopClosureConfig) -> Result<Self, SlamError> {
        let state = Arc::new(Mutex::new(LoopClosing::new(config)?));
        let (sender, requests) = bounded::<Request>(QUEUE);
        // one correction per closed loop or localisation in the map: at most one per
        // keyframe spacing, and never a reason for the thread to wait
        let (correct, corrections) = unbounded::<Correction>();
        let shared = Arc::clone(&state);
        let worker = std::thread::Builder::new()
            .name("vo-loop-closing".into())
            .spawn(move || serve(&shared, &requests, &correct))
            .map_err(|e| SlamError::Thread(e.to_string()))?;
        Ok(Self {
            sender: Some(sender),
            corrections,
            state,
            worker: Some(worker),
            epoch: 0,
        })
    }

    /// Hands a tracked frame at `world_from_tracked` (in the world as the tracker has it
    /// now) to the thread; waits only when [`QUEUE`] frames are already waiting.
    pub(super) fn add_frame(
        &mut self,
        timestamp: f64,
        world_from_tracked: Pose3,
        place: Option<PlaceFeatures>,
        joined: Joined,
    ) {
        let request = Request::Frame {
            epoch: self.epoch,
            timestamp,
            world_from_tracked,
            place,
            joined: Box::new(joined),
        };
        let sent = self.sender.as_ref().map(|s| s.send(request).is_ok());
        if sent == Some(false) {
            // the thread is gone (it panicked): no loop closing from here on
            self.sender = None;
        }
    }

    /// The corrections issued since the last call, as one (`None` when no loop closed and no
    /// frame was localised in the map); the tracker applies it before its next frame.
    pub(super) fn take_correction(&mut self) -> Option<Correction> {
        let mut total: Option<Correction> = None;
        while let Ok(c) = self.corrections.try_recv() {
            self.epoch += 1;
            total = Some(match total {
                None => c,
                Some(t) => Correction {
                    corrected_from_world: c.corrected_from_world * t.corrected_from_world,
                    loop_closed: c.loop_closed || t.loop_closed,
                },
            });
        }
        total
    }

    /// Looks for a frame with features `place` among the keyframes, once every frame sent is
    /// in them; its `world_from_tracked` is in the newest world, so the tracker takes the
    /// pending corrections ([`Self::take_correction`]) before using it.
    pub(super) fn relocalise(&mut self, place: &PlaceFeatures) -> Option<(Relocalisation, Pose3)> {
        self.flush();
        self.state().relocalise(place)
    }

    /// Waits until the thread has taken every frame sent (at once when it is gone).
    pub(super) fn flush(&self) {
        let (done, wait) = bounded(1);
        if let Some(sender) = &self.sender {
            if sender.send(Request::Flush(done)).is_ok() {
                // an error: the thread ended without answering (it panicked)
                let _ = wait.recv();
            }
        }
    }

    /// The back end once every frame sent is in it.
    pub(super) fn state(&self) -> MutexGuard<'_, LoopClosing> {
        self.flush();
        // a panic on the thread leaves the state as the last finished frame left it
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Ends the thread; its CPU time per frame (`loop_closing`).
    ///
    /// # Errors
    /// [`SlamError::Thread`] when the thread panicked.
    pub(super) fn finish(mut self) -> Result<StageTimings, SlamError> {
        self.sender = None;
        match self.worker.take() {
            None => Ok(StageTimings::default()),
            Some(worker) => worker
                .join()
                .map_err(|_| SlamError::Thread("the loop-closing thread panicked".into())),
        }
    }
}

/// The thread's loop: each frame moved into the newest world and added; a closed loop's
/// correction sent back and kept, to move the frames sent before the tracker took it.
fn serve(
    state: &Mutex<LoopClosing>,
    requests: &Receiver<Request>,
    correct: &Sender<Correction>,
) -> StageTimings {
    let mut timings = StageTimings::default();
    // corrections[e] moves the world after e corrections to the world after e + 1
    let mut corrections: Vec<Pose3> = Vec::new();
    for request in requests {
        match request {
            Request::Frame {
                epoch,
                timestamp,
                world_from_tracked,
                place,
                joined,
            } => {
                let start = ThreadTime::now();
                let since = corrections.get(epoch..).unwrap_or_default();
                let newest_from_then = since.iter().fold(Pose3::identity(), |total, c| c * total);
                let correction = state
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .add_frame(
                        timestamp,
                        newest_from_then * world_from_tracked,
                        place,
                        *joined,
                    );
                if let Some(c) = correction {
                    corrections.push(c.corrected_from_world);
                    // the tracker gone: its results are read from the state all the same
                    let _ = correct.send(c);
                }
                timings.record("loop_closing", start.elapsed().as_secs_f64() * 1e3);
            }
            Request::Flush(done) => {
                let _ = done.send(());
            }
        }
    }
    timings
}

impl std::fmt::Debug for LoopThread {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoopThread")
            .field("running", &self.worker.is_some())
            .field("epoch", &self.epoch)
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::super::loop_closing::tests::drive_with;
    use super::*;

    #[test]
    fn corrections_taken_late_leave_the_same_trajectory_as_at_once() {
        let config = LoopClosureConfig {
            enabled: true,
            ..LoopClosureConfig::default()
        };
        // at once: the back end on the tracking thread, each correction applied to the
        // next frame
        let mut inline = LoopClosing::new(&config).unwrap();
        drive_with(1, false, 156, |t, pose, place, joined| {
            inline
                .add_frame(t, pose, Some(place), joined)
                .map(|c| c.corrected_from_world)
        });
        // on the thread, with a tracker that takes corrections every 7th frame only: the
        // frames between a closure and its correction arrive in the old world
        let mut thread = LoopThread::start(&config).unwrap();
        drive_with(1, false, 156, |t, pose, place, joined| {
            thread.add_frame(t, pose, Some(place), joined);
            if (t as usize) % 7 != 0 {
                return None;
            }
            thread.flush();
            thread.take_correction().map(|c| c.corrected_from_world)
        });
        let expected = inline.trajectory(&Pose3::identity());
        let state = thread.state();
        assert_eq!(state.stats(), inline.stats());
        let closures = state.closures(&Pose3::identity());
        assert!(
            closures
                .iter()
                .any(|c| (c.query_timestamp as usize) % 7 != 0),
            "no correction was taken late: {closures:?}"
        );
        let got = state.trajectory(&Pose3::identity());
        assert_eq!(got.len(), expected.len());
        for (a, b) in got.poses.iter().zip(&expected.poses) {
            let d = a.pose.inverse() * b.pose;
            assert!(
                d.translation.vector.norm() < 1e-6 && d.rotation.angle() < 1e-6,
                "frame {}: {d}",
                a.timestamp
            );
        }
        drop(state);
        let timings = thread.finish().unwrap();
        assert!(timings.summary().contains_key("loop_closing"));
    }
}
