//! Two robots and a merger on loopback (issue 22, item 2): each robot its own Zenoh session
//! (peer mode, multicast scouting off, explicit `tcp/127.0.0.1:PORT` endpoints: no packet
//! leaves the machine), mapping a simulated room with its own `LidarSlam` session and
//! publishing its map updates; the merger collects them and fetches by query what it missed.
//! With 30 % of the publications dropped, the merger's maps and their merge are the same as
//! without loss.

use slamkit_core::Pose2;
use slamkit_fleet::{Merger, PeerConfig, RobotPublisher};
use slamkit_lidar::sim_scan::SegmentWorld;
use slamkit_slam::map_updates::{UpdateConfig, UpdateOutbox};
use slamkit_slam::merge::MergeConfig;
use slamkit_slam::{LidarSlam, LidarSlamConfig};
use std::time::{Duration, Instant};
use zenoh::Wait;

/// The test room with furniture, so that no place looks like another.
fn world() -> SegmentWorld {
    let mut room = SegmentWorld::room();
    for corners in [
        [(3.5, 2.6), (4.3, 2.6), (4.3, 3.3), (3.5, 3.3)],
        [(-4.2, -4.0), (-4.0, -4.0), (-4.0, -2.8), (-4.2, -2.8)],
        [(-0.5, 3.0), (0.5, 3.0), (0.5, 4.0), (-0.5, 4.0)],
    ] {
        room.segments
            .extend(SegmentWorld::polygon(&corners).segments);
    }
    room
}

/// One robot: drives from `from` to `to` at `heading`, maps, publishes.
fn robot(name: &str, merger: u16, from: (f64, f64), to: (f64, f64), heading: f64, loss: f64) {
    let session = PeerConfig {
        listen: vec![format!(
            "tcp/127.0.0.1:{}",
            slamkit_testdata::free_loopback_port()
        )],
        connect: vec![format!("tcp/127.0.0.1:{merger}")],
    }
    .open()
    .unwrap();
    wait_for_peers(&session, 1);
    let mut publisher = RobotPublisher::new(session, "test", name)
        .unwrap()
        .with_loss(loss, 7);
    let world = world();
    let mut slam = LidarSlam::new(LidarSlamConfig::default(), Pose2::identity()).unwrap();
    let config = UpdateConfig {
        batch_keyframes: 4,
        ..UpdateConfig::default()
    };
    let mut outbox = UpdateOutbox::new(config).unwrap();
    let steps = 160;
    for i in 0..=steps {
        let s = i as f64 / steps as f64;
        let world_from_base = Pose2::new(
            [from.0 + s * (to.0 - from.0), from.1 + s * (to.1 - from.1)].into(),
            heading,
        );
        let mut scan = world.scan(&world_from_base, 361, 4.7, 20.0);
        scan.timestamp = 0.1 * i as f64;
        let update = slam.push_scan(scan);
        for u in outbox.poll(slam.live_map().unwrap(), update.timestamp) {
            publisher.publish(&u).unwrap();
        }
        if i == steps {
            for u in outbox.flush(slam.live_map().unwrap()) {
                publisher.publish(&u).unwrap();
            }
            // the status goes out until the merger has had it
            publisher.publish(&outbox.status(&update)).unwrap();
        }
    }
    // stay up to answer the merger's queries
    std::thread::sleep(Duration::from_secs(8));
}

fn wait_for_peers(session: &zenoh::Session, n: usize) {
    let start = Instant::now();
    while session.info().peers_zid().wait().count() < n {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "peers did not connect"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

struct Run {
    maps: Vec<Vec<u8>>,
    fetched: usize,
    merged: Vec<Pose2>,
    unmerged: Vec<usize>,
}

fn run(loss: f64) -> Run {
    let (session, port) = crate::listening_peer();
    let mut merger = Merger::new(session.clone(), "test").unwrap();
    let robots = [
        std::thread::spawn(move || robot("a", port, (-4.5, -2.0), (3.5, -2.2), 0.1, loss)),
        std::thread::spawn(move || robot("b", port, (4.0, 2.2), (-4.0, 2.5), 3.0, loss)),
    ];
    // take what comes, and ask for what is missing, until both robots' status arrived and
    // nothing is missing
    let start = Instant::now();
    let mut fetched = 0;
    loop {
        merger.receive(Duration::from_millis(200)).unwrap();
        fetched += merger.fetch_missing(Duration::from_secs(2)).unwrap();
        let done = merger.robots().len() == 2
            && merger.robots().values().all(|i| i.status().is_some())
            && merger.missing() == 0;
        if done {
            break;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "merger never complete"
        );
    }
    for r in robots {
        r.join().unwrap();
    }
    assert_eq!(merger.rejected(), 0);
    let maps = merger
        .robots()
        .values()
        .map(|i| {
            i.map()
                .to_file(slamkit_slam::map_file::MapHeader::new(
                    slamkit_slam::map_file::Rig::Lidar2d,
                    0,
                    None,
                ))
                .unwrap()
                .sections
                .into_iter()
                .flat_map(|s| s.data)
                .collect()
        })
        .collect();
    let mut config = MergeConfig::default();
    config.places.spacing_m = 1.0;
    config.places.half_keyframes = 3;
    config.verify.half_keyframes = 3;
    let (_, outcome) = merger.merge(&config).unwrap();
    Run {
        maps,
        fetched,
        merged: outcome
            .map
            .keyframes
            .iter()
            .map(|k| k.world_from_base)
            .collect(),
        unmerged: outcome.unmerged(),
    }
}

#[test]
fn lossy_fleet_on_loopback_merges_as_the_lossless_one() {
    let clean = run(0.0);
    let lossy = run(0.3);
    eprintln!(
        "fetched by query: {} without loss, {} with 30 % loss; unmerged {:?}",
        clean.fetched, lossy.fetched, clean.unmerged
    );
    // both maps merged, and the loss was made good by queries
    assert!(clean.unmerged.is_empty() && !clean.merged.is_empty());
    assert!(lossy.fetched > 0);
    assert_eq!(lossy.maps, clean.maps);
    assert_eq!(lossy.unmerged, clean.unmerged);
    assert_eq!(lossy.merged.len(), clean.merged.len());
    for (a, b) in lossy.merged.iter().zip(&clean.merged) {
        assert!((a.inverse() * b).translation.vector.norm() < 0.02);
    }
}
