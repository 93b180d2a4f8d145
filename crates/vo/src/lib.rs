//! slamkit-vo: visual odometry for a stereo or RGB-D camera on a small CPU.
//!
//! Frames: camera x right, y down, z forward; poses `world_from_camera`, the world being the
//! first frame's camera (or the ground truth's first pose when the dataset has one). Units m,
//! rad, s. Modules, each citing its papers:
//! * [`frame`]: preprocessing (CLAHE), detection (Shi–Tomasi or ORB), depth of features.
//! * [`depth`]: depth of features from an RGB-D depth image, registered to the colour camera;
//!   stereo depth comes from `slamkit_vision::stereo`.
//! * [`registration`]: depth of an unregistered RGB-D pair read in the colour camera at the
//!   features only.
//! * [`spacing`]: minimum distance between features, on a grid.
//! * [`motion`]: RANSAC over 3-point Horn samples, inlier refit and Gauss–Newton refinement on
//!   reprojection error.
//! * [`odometry`]: frame-to-frame or local-map tracking, failed frames keeping the reference.
//! * [`local_map`]: features of the recent key frames, positions averaged over observations.
//! * [`voxel_map`]: the world point map, merged per voxel, PLY export.
//! * [`metrics`]: ATE, RPE and end-point drift against ground truth.
//! * [`pipeline`]: the four-thread pipeline, real-time play with frame dropping.
//! * [`config`]: the configuration, defaults and TOML.
//! * [`error`]: [`VoError`]; a bad frame is not an error but a failed [`FrameStatus`], counted
//!   and skipped.

pub mod config;
pub mod depth;
pub mod error;
pub mod frame;
pub mod local_map;
pub mod metrics;
pub mod motion;
pub mod odometry;
pub mod pipeline;
pub mod registration;
pub mod spacing;
pub mod voxel_map;

pub use config::{FrontendKind, TrackingMode, VoConfig};
pub use error::VoError;
pub use metrics::{evaluate, VoMetrics};
pub use odometry::{FailReason, FrameStatus, Odometry};
pub use pipeline::{run, FrameRecord, RunOptions, RunStats, VoRun};
pub use voxel_map::VoxelMap;
