//! [`VisualSlam`]: the online session of an RGB-D or stereo camera, over the visual odometry of
//! `slamkit_vo` (KLT or ORB features, RANSAC + Gauss–Newton motion, local map of key frames).
//!
//! A frame's work has two halves: [`FramePreparer::prepare`] (grey image, features and their
//! depth) needs nothing of the tracking state, [`VisualSlam::track`] (motion against the local
//! map) needs all of it. [`VisualSlam::push`] does both in turn; [`pipeline::run`] prepares the
//! next frame on another thread while the session tracks the current one, and decodes images
//! on a third, as a live camera driver would. The world point map is filled on a thread of its
//! own ([`point_map`]). [`run_files`] writes and scores a finished run over a dataset.
//!
//! With [`VoConfig::loop_closure`] on (`slamkit vo --slam`) the session is visual SLAM: its
//! keyframes, map points, place index and pose graph (module `loop_closing`) close loops on a
//! thread of their own (module `loop_thread`), and the tracker moves its state with the
//! corrected map before the next frame it tracks; [`VisualSlam::corrected_trajectory`] is then
//! the final trajectory (frames move with their keyframes) and [`VisualSlam::loop_closures`]
//! what was closed. The world point map and the map file's keyframes keep the poses they were
//! given when tracked.
//!
//! With loop closure on, a session that lost tracking (`max_consecutive_failures` failed
//! frames in a row: dark, blurred or textureless frames, a kidnapped camera) relocalises: each
//! new frame is looked for among the keyframes (place index, then RANSAC + Horn verification,
//! `slamkit_vo::relocalisation`), and tracking resumes where it is found, in the same map
//! frame. Until then the frames are [`TrackingStatus::Lost`] with no pose (nothing is
//! invented); after `loop_closure.relocalisation.restart_after_s` without a match (a place the
//! map lacks), tracking starts again at the last pose, as plain odometry does at once.
//!
//! Poses are `world_from_camera` of the rig's reference camera: the depth camera of an RGB-D
//! rig (the dataset's camera; the tracked colour camera is moved onto it when depth is
//! registered to colour by the session), the left camera of a stereo rig. The world is wherever
//! the session was told the first frame is ([`VisualSlam::starting_at`], identity by default),
//! never the dataset's ground truth.
//!
//! Basic settings for a new camera: the rig (intrinsics, stereo baseline; depth arrives in
//! metres), [`VoConfig::frontend`] and, for a colour camera whose depth is not registered to it,
//! [`VoConfig::register_depth`]; the rest of [`VoConfig`] is advanced.

mod bundle_thread;
mod in_map;
pub mod keyframes;
mod loop_closing;
mod loop_thread;
pub mod pipeline;
pub mod planning_map;
pub mod point_map;
mod prepare;
pub mod run_files;
pub mod simulated;

pub use keyframes::{Keyframe, VisualMap};
pub use loop_closing::{check_closures, LoopClosure, LoopStats, RelocalisationStats};
pub use pipeline::{run, FrameRecord, RunOptions, RunStats, VisualRun};
pub use point_map::PointMapping;
pub use prepare::{FramePreparer, PreparedObservation};

use cpu_time::ThreadTime;
use slamkit_core::camera::PinholeCamera;
use slamkit_core::{Observation, Pose3, StageTimings, Trajectory};
use slamkit_io::{Dataset, DatasetFormat};
use slamkit_vo::covisibility::PlaceFeatures;
use slamkit_vo::frame::Rig;
use slamkit_vo::motion::StereoCamera;
use slamkit_vo::{
    FailReason, FrameStatus, FrontendKind, Odometry, TrackingMode, VoConfig, VoxelMap,
};
use std::path::Path;

use crate::map_file;
use crate::profile::layout_profile;
use crate::session::{MapChange, Session, TrackingStatus, Update};
use crate::SlamError;
use bundle_thread::BundleThread;
use in_map::MapLocaliser;
use loop_closing::Joined;
use loop_thread::LoopThread;
use point_map::PointMapper;
use prepare::Prepared;

/// Visual odometry as an online session.
///
/// ```
/// use slamkit_core::camera::Intrinsics;
/// use slamkit_core::image::{Image, RgbImage};
/// use slamkit_core::observation::{Observation, RgbdFrame};
/// use slamkit_slam::visual::{PointMapping, VisualSlam};
/// use slamkit_slam::TrackingStatus;
/// use slamkit_vo::frame::Rig;
/// use slamkit_vo::VoConfig;
///
/// // a 160×120 camera looking at a checkerboard wall 2 m away
/// let k = Intrinsics::from_array([150.0, 150.0, 79.5, 59.5], 160, 120);
/// let rig = Rig::Rgbd { color: k, depth: k };
/// let mut session = VisualSlam::new(&VoConfig::default(), rig)?.with_point_map(PointMapping::Off)?;
/// let checker = |i: usize| if (i % 160 / 10 + i / 160 / 10) % 2 == 0 { 40 } else { 210 };
/// let texture: Vec<[u8; 3]> = (0..160 * 120).map(|i| [checker(i); 3]).collect();
/// for i in 0..3 {
///     let color = RgbImage::from_vec(160, 120, texture.clone()).expect("160×120 pixels");
///     let depth_m = Image::filled(160, 120, 2.0f32);
///     let frame = RgbdFrame { timestamp: i as f64 / 30.0, color, depth_m };
///     let update = session.push(Observation::Rgbd(frame)).expect("a camera frame");
///     // the camera did not move: the pose stays at the start (identity)
///     assert_eq!(update.status, TrackingStatus::Tracking);
///     assert!(update.pose.expect("a pose").translation.vector.norm() < 1e-3);
/// }
/// let stats = session.stats();
/// assert_eq!((stats.frames, stats.processed, stats.initialisations), (3, 3, 1));
/// # Ok::<(), slamkit_slam::SlamError>(())
/// ```
#[derive(Debug)]
pub struct VisualSlam {
    config: VoConfig,
    rig: Rig,
    preparer: FramePreparer,
    odometry: Odometry,
    /// `tracked_from_camera`: the rig's reference camera seen from the tracked one.
    tracked_from_camera: Pose3,
    point_map: PointMapper,
    timings: StageTimings,
    stats: VisualStats,
    /// Failed frames since the last tracked or initialised one.
    failures_in_row: usize,
    /// Time of the frame tracking was lost at, while it is.
    lost_since: Option<f64>,
    /// Index of the next frame [`Self::push`] prepares (one past the last tracked).
    next_index: usize,
    /// The keyframes for the map file.
    map: VisualMap,
    /// Place recognition and loop closure on their thread (`loop_closure.enabled`).
    loops: Option<LoopThread>,
    /// The saved map the session localises in ([`Self::localising_in`]).
    in_map: Option<MapLocaliser>,
    /// The local bundle adjustment on its thread (`local_map.bundle.enabled`).
    bundles: Option<BundleThread>,
}

/// Frame counters of a [`VisualSlam`] session.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct VisualStats {
    /// Camera frames of the rig's kind received.
    pub frames: usize,
    /// Frames tracked or used to (re)start tracking.
    pub processed: usize,
    /// Frames that could not be tracked (too dark, no depth, no motion found).
    pub failed: usize,
    /// Tracking (re)starts, relocalisations included.
    pub initialisations: usize,
    /// Tracking resumed where the frame was found in the map after tracking was lost
    /// (with loop closure on).
    pub relocalisations: usize,
    /// Frames while tracking was lost, reported without a pose (part of `failed`).
    pub lost: usize,
    /// Tracked frames whose pose the points of the saved map measured
    /// ([`VisualSlam::localising_in`]; the others were carried by odometry).
    pub map_tracked: usize,
    /// Observations the session does not use (other sensors, another kind of camera).
    pub ignored: usize,
    /// Tracked frames left out of the point map because its thread was busy
    /// ([`PointMapping::WhenIdle`]).
    pub unmapped: usize,
}

/// What [`VisualSlam::track`] made of a camera frame.
#[derive(Debug, Clone, PartialEq)]
pub struct VisualUpdate {
    /// The session's answer.
    pub update: Update,
    /// Position of the frame in its source.
    pub index: usize,
    /// Visual odometry's own account of the frame (inliers, or why it failed).
    pub frame: FrameStatus,
}

impl VisualUpdate {
    /// The frame's pose when odometry tracked it (or started on it); `None` for a failed
    /// frame, whose pose would only be the one held over it (a trajectory leaves it out).
    pub fn tracked_pose(&self) -> Option<Pose3> {
        let tracked = !matches!(self.frame, FrameStatus::Failed(_));
        self.update.pose.filter(|_| tracked)
    }
}

/// What a finished session leaves.
#[derive(Debug)]
pub struct VisualOutput {
    /// The world point map (`None` with [`PointMapping::Off`]).
    pub point_map: Option<VoxelMap>,
    /// CPU time per stage \[ms\]: `prepare`, `track`, `frame` (the two together), `map` and
    /// `loop_closing` (per frame, on their threads).
    pub timings: StageTimings,
    /// Frame counters.
    pub stats: VisualStats,
}

impl VisualSlam {
    /// A session for `rig` starting at the identity, filling a point map from every frame.
    ///
    /// # Errors
    /// [`SlamError::Vo`] for an invalid configuration, [`SlamError::Thread`] when the mapping
    /// thread cannot start.
    pub fn new(config: &VoConfig, rig: Rig) -> Result<Self, SlamError> {
        Self::starting_at(config, rig, Pose3::identity())
    }

    /// A session whose first frame is at `world_from_camera` (the rig's reference camera).
    ///
    /// # Errors
    /// As [`Self::new`].
    pub fn starting_at(
        config: &VoConfig,
        rig: Rig,
        world_from_camera: Pose3,
    ) -> Result<Self, SlamError> {
        let preparer = FramePreparer::new(config, rig.clone())?;
        // the tracked (colour) camera vs the rig's reference (depth) camera, for depth the
        // session registers to colour
        let tracked_from_camera = config
            .register_depth
            .as_ref()
            .map_or(Pose3::identity(), |r| r.color_from_depth());
        let mut odometry = Odometry::new(config, world_from_camera * tracked_from_camera.inverse());
        let bundles = (config.mode == TrackingMode::LocalMap && config.local_map.bundle.enabled)
            .then(BundleThread::start)
            .transpose()?;
        if bundles.is_some() {
            odometry.hand_off_bundles();
        }
        Ok(Self {
            odometry,
            point_map: PointMapper::start(PointMapping::default(), config.voxel_map.clone())?,
            config: config.clone(),
            rig,
            preparer,
            tracked_from_camera,
            timings: StageTimings::default(),
            stats: VisualStats::default(),
            failures_in_row: 0,
            lost_since: None,
            next_index: 0,
            map: VisualMap::default(),
            loops: config
                .loop_closure
                .enabled
                .then(|| LoopThread::start(&config.loop_closure))
                .transpose()?,
            in_map: None,
            bundles,
        })
    }

    /// A session localising in the saved `map` (`slamkit vo --localize`): no pose until a
    /// frame is found among the map's keyframes, then odometry, and the map searched again
    /// whenever tracking is lost; poses are in the map's frame, and the map is
    /// not changed (no loop closure, no keyframes added to it).
    ///
    /// # Errors
    /// As [`Self::new`]; [`SlamError::Map`] for a map without ORB descriptors.
    pub fn localising_in(config: &VoConfig, rig: Rig, map: &VisualMap) -> Result<Self, SlamError> {
        let mut config = config.clone();
        // frames are prepared with their place features (ORB with depth), as for loop closure
        config.loop_closure.enabled = true;
        let mut session = Self::new(&config, rig)?;
        session.loops = None;
        session.in_map = Some(MapLocaliser::new(
            &config,
            map,
            &session.tracked_from_camera,
        )?);
        Ok(session)
    }

    /// The same session building its point map the way `mode` says.
    ///
    /// # Errors
    /// [`SlamError::Thread`] when the mapping thread cannot start.
    pub fn with_point_map(mut self, mode: PointMapping) -> Result<Self, SlamError> {
        // the default thread has seen no frame yet: nothing is lost by ending it
        self.point_map.finish()?;
        self.point_map = PointMapper::start(mode, self.config.voxel_map.clone())?;
        Ok(self)
    }

    /// A preparer for this session's frames, to run on another thread ([`pipeline::run`]).
    ///
    /// # Errors
    /// As [`Self::new`] (the configuration was checked then, so only in theory).
    pub fn preparer(&self) -> Result<FramePreparer, SlamError> {
        FramePreparer::new(&self.config, self.rig.clone())
    }

    /// Takes one observation: a frame of the rig's camera is prepared and tracked; anything
    /// else is counted and ignored (`None`).
    pub fn push(&mut self, observation: Observation) -> Option<Update> {
        self.process(observation).map(|u| u.update)
    }

    /// [`Self::push`] with visual odometry's own account of the frame.
    pub fn process(&mut self, observation: Observation) -> Option<VisualUpdate> {
        let index = self.next_index;
        let prepared = self.preparer.prepare(index, observation);
        self.track(prepared)
    }

    /// Tracks a frame prepared by a [`FramePreparer`] of this session (frames in order).
    pub fn track(&mut self, prepared: PreparedObservation) -> Option<VisualUpdate> {
        let Some(Prepared {
            index,
            timestamp,
            frame,
            prepare_ms,
        }) = prepared.0
        else {
            self.stats.ignored += 1;
            return None;
        };
        self.next_index = self.next_index.max(index + 1);
        self.stats.frames += 1;
        let start = ThreadTime::now();
        // the safe point: the map moved by the loops closed since the last frame
        let closed = self.take_correction();
        let keyframes_before = self.odometry.keyframes();
        let searching = self.searching(timestamp);
        let mut joined = Joined::Tracked;
        let mut relocalised = false;
        let (status, points, place) = match frame {
            Ok(mut frame) => {
                let points = std::mem::take(&mut frame.map_source);
                let place = frame.place.take();
                let camera = frame.stereo_camera(&self.config);
                let found = place
                    .as_ref()
                    .filter(|_| searching)
                    .and_then(|p| self.locate(p));
                let status = match found {
                    Some((found, world_from_tracked)) => {
                        let status = self.odometry.restart_at(frame, world_from_tracked);
                        relocalised = !matches!(status, FrameStatus::Failed(_));
                        if let Some(found) = found.filter(|_| relocalised) {
                            joined = Joined::Relocalised(found);
                        }
                        status
                    }
                    None if searching => self.odometry.skip(FailReason::NotRelocalised),
                    None => self.odometry.track(frame),
                };
                if !matches!(status, FrameStatus::Failed(_)) {
                    self.follow_map(place.as_ref(), &camera);
                }
                (status, points, place)
            }
            Err(reason) => (self.odometry.skip(reason), Default::default(), None),
        };
        if let Some(bundles) = &mut self.bundles {
            bundles.exchange(&mut self.odometry);
        }
        if matches!(status, FrameStatus::Initialised { .. }) && joined == Joined::Tracked {
            joined = Joined::Restarted;
        }
        self.close_loops(timestamp, &status, place, joined.clone());
        let track_ms = start.elapsed().as_secs_f64() * 1e3;
        self.timings.record("prepare", prepare_ms);
        self.timings.record("track", track_ms);
        self.timings.record("frame", prepare_ms + track_ms);
        let world_from_tracked = self.odometry.pose();
        let tracking = match status {
            FrameStatus::Failed(_) => {
                self.stats.failed += 1;
                self.failures_in_row += 1;
                if self.stats.initialisations == 0 {
                    TrackingStatus::Initialising
                } else if self.failures_in_row >= self.config.max_consecutive_failures {
                    self.stats.lost += 1;
                    self.lost_since.get_or_insert(timestamp);
                    TrackingStatus::Lost
                } else {
                    TrackingStatus::Predicted
                }
            }
            FrameStatus::Initialised { .. } | FrameStatus::Tracked { .. } => {
                if matches!(status, FrameStatus::Initialised { .. }) {
                    self.stats.initialisations += 1;
                }
                if relocalised {
                    self.stats.relocalisations += 1;
                }
                self.stats.processed += 1;
                self.failures_in_row = 0;
                self.lost_since = None;
                self.point_map.insert(world_from_tracked, points);
                TrackingStatus::Tracking
            }
        };
        self.stats.unmapped = self.point_map.unmapped();
        let pose = world_from_tracked * self.tracked_from_camera;
        let keyframe = tracking == TrackingStatus::Tracking
            && match self.config.mode {
                TrackingMode::LocalMap => self.odometry.keyframes() > keyframes_before,
                TrackingMode::FrameToFrame => {
                    (self.stats.processed - 1) % self.config.local_map.keyframe_every.max(1) == 0
                }
            };
        if keyframe && self.loops.is_none() {
            self.add_keyframe(timestamp, pose);
        }
        Some(VisualUpdate {
            update: Update {
                timestamp,
                // a lost camera's held pose would be invented, as would one in a map before
                // the camera is found in it
                pose: (tracking != TrackingStatus::Lost
                    && !(self.in_map.is_some() && tracking == TrackingStatus::Initialising))
                    .then_some(pose),
                status: tracking,
                map: MapChange {
                    keyframes_added: usize::from(keyframe),
                    loop_closures: usize::from(closed),
                    map_moved: closed,
                },
            },
            index,
            frame: status,
        })
    }

    /// True when the frame at `timestamp` is to be looked for in the map rather than
    /// tracked: loop closure is on, tracking was lost, and not for longer than
    /// `restart_after_s` (0: no limit).
    fn searching(&self, timestamp: f64) -> bool {
        if self.in_map.is_some() && self.stats.initialisations == 0 {
            // in a saved map, the first pose is where the map recognises the camera
            return true;
        }
        let limit = self.config.loop_closure.relocalisation.restart_after_s;
        (self.loops.is_some() || self.in_map.is_some())
            && self.stats.initialisations > 0
            && self.odometry.is_lost()
            && self
                .lost_since
                .map_or(true, |t| limit == 0.0 || timestamp - t < limit)
    }

    /// Where the frame with features `place` is in the map (the saved one, or this session's
    /// keyframes), `world_from_tracked`, with the keyframe found (this session's map only).
    fn locate(
        &mut self,
        place: &PlaceFeatures,
    ) -> Option<(Option<slamkit_vo::relocalisation::Relocalisation>, Pose3)> {
        if let Some(map) = &self.in_map {
            return map.locate(place).map(|pose| (None, pose));
        }
        let found = self.loops.as_mut()?.relocalise(place);
        // the pose found is in the newest map: the tracker follows it there first
        self.take_correction();
        let (found, pose) = found?;
        Some((Some(found), pose))
    }

    /// In a saved map, moves the tracking state to where the map's points put the frame just
    /// tracked (odometry carries on from there); where they do not match, odometry's pose
    /// stands.
    fn follow_map(&mut self, place: Option<&PlaceFeatures>, camera: &StereoCamera) {
        let (Some(map), Some(place)) = (&self.in_map, place) else {
            return;
        };
        let predicted = self.odometry.pose();
        if let Some(fix) = map.track(place, camera, &predicted) {
            self.odometry.correct(&(fix * predicted.inverse()));
            self.stats.map_tracked += 1;
        }
    }

    /// Hands a tracked frame to the loop-closing thread (when on).
    fn close_loops(
        &mut self,
        timestamp: f64,
        status: &FrameStatus,
        place: Option<PlaceFeatures>,
        joined: Joined,
    ) {
        if let Some(loops) = &mut self.loops {
            if !matches!(status, FrameStatus::Failed(_)) {
                loops.add_frame(timestamp, self.odometry.pose(), place, joined);
            }
        }
    }

    /// Moves the tracking state with the map when loops closed or a frame was localised in
    /// the map since the last call; true when a loop closed (the map moved).
    fn take_correction(&mut self) -> bool {
        let Some(c) = self.loops.as_mut().and_then(LoopThread::take_correction) else {
            return false;
        };
        self.odometry.correct(&c.corrected_from_world);
        c.loop_closed
    }

    /// The trajectory of every tracked frame as loop closure left it, once the loop-closing
    /// thread has taken every frame (`None` when loop closure is off: the poses of the
    /// updates are then final).
    pub fn corrected_trajectory(&self) -> Option<Trajectory> {
        self.loops
            .as_ref()
            .map(|l| l.state().trajectory(&self.tracked_from_camera))
    }

    /// The accepted loops, relative poses of the rig's reference camera, and the back end's
    /// counts (`None` when loop closure is off).
    pub fn loop_closures(&self) -> Option<(LoopStats, Vec<LoopClosure>)> {
        self.loops.as_ref().map(|l| {
            let state = l.state();
            (state.stats(), state.closures(&self.tracked_from_camera))
        })
    }

    /// The frames that were due to become keyframes but were localised against an existing
    /// keyframe instead (`loop_closure.cull_redundant_keyframes`), each as a loop from the
    /// frame (query) to the keyframe (candidate) in the rig's reference camera, so that they
    /// can be checked as closures are ([`check_closures`]); `None` when loop closure is off.
    pub fn map_localisations(&self) -> Option<Vec<LoopClosure>> {
        self.loops
            .as_ref()
            .map(|l| l.state().localisations(&self.tracked_from_camera))
    }

    /// Records the frame just tracked, at `pose`, as a keyframe of the map, its points moved
    /// from the tracked camera into the rig's reference camera.
    fn add_keyframe(&mut self, timestamp: f64, pose: Pose3) {
        let camera_from_tracked = self.tracked_from_camera.inverse();
        let points = self
            .odometry
            .reference_points()
            .into_iter()
            .map(|(p, d)| (camera_from_tracked * p, d))
            .collect();
        self.map.keyframes.push(keyframes::Keyframe {
            timestamp,
            pose,
            points,
        });
    }

    /// The keyframes so far: what [`Session::save`] writes. With loop closure on, loop
    /// closing's keyframes where it left them, their points with ORB descriptors (a map to
    /// localise in); otherwise the local map's keyframes as tracked.
    pub fn map(&self) -> VisualMap {
        match &self.loops {
            Some(loops) => loops.state().visual_map(&self.tracked_from_camera),
            None => self.map.clone(),
        }
    }

    /// The camera rig the session was made for.
    pub fn rig(&self) -> &Rig {
        &self.rig
    }

    /// Frame counters so far.
    pub fn stats(&self) -> VisualStats {
        self.stats
    }

    /// The current `world_from_camera` of the rig's reference camera (with loop closure on,
    /// in the map as the last correction the tracker took left it).
    pub fn pose(&self) -> Pose3 {
        self.odometry.pose() * self.tracked_from_camera
    }

    /// Ends the session: waits for the point map and loop closing to take every tracked
    /// frame.
    ///
    /// # Errors
    /// [`SlamError::Thread`] when the mapping or loop-closing thread failed.
    pub fn finish(self) -> Result<VisualOutput, SlamError> {
        let mut timings = self.timings;
        if let Some(loops) = self.loops {
            timings.merge(&loops.finish()?);
        }
        if let Some(bundles) = self.bundles {
            timings.merge(&bundles.finish()?);
        }
        let point_map = self.point_map.finish()?.map(|(map, map_timings)| {
            timings.merge(&map_timings);
            map
        });
        Ok(VisualOutput {
            point_map,
            timings,
            stats: self.stats,
        })
    }
}

impl Session for VisualSlam {
    fn push(&mut self, observation: Observation) -> Option<Update> {
        VisualSlam::push(self, observation)
    }

    /// Writes the keyframes (poses, points and descriptors; [`keyframes`] lists the sections).
    fn save(&self, path: &Path) -> Result<(), SlamError> {
        let map_error = |source| SlamError::MapFile {
            path: path.to_path_buf(),
            source,
        };
        self.map()
            .to_map_file(file_rig(&self.rig))
            .map_err(map_error)?
            .save(path)
            .map_err(map_error)
    }
}

/// A camera session's settings as a shell builds them: `frontend`'s defaults, the profile's
/// `[vo]` table over them (the named profile, or else the camera of the dataset's layout,
/// [`layout_profile`]), the file `config`'s fields on top, and loop closure switched on
/// when `slam` asks for it; then checked.
///
/// # Errors
/// [`SlamError::Config`] for an unknown profile or field, [`SlamError::Vo`] for settings out
/// of range.
pub fn session_settings(
    frontend: FrontendKind,
    format: DatasetFormat,
    profile: Option<&str>,
    config: Option<&Path>,
    slam: bool,
) -> Result<VoConfig, SlamError> {
    let base = VoConfig {
        frontend,
        ..VoConfig::default()
    };
    let profile = profile.or_else(|| layout_profile(format));
    let mut settings = crate::profile::settings(base, "vo", profile, config)?;
    settings.loop_closure.enabled |= slam;
    settings.validate()?;
    Ok(settings)
}

/// The map file's name for the kind of `rig`.
fn file_rig(rig: &Rig) -> map_file::Rig {
    match rig {
        Rig::Rgbd { .. } => map_file::Rig::Rgbd,
        Rig::Stereo { .. } => map_file::Rig::Stereo,
    }
}

/// Reads the visual map saved at `path` for a camera `rig` (to localise in it,
/// [`VisualSlam::localising_in`]).
///
/// # Errors
/// [`SlamError::MapFile`] naming the file: unreadable, not a map, damaged, or the map of
/// another rig (a stereo map for an RGB-D camera, a lidar map).
pub fn load_map(path: &Path, rig: &Rig) -> Result<VisualMap, SlamError> {
    let map_error = |source| SlamError::MapFile {
        path: path.to_path_buf(),
        source,
    };
    let file = map_file::MapFile::load(path).map_err(map_error)?;
    VisualMap::from_map_file(&file, file_rig(rig)).map_err(map_error)
}

/// The camera rig of a dataset: what a [`VisualSlam`] on it is built with.
pub fn rig_of(dataset: &Dataset) -> Rig {
    match dataset {
        Dataset::Rgbd(s) => Rig::Rgbd {
            color: s.color_camera.intrinsics,
            depth: s.depth_camera.intrinsics,
        },
        Dataset::RgbdBag(b) => rgbd_rig(&b.camera),
        Dataset::Stereo(s) => Rig::Stereo {
            left: s.left_camera.intrinsics,
            baseline_m: s.baseline_m(),
        },
    }
}

/// The rig of an RGB-D camera whose depth is registered to its colour images (a bag's, or a
/// live camera's from its `CameraInfo`): one camera for both.
pub fn rgbd_rig(camera: &PinholeCamera) -> Rig {
    Rig::Rgbd {
        color: camera.intrinsics,
        depth: camera.intrinsics,
    }
}
