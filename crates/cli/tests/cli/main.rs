//! `slamkit`'s command-line tests: each module runs the CLI as a user would (the built binary,
//! `CARGO_BIN_EXE_slamkit`) and checks its outputs.
//!
//! One test binary, not one per file: each binary links and instantiates the workspace's
//! generic code anew, and `cargo test` runs binaries one after another, so a binary with one
//! long single-threaded test left a core idle. Here the tests of every module share the
//! harness's threads. Run one module's tests with a filter, e.g.
//! `cargo test --release -p slamkit --test cli bag::`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod bag;
mod demo;
mod drone_recording;
mod eval;
mod fleet;
mod fleet_sim;
mod lidar;
mod nav;
mod outputs;
mod plan;
mod recording;
mod ros2_bags;
mod sim;
mod vo_bags;
mod vo_sim;
