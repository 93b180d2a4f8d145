//! `slamkit-io`'s integration tests: the readers on the real files and on damaged copies.
//!
//! One test binary, not one per file: each binary links and instantiates the workspace's
//! generic code anew, and `cargo test` runs binaries one after another, so a binary with one
//! long single-threaded test left a core idle. Here the tests of every module share the
//! harness's threads. Run one module's tests with a filter, e.g.
//! `cargo test --release -p slamkit-io --test io damaged_bags::`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod damaged_bags;
mod damaged_images;
mod damaged_logs;
mod damaged_ros2_bags;
mod datasets;
mod lidar_logs;
mod missing_frames;
mod ros1_bags;
