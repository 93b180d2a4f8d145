//! The visual-odometry configuration: one struct of per-stage structs, every field with its
//! published default, loadable from TOML (fields not given keep their defaults).

use serde::{Deserialize, Serialize};
use slamkit_vision::{
    ClaheConfig, KltConfig, MatchConfig, OrbConfig, ShiTomasiConfig, StereoConfig,
};

use crate::depth::{DepthConfig, DepthRegistration};
use crate::error::VoError;
use crate::local_map::LocalMapConfig;
use crate::loop_closure::LoopClosureConfig;
use crate::motion::MotionConfig;

use crate::voxel_map::VoxelMapConfig;

/// Which features are tracked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrontendKind {
    /// Shi–Tomasi corners followed by pyramidal KLT.
    Klt,
    /// ORB features matched by Hamming distance.
    Orb,
}

/// What the current frame is matched against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrackingMode {
    /// The last successfully tracked frame only.
    FrameToFrame,
    /// Features of the recent key frames, each position averaged over its observations.
    LocalMap,
}

/// When CLAHE turns itself on (`use_clahe` off): a frame whose plain image gives fewer than
/// `on_below` features is detected again after CLAHE, and the following frames keep CLAHE
/// until the plain image, looked at again every `recheck_every` frames, gives `off_at` or
/// more. The gap between the two counts is the hysteresis that keeps a frame near one
/// threshold from switching every frame (each switch changes the grey levels the tracker
/// compares: the KLT front end tracks a switch frame in both images, see
/// [`crate::frame::PreparedFrame::bridge`]).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AutoClaheConfig {
    /// Features of the plain image below which CLAHE turns on (0: never).
    pub on_below: usize,
    /// Features of the plain image at or above which CLAHE turns off again (> `on_below`).
    pub off_at: usize,
    /// While CLAHE is on, the plain image is detected on too every this many frames (> 0).
    pub recheck_every: usize,
}

/// Off by default: on as-recorded frames the measured thresholds (`on_below` 150, `off_at`
/// 300) never switch, and on relit 7-Scenes they lower the KLT front end's ATE (0.0384 ->
/// 0.0274 m), but the simulated worlds' plain walls (`slamkit nav`) were not measured with it
/// (docs/experiments/clahe.md). `on_below = 150` turns it on.
impl Default for AutoClaheConfig {
    fn default() -> Self {
        Self {
            on_below: 0,
            off_at: 300,
            recheck_every: 15,
        }
    }
}

impl AutoClaheConfig {
    /// Whether CLAHE may turn itself on.
    pub fn enabled(&self) -> bool {
        self.on_below > 0
    }

    fn validate(&self) -> Result<(), VoError> {
        if !self.enabled() {
            return Ok(());
        }
        if self.off_at <= self.on_below {
            return Err(VoError::config(
                "auto_clahe.off_at",
                self.off_at,
                "must be > auto_clahe.on_below (the hysteresis)",
            ));
        }
        if self.recheck_every == 0 {
            return Err(VoError::config(
                "auto_clahe.recheck_every",
                0,
                "must be > 0",
            ));
        }
        Ok(())
    }
}

/// Everything visual odometry can be told.
///
/// Basic (what a new camera needs; the intrinsics and stereo baseline come with the data):
/// `frontend`, `depth.min_depth_m` / `depth.max_depth_m` (the depth sensor's usable ranges),
/// `max_stereo_depth_m`, `register_depth` (an RGB-D camera whose colour is not registered to
/// depth), `use_clahe` (poorly or unevenly lit scenes). Named profiles hold what one kind of
/// camera needs (`config/stereo.toml`, `config/kinect-v1.toml`); the rest is advanced.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VoConfig {
    /// Feature front end.
    pub frontend: FrontendKind,
    /// Frame-to-frame or local-map tracking.
    pub mode: TrackingMode,
    /// Apply CLAHE (on CIELAB L for colour input) before detection.
    pub use_clahe: bool,
    /// CLAHE settings (OpenCV `createCLAHE` defaults).
    pub clahe: ClaheConfig,
    /// CLAHE turned on by the frames themselves when `use_clahe` is off.
    pub auto_clahe: AutoClaheConfig,
    /// Frames whose mean grey level is below this are too dark to track \[grey levels\].
    pub min_mean_intensity: f64,
    /// Corner detection for the KLT front end.
    pub shi_tomasi: ShiTomasiConfig,
    /// KLT tracking.
    pub klt: KltConfig,
    /// Features the KLT front end keeps tracking; new corners top the set up to this.
    pub max_features: usize,
    /// ORB detection.
    pub orb: OrbConfig,
    /// ORB descriptor matching.
    pub matching: MatchConfig,
    /// Depth lookup of RGB-D features.
    pub depth: DepthConfig,
    /// Warp the depth image into the colour camera first (unregistered RGB-D, e.g. 7-Scenes).
    pub register_depth: Option<DepthRegistration>,
    /// Stereo matching of features.
    pub stereo: StereoConfig,
    /// Farthest stereo point used \[m\].
    pub max_stereo_depth_m: f64,
    /// Motion estimation.
    pub motion: MotionConfig,
    /// Local map model.
    pub local_map: LocalMapConfig,
    /// Failed frames in a row after which tracking restarts from the current frame at the last
    /// pose.
    pub max_consecutive_failures: usize,
    /// World point map.
    pub voxel_map: VoxelMapConfig,
    /// Keyframes, place recognition and loop closure (off by default; `slamkit vo --slam`).
    pub loop_closure: LoopClosureConfig,
}

impl Default for VoConfig {
    fn default() -> Self {
        Self {
            frontend: FrontendKind::Klt,
            mode: TrackingMode::LocalMap,
            use_clahe: false,
            clahe: ClaheConfig::default(),
            auto_clahe: AutoClaheConfig::default(),
            min_mean_intensity: 12.0,
            shi_tomasi: ShiTomasiConfig::default(),
            // 11 px rather than OpenCV's 21: on KITTI 06 and 7-Scenes both more accurate and
            // faster (BENCHMARKS.md)
            klt: KltConfig {
                window_px: 11,
                ..KltConfig::default()
            },
            max_features: 400,
            orb: OrbConfig::default(),
            matching: MatchConfig::default(),
            depth: DepthConfig::default(),
            register_depth: None,
            stereo: StereoConfig::default(),
            max_stereo_depth_m: 25.0,
            motion: MotionConfig::default(),
            local_map: LocalMapConfig::default(),
            max_consecutive_failures: 5,
            voxel_map: VoxelMapConfig::default(),
            loop_closure: LoopClosureConfig::default(),
        }
    }
}

impl VoConfig {
    /// Checks the ranges this crate relies on (the kernels check their own).
    ///
    /// # Errors
    /// [`VoError::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<(), VoError> {
        self.motion.validate()?;
        self.local_map.validate()?;
        self.voxel_map.validate()?;
        self.loop_closure.validate()?;
        if self.max_features == 0 {
            return Err(VoError::config("max_features", 0, "must be > 0"));
        }
        if !(self.depth.min_depth_m >= 0.0 && self.depth.max_depth_m > self.depth.min_depth_m) {
            return Err(VoError::config(
                "depth.max_depth_m",
                self.depth.max_depth_m,
                "must be > min_depth_m >= 0",
            ));
        }
        let vb = self.depth.virtual_baseline_m;
        if vb.is_nan() || vb < 0.0 || vb.is_infinite() {
            return Err(VoError::config(
                "depth.virtual_baseline_m",
                vb,
                "must be finite and >= 0",
            ));
        }
        if self.max_stereo_depth_m.is_nan() || self.max_stereo_depth_m <= 0.0 {
            return Err(VoError::config(
                "max_stereo_depth_m",
                self.max_stereo_depth_m,
                "must be > 0",
            ));
        }
        self.auto_clahe.validate()?;
        if !self.min_mean_intensity.is_finite() {
            return Err(VoError::config(
                "min_mean_intensity",
                self.min_mean_intensity,
                "must be finite",
            ));
        }
        Ok(())
    }
}
