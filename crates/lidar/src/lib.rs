//! slamkit-lidar: 2D scan matching and ICP-SLAM.
//!
//! Frames: a scan's beams are measured in the laser frame and brought into the robot `base`
//! frame with [`LaserScan::base_from_laser`](slamkit_core::LaserScan); poses estimated here are
//! `world_from_base`, with the world frame anchored at the first usable scan.
//!
//! * [`icp`]: point-to-point and point-to-line ICP (Besl & McKay 1992; Chen & Medioni 1992;
//!   Censi, "An ICP variant using a point-to-line metric", ICRA 2008) with robust kernels and
//!   Gauss–Newton or Levenberg–Marquardt steps.
//! * [`correlative`]: exhaustive correlative scan matching with a two-level branch and bound
//!   (Olson, "Real-time correlative scan matching", ICRA 2009; Hess et al., ICRA 2016) for poor
//!   initial guesses.
//! * [`global_search`]: global localisation in a keyframe map with no prior pose: coarse
//!   correlative searches around anchors, refined by ICP, accepted only when unambiguous.
//! * [`icp_slam`]: the incremental map builder of MRPT's icp-slam: each scan is matched against a
//!   point map of keyframes, and inserted into it when the robot has moved far enough.
//! * [`cloud`]: scan preprocessing: beam end points in the base frame, voxel downsampling,
//!   surface normals by local PCA.
//! * [`nn`]: nearest-neighbour search over 2D points (k-d tree and uniform grid) with the points
//!   and normals kept beside the index.
//! * [`point_map`]: the keyframe point map ICP-SLAM matches against, thinned per voxel.
//! * [`pose_graph`]: the 2D pose graph and its sparse Gauss–Newton solver (Lu & Milios 1997;
//!   Grisetti et al. 2010), the back end of loop closure.
//! * [`motion`]: the odometry motion model of the particle filters (Thrun et al. 2005, 5.4).
//! * [`particles`]: log-weight normalisation, effective sample size, low-variance resampling.
//! * [`rbpf`]: Rao-Blackwellised particle-filter SLAM in the style of GMapping (Grisetti et al.
//!   2007), copy-on-write grids, relocalisation against each particle's own past.
//! * [`mcl`]: Monte Carlo localisation in a saved occupancy grid (Dellaert et al. 1999).
//! * [`layers`]: layered 2D SLAM for a drone flying through a 3D room with a planar lidar and
//!   up/down range finders.
//! * [`sim_scan`]: ray-cast scans in a world of line segments, fixtures for tests and benchmarks.
//!
//! Nothing in this crate prints, reads files or exits the process.

pub mod cloud;
pub mod correlative;
mod error;
pub mod global_search;
pub mod icp;
pub mod icp_slam;
pub mod layers;
pub mod mcl;
pub mod motion;
pub mod nn;
pub mod particles;
pub mod point_map;
pub mod pose_graph;
pub mod rbpf;
pub mod sim_scan;

pub use error::LidarError;
