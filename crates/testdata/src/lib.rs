//! slamkit-testdata: what slamkit's integration tests share: how they find the public
//! datasets, and a free loopback port for the tests that start network peers.
//!
//! The real data (lidar logs, KITTI, 7-Scenes, …) is never part of the repository; CI and
//! developers point `SLAMKIT_DATA` at a copy of it. A test that needs it asks [`data`] and
//! returns early when it gets `None`, having said on stderr that it was skipped, so that
//! `cargo test` on a machine without the data passes visibly rather than silently.

use std::path::PathBuf;

/// The environment variable naming the data folder.
pub const DATA_VAR: &str = "SLAMKIT_DATA";

/// `$SLAMKIT_DATA/<relative>`, or `None` after printing `skipped: <test>: SLAMKIT_DATA not set`
/// when the variable is unset.
pub fn data(test: &str, relative: &str) -> Option<PathBuf> {
    match std::env::var_os(DATA_VAR) {
        Some(root) => Some(PathBuf::from(root).join(relative)),
        None => {
            eprintln!("skipped: {test}: {DATA_VAR} not set");
            None
        }
    }
}

/// A free TCP port on 127.0.0.1 (bound and given back: the peer a test starts binds it a moment
/// later), so tests that start Zenoh or DDS peers never meet on a fixed port.
///
/// # Panics
/// When the OS cannot bind a loopback socket: the test cannot run at all.
#[allow(clippy::expect_used)]
pub fn free_loopback_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|listener| listener.local_addr())
        .expect("binding a loopback port")
        .port()
}
