//! The fleet crate's tests, one binary: Zenoh peers on loopback (127.0.0.1, multicast scouting
//! off), and the files a robot keeps. The crate has no unit tests of its own (`[lib] test =
//! false`): its behaviour is all in its public API, and a unit-test build of the crate costs a
//! second optimised compile of it and Zenoh's generics.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test helpers fail loudly

mod loopback;
mod merged_map_inbox;
mod store_file;

/// A Zenoh peer listening on a free loopback port (a merger's side), and the port.
fn listening_peer() -> (zenoh::Session, u16) {
    let port = slamkit_testdata::free_loopback_port();
    let session = slamkit_fleet::PeerConfig {
        listen: vec![format!("tcp/127.0.0.1:{port}")],
        connect: Vec::new(),
    }
    .open()
    .unwrap();
    (session, port)
}
