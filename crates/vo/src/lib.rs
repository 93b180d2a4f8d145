//! slamkit-vo: visual odometry for a stereo or RGB-D camera on a small CPU.
//!
//! Frames: camera x right, y down, z forward; poses `world_from_camera`, the world being where
//! [`Odometry::new`] was told the first camera is. Units m, rad, s. The online session over
//! these parts, and the threads that overlap them, are `slamkit_slam::visual`. Modules, each
//! citing its papers:
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
//! * [`local_ba`]: local bundle adjustment of the recent key frames and their points.
//! * [`covisibility`]: map points with their observations, the keyframes' covisibility graph.
//! * [`place_index`]: the online place index over binary descriptors (HBST).
//! * [`loop_closure`]: loop candidates, temporal consistency, geometric verification.
//! * [`relocalisation`]: a frame without a pose found among a map's keyframes.
//! * [`map_tracking`]: a frame's pose measured from a saved map's points near its prediction.
//! * [`voxel_map`]: the world point map, merged per voxel, PLY export.
//! * [`pose_graph`]: the SE(3) pose graph of loop closure, optimised by Levenberg–Marquardt
//!   with exact SE(3) Jacobians, sparse block elimination and an optional Cauchy kernel.
//! * [`metrics`]: ATE, RPE and end-point drift against ground truth.
//! * [`config`]: the configuration, defaults and TOML.
//! * [`error`]: [`VoError`]; a bad frame is not an error but a failed [`FrameStatus`], counted
//!   and skipped.

pub mod config;
pub mod covisibility;
pub mod depth;
pub mod error;
pub mod frame;
pub mod local_ba;
pub mod local_map;
pub mod loop_closure;
pub mod map_tracking;
pub mod metrics;
pub mod motion;
pub mod odometry;
pub mod place_index;
pub mod pose_graph;
pub mod registration;
pub mod relocalisation;
pub mod spacing;
pub mod voxel_map;

pub use config::{AutoClaheConfig, FrontendKind, TrackingMode, VoConfig};
pub use error::VoError;
pub use metrics::{evaluate, VoMetrics};
pub use odometry::{FailReason, FrameStatus, LocalBundle, Odometry};
pub use voxel_map::VoxelMap;
