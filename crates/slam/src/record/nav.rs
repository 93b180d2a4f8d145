//! A `slamkit nav` run recorded, as the loop runs: every camera frame's colour image
//! (`/camera/image`), the estimated pose (`/pose`, `map → base_link` on `/tf`), the true pose
//! (`/groundtruth`, which the robot never sees), each new plan (`/plan`), and every
//! [`MAP_PERIOD_S`] of simulated time and at the end the floor grid the robot built (`/map`)
//! and its estimated path so far (`/path`).
//!
//! The map is snapshotted by simulated time, not by frame count, because a navigation run's
//! length is not known when it starts (it ends at the goal).

use super::{encode_jpeg, Recorder, IMAGE_TOPIC};
use crate::ground_robot::GroundRobotNav;
use crate::SlamError;
use slamkit_core::{Observation, Pose3};
use slamkit_map::TriGrid;
use std::collections::BTreeMap;
use std::path::Path;

/// Simulated time between two snapshots of the robot's map \[s\]: a few dozen over a
/// typical run (office: 60-100 s), each a few hundred kB.
pub const MAP_PERIOD_S: f64 = 5.0;

/// A closed navigation loop being recorded to an MCAP file.
pub struct NavRecording {
    recorder: Recorder,
    path: Vec<Pose3>,
    plans_recorded: usize,
    next_map_s: f64,
}

impl NavRecording {
    /// Starts recording to `path`.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be created.
    pub fn create(path: &Path) -> Result<Self, SlamError> {
        Ok(Self {
            recorder: Recorder::create(path)?,
            path: Vec::new(),
            plans_recorded: 0,
            next_map_s: 0.0,
        })
    }

    /// Records the camera's image of `observation` (before the session takes it).
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be written.
    pub fn image(&mut self, observation: &Observation) -> Result<(), SlamError> {
        match encode_jpeg(observation) {
            Some((t, jpeg)) => {
                self.recorder
                    .compressed_image(IMAGE_TOPIC, "camera", t, "jpeg", &jpeg)
            }
            None => Ok(()),
        }
    }

    /// Records the step at time `t` \[s\] once `nav` has processed its frame: the true pose,
    /// the estimate when there is one, the plans made since the last step, and the map and
    /// path when a snapshot is due.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be written.
    pub fn step(
        &mut self,
        t: f64,
        truth: &Pose3,
        estimate: Option<&Pose3>,
        nav: &GroundRobotNav,
    ) -> Result<(), SlamError> {
        self.recorder.pose("/groundtruth", "map", t, truth)?;
        if let Some(pose) = estimate {
            self.recorder.pose("/pose", "map", t, pose)?;
            self.recorder.transform(t, "map", "base_link", pose)?;
            self.path.push(*pose);
        }
        for plan in nav.plans().iter().skip(self.plans_recorded) {
            let poses: Vec<Pose3> = plan
                .waypoints_m
                .iter()
                .map(|p| Pose3::translation(p.x, p.y, 0.0))
                .collect();
            self.recorder.poses("/plan", "map", t, &poses)?;
        }
        self.plans_recorded = nav.plans().len();
        if t >= self.next_map_s {
            self.snapshot(t, &nav.grid())?;
            self.next_map_s = t + MAP_PERIOD_S;
        }
        Ok(())
    }

    /// Records the final map `grid` and path at time `t` \[s\] and ends the recording;
    /// returns the messages written per topic.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be completed.
    pub fn finish(mut self, t: f64, grid: &TriGrid) -> Result<BTreeMap<String, u64>, SlamError> {
        self.snapshot(t, grid)?;
        self.recorder.finish()
    }

    fn snapshot(&mut self, t: f64, grid: &TriGrid) -> Result<(), SlamError> {
        self.recorder.grid("/map", "map", t, grid)?;
        self.recorder.poses("/path", "map", t, &self.path)
    }
}
