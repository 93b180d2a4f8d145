//! slamkit's ROS 2 nodes on loopback: each module starts a node and its peers (plain RustDDS
//! writers and readers, or slamkit's simulator nodes) in this process, on `127.0.0.1` only.
//!
//! One test binary, not one per node: each binary instantiated RustDDS's and ros2-client's
//! generic code anew (the four took about 230 s of one core to build in CI, the largest two
//! 107 and 72; docs/experiments/ci-time.md), and `cargo test` runs binaries one after another.
//! Run one module's tests with a filter, e.g. `cargo test --release -p slamkit-ros2 --test
//! loopback vo::`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod drone;
mod lidar_record;
mod nav;
mod vo;

use ros2_client::dds::rustdds::{
    DataWriterStatus, DomainParticipant, Publisher, QosPolicies, Subscriber,
};
use ros2_client::{Context, NodeName, NodeOptions};
use slamkit_ros2::dds::Discovery;
use std::time::{Duration, Instant};

/// The DDS domains one run of this binary may use: [`DOMAINS_PER_RUN`] consecutive ones.
const DOMAINS_PER_RUN: u16 = 5;

/// Unicast discovery on `127.0.0.1` on a domain of this test's own: `slot` (0 to
/// [`DOMAINS_PER_RUN`] − 1) names the test within this process, which runs its tests at the
/// same time, and the process id picks the block of domains, so concurrent runs of the binary
/// rarely meet (and a meeting costs a retry, not a wrong result: every peer checks the
/// topics' types). RTPS puts domain d's ports at 7400 + 250·d, so domains go up to 232.
fn loopback_discovery(slot: u16) -> Discovery {
    assert!(slot < DOMAINS_PER_RUN);
    let blocks = 220 / DOMAINS_PER_RUN;
    Discovery {
        domain_id: 10 + (std::process::id() % u32::from(blocks)) as u16 * DOMAINS_PER_RUN + slot,
        localhost_only: true,
    }
}

/// Waits until each writer (its status, polled by one closure each) has matched a reader:
/// the node under test discovered over `127.0.0.1`. Fails after 10 s, naming which did not.
fn wait_until_matched(statuses: &[&dyn Fn() -> Option<DataWriterStatus>]) {
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut matched = vec![false; statuses.len()];
    while matched.iter().any(|m| !m) {
        assert!(
            Instant::now() < deadline,
            "the node was not discovered: {matched:?}"
        );
        for (m, status) in matched.iter_mut().zip(statuses) {
            *m |= matches!(status(), Some(DataWriterStatus::PublicationMatched { .. }));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The test's side of a loopback run: plain RustDDS writers and readers (so the test can see
/// them matched) on a participant of `discovery`, and a ROS 2 node named `name` on it to make
/// the topics.
/// The topic `name` of messages `ros_type` (`"package/Type"`, as ROS 2 writes them).
fn typed_topic(
    ros: &mut ros2_client::Node,
    name: &str,
    ros_type: &str,
    qos: &ros2_client::QosProfile,
) -> ros2_client::dds::rustdds::Topic {
    let (package, ty) = ros_type.split_once('/').unwrap();
    slamkit_ros2::dds::topic(ros, name, package, ty, qos).unwrap()
}

struct Peer {
    /// Held for the writers' and readers' lifetime (they refer to it weakly).
    _participant: DomainParticipant,
    ros: ros2_client::Node,
    publisher: Publisher,
    subscriber: Subscriber,
}

impl Peer {
    fn new(discovery: &Discovery, name: &str) -> Peer {
        let participant: DomainParticipant = discovery.participant().unwrap();
        let context = Context::from_domain_participant(participant.clone()).unwrap();
        let ros = context
            .new_node(
                NodeName::new("/", name).unwrap(),
                NodeOptions::new().enable_rosout(false),
            )
            .unwrap();
        Peer {
            publisher: participant
                .create_publisher(&QosPolicies::qos_none())
                .unwrap(),
            subscriber: participant
                .create_subscriber(&QosPolicies::qos_none())
                .unwrap(),
            _participant: participant,
            ros,
        }
    }
}
