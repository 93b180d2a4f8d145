//! The local bundle adjustment (`slamkit_vo::local_ba`) on a thread of its own (issue 20,
//! item 2), so that refining the recent key frames never holds a frame's tracking back.
//!
//! After a key frame the tracker hands its bundle (the recent key frames and their shared
//! landmarks, [`Odometry::take_bundle`]) to the thread and goes on. At the next key frame it
//! first takes the adjusted bundle back and applies it ([`Odometry::apply_bundle`]: each
//! landmark and key frame moved by what the adjustment moved it, the current pose by its
//! newest key frame's correction), then hands off the new one. The result lands at the same
//! frame whatever the machine's load, so a run is repeatable; the tracker waits only when an
//! adjustment takes longer than the frames between two key frames.

use std::thread::JoinHandle;

use cpu_time::ThreadTime;
use crossbeam_channel::{bounded, Receiver, Sender};
use slamkit_core::StageTimings;
use slamkit_vo::{LocalBundle, Odometry};

use crate::SlamError;

/// The tracker's end of the bundle-adjustment thread.
#[derive(Debug)]
pub(super) struct BundleThread {
    sender: Option<Sender<LocalBundle>>,
    adjusted: Receiver<LocalBundle>,
    /// A bundle is on the thread.
    outstanding: bool,
    worker: Option<JoinHandle<StageTimings>>,
}

impl BundleThread {
    /// Starts the thread.
    ///
    /// # Errors
    /// [`SlamError::Thread`] when the thread cannot start.
    pub(super) fn start() -> Result<Self, SlamError> {
        let (sender, requests) = bounded::<LocalBundle>(1);
        let (done, adjusted) = bounded::<LocalBundle>(1);
        let worker = std::thread::Builder::new()
            .name("vo-local-ba".into())
            .spawn(move || serve(&requests, &done))
            .map_err(|e| SlamError::Thread(e.to_string()))?;
        Ok(Self {
            sender: Some(sender),
            adjusted,
            outstanding: false,
            worker: Some(worker),
        })
    }

    /// After a key frame: applies the bundle on the thread to `odometry` (waiting for it if
    /// it is not done), then hands off the new one.
    pub(super) fn exchange(&mut self, odometry: &mut Odometry) {
        if !odometry.bundle_due() {
            return;
        }
        if self.outstanding {
            self.outstanding = false;
            if let Ok(b) = self.adjusted.recv() {
                odometry.apply_bundle(&b);
            }
        }
        let Some(bundle) = odometry.take_bundle() else {
            return;
        };
        self.outstanding = self.sender.as_ref().is_some_and(|s| s.send(bundle).is_ok());
    }

    /// Ends the thread (a bundle still on it is dropped: the frames it would move are
    /// reported); returns its CPU time per adjustment (`local_ba`).
    ///
    /// # Errors
    /// [`SlamError::Thread`] when the thread panicked.
    pub(super) fn finish(mut self) -> Result<StageTimings, SlamError> {
        self.sender = None;
        match self.worker.take() {
            None => Ok(StageTimings::default()),
            Some(worker) => worker.join().map_err(|_| {
                SlamError::Thread("the local bundle adjustment thread panicked".into())
            }),
        }
    }
}

fn serve(requests: &Receiver<LocalBundle>, done: &Sender<LocalBundle>) -> StageTimings {
    let mut timings = StageTimings::default();
    for mut bundle in requests {
        let start = ThreadTime::now();
        bundle.adjust();
        timings.record("local_ba", start.elapsed().as_secs_f64() * 1e3);
        if done.send(bundle).is_err() {
            break;
        }
    }
    timings
}
