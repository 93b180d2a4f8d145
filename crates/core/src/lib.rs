//! slamkit-core: the geometry every other slamkit crate speaks.
//!
//! * Poses are nalgebra isometries ([`Pose2`], [`Pose3`]) named `target_from_source`:
//!   `world_from_camera * p_camera = p_world`.
//! * Units are metres, radians and seconds; a unit suffix is used wherever a bare number could
//!   be misread.
//! * Camera frame: x right, y down, z forward (TUM, OpenCV, RealSense).
//!
//!
//! Geometry provided here, each module citing its papers:
//! * [`absolute_orientation`]: Horn (1987) and Umeyama (1991) closed-form similarity fits, used
//!   for trajectory alignment and 3D–3D motion estimation.
//! * [`block_elimination`]: sparse block LDLᵀ elimination (minimum-degree order) of pose-graph
//!   normal equations, for any block size.
//! * [`mod@ransac`]: adaptive RANSAC (Fischler & Bolles 1981) over any [`Estimator`].
//! * [`robust`]: robust kernels (Cauchy) for reweighted least squares.
//! * [`camera`]: pinhole projection with Brown–Conrady distortion.
//! * [`trajectory`]: timestamped poses with SE(3) interpolation; [`point_cloud`]: point sets.
//! * [`observation`]: the timestamped [`Observation`] every source produces and every SLAM
//!   session consumes.
//! * [`pose`]: the [`Pose2`] / [`Pose3`] aliases and conversions between 2D and 3D poses.
//! * [`se3`]: the SE(3) exponential and logarithm, adjoint and right-Jacobian inverse (exact
//!   Lie-group maps for pose optimisation).
//! * [`scan`]: [`LaserScan`], a 2D laser scan as a planar lidar delivers it.
//! * [`image`]: a minimal owned row-major image shared by the readers and the vision crates.
//! * [`timing`]: per-stage timings summarised as median and 95th percentile ([`StageTimings`]).
//! * [`error`]: [`GeometryError`], bad input as an `Err`, never a panic.
//!
//! Nothing in this crate prints, reads files or exits the process.

pub mod absolute_orientation;
pub mod block_elimination;
pub mod camera;
pub mod error;
pub mod image;
pub mod observation;
pub mod point_cloud;
pub mod pose;
pub mod ransac;
pub mod robust;
pub mod scan;
pub mod se3;
pub mod timing;
pub mod trajectory;

#[cfg(test)]
mod test_support;

pub use absolute_orientation::{horn, umeyama, SimilarityFit};
pub use camera::{Distortion, Intrinsics, PinholeCamera};
pub use error::GeometryError;
pub use observation::Observation;
pub use point_cloud::{BoundingBox, PointCloud};
pub use pose::{Pose2, Pose3};
pub use ransac::{
    ransac, Estimator, PointMatch, RansacConfig, RansacResult, RigidTransformEstimator,
};
pub use scan::LaserScan;
pub use timing::StageTimings;
pub use trajectory::{StampedPose, Trajectory};
