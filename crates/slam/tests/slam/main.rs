//! `slamkit-slam`'s integration tests: the sessions (`LidarSlam`, `DroneSlam`, `VisualSlam`,
//! `GroundRobotNav`), the map file and the merge, on real data and simulated runs.
//!
//! One test binary, not one per file: each binary links and instantiates the workspace's
//! generic code anew, and `cargo test` runs binaries one after another, so a binary with one
//! long single-threaded test left a core idle. Here the tests of every module share the
//! harness's threads. Run one module's tests with a filter, e.g.
//! `cargo test --release -p slamkit-slam --test slam drone_in_map::`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod benchmark_log;
mod drone_in_map;
mod ground_robot_map;
mod lidar_damaged;
mod lidar_lifecycle;
mod lidar_merge;
mod map_updates_intel;
mod visual_bad_frames;
mod visual_clahe;
mod visual_damaged_data;
mod visual_fast_motion;
mod visual_localisation;
mod visual_loop_closure;
mod visual_map_file;
mod visual_real_data;
mod visual_relocalisation;
