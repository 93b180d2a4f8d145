//! The first half of a camera frame's work: grey image, features and their depth
//! ([`slamkit_vo::frame::Preprocessor`]). It needs nothing of the tracking state, so a
//! [`FramePreparer`] can run on its own thread, a frame ahead of the tracker
//! ([`super::pipeline`]).

use cpu_time::ThreadTime;
use slamkit_core::Observation;
use slamkit_vo::frame::{PreparedFrame, Preprocessor, Rig, SensorImages};
use slamkit_vo::{FailReason, VoConfig};

use crate::SlamError;

/// Turns camera observations into frames ready for tracking.
#[derive(Debug)]
pub struct FramePreparer {
    preprocessor: Preprocessor,
    rig: Rig,
}

/// A prepared observation, for [`super::VisualSlam::track`] (`None` inside: an observation the
/// session does not use, another sensor or another kind of camera).
#[derive(Debug)]
pub struct PreparedObservation(pub(super) Option<Prepared>);

/// A frame of the rig's camera, ready for tracking (or why it cannot be tracked).
#[derive(Debug)]
pub(super) struct Prepared {
    pub(super) index: usize,
    pub(super) timestamp: f64,
    pub(super) frame: Result<PreparedFrame, FailReason>,
    /// CPU time of the preparation \[ms\].
    pub(super) prepare_ms: f64,
}

impl FramePreparer {
    /// A preparer for `rig` with the kernels of `config`.
    ///
    /// # Errors
    /// [`SlamError::Vo`] for an invalid configuration.
    pub fn new(config: &VoConfig, rig: Rig) -> Result<Self, SlamError> {
        Ok(Self {
            preprocessor: Preprocessor::new(config, rig.clone())?,
            rig,
        })
    }

    /// Prepares `observation`, the `index`-th frame of its source (consecutive indices tell
    /// the tracker that no frame was dropped between two, for its constant-velocity
    /// prediction). Observations that are not frames of the rig's kind of camera are passed
    /// on as ignored.
    pub fn prepare(&mut self, index: usize, observation: Observation) -> PreparedObservation {
        let (timestamp, images) = match (observation, &self.rig) {
            (Observation::Rgbd(f), Rig::Rgbd { .. }) => (
                f.timestamp,
                SensorImages::Rgbd {
                    color: f.color,
                    depth_m: f.depth_m,
                },
            ),
            (Observation::Stereo(f), Rig::Stereo { .. }) => (
                f.timestamp,
                SensorImages::Stereo {
                    left: f.left,
                    right: f.right,
                },
            ),
            _ => return PreparedObservation(None),
        };
        let start = ThreadTime::now();
        let frame = self.preprocessor.prepare(index, timestamp, images);
        PreparedObservation(Some(Prepared {
            index,
            timestamp,
            frame,
            prepare_ms: start.elapsed().as_secs_f64() * 1e3,
        }))
    }
}
