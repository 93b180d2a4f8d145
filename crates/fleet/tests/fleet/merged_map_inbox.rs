//! [`MergedMapInbox`]: a robot keeps the newest merged map it hears of, never an older or a
//! broken one, and asks the merger for it once when a status names a newer map.

use slamkit_fleet::keys::{merged_key, Merged};
use slamkit_fleet::merged_map::{MergedMapInbox, MergedReceipts};
use slamkit_fleet::PeerConfig;
use slamkit_slam::lidar::LidarMap;
use std::time::{Duration, Instant};
use zenoh::Wait;

/// Two peers on loopback: the merger's side (listening) and a robot's (connected).
fn peers() -> (zenoh::Session, zenoh::Session) {
    let (merger, port) = crate::listening_peer();
    let robot = PeerConfig {
        listen: Vec::new(),
        connect: vec![format!("tcp/127.0.0.1:{port}")],
    }
    .open()
    .unwrap();
    (merger, robot)
}

/// Polls until `done` or 10 s.
fn poll_until(inbox: &mut MergedMapInbox, done: impl Fn(&MergedReceipts) -> bool) {
    let start = Instant::now();
    while !done(&inbox.receipts()) {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "{:?}",
            inbox.receipts()
        );
        inbox.poll().unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn the_newest_map_is_kept_an_older_or_broken_one_is_not_and_the_merger_is_asked_once() {
    let (merger, robot) = peers();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("merged.skmap");
    let mut inbox = MergedMapInbox::new(robot, "lab", &path).unwrap();
    let map = |keyframes_note: &str| {
        LidarMap::default()
            .to_new_file(serde_json::json!({ "note": keyframes_note }))
            .unwrap()
            .to_bytes()
            .unwrap()
    };
    let key = merged_key("lab", Merged::Map);
    let (older, newer, newest) = (
        merger.new_timestamp(),
        merger.new_timestamp(),
        merger.new_timestamp(),
    );
    // wait until the robot's subscriber is known to the merger's side
    let publisher = merger.declare_publisher(key.clone()).wait().unwrap();
    let start = Instant::now();
    while !publisher.matching_status().wait().unwrap().matching() {
        assert!(start.elapsed() < Duration::from_secs(10));
        std::thread::sleep(Duration::from_millis(20));
    }
    // made once: a map file's header holds the second it was made in
    let newer_map = map("newer");
    for (bytes, stamp) in [
        (newer_map.clone(), newer),
        (map("older"), older),
        (b"not a map".to_vec(), newest),
    ] {
        publisher.put(bytes).timestamp(stamp).wait().unwrap();
    }
    poll_until(&mut inbox, |r| r.maps == 3);
    let r = inbox.receipts();
    assert_eq!((r.kept, r.rejected, r.fetched), (1, 1, 0));
    assert_eq!(std::fs::read(&path).unwrap(), newer_map);
    assert_eq!(inbox.newest(), Some(newer));

    // the merger's queryable comes in reach (the robot asks once), and a status names a
    // newer map than the one held (no second query while the first is out)
    let answer = map("newest");
    let served = answer.clone();
    let _queryable = merger
        .declare_queryable(key.clone())
        .callback(move |query| {
            let _ = query
                .reply(query.key_expr().clone(), served.clone())
                .timestamp(newest)
                .wait();
        })
        .wait()
        .unwrap();
    merger
        .put(merged_key("lab", Merged::Status), newest.to_string())
        .wait()
        .unwrap();
    poll_until(&mut inbox, |r| r.kept == 2 && r.statuses == 1);
    let r = inbox.receipts();
    assert_eq!((r.queries, r.fetched, r.maps), (1, 1, 4));
    assert_eq!(std::fs::read(&path).unwrap(), answer);
    assert_eq!(inbox.newest(), Some(newest));
}
