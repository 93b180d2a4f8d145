//! Map updates on real data (issue 22, item 1): the Intel log mapped by a `LidarSlam` session
//! whose map goes out as map update messages ([`slamkit_slam::map_updates`]). Measures the
//! bytes sent (messages and their Zenoh keys) against the scans as ROS 2 `LaserScan` messages
//! would carry them (goal: under 5 %), and checks that the map rebuilt from the messages is
//! the session's: every keyframe and edge, each keyframe within the resend tolerance of the
//! session's final pose. Log: `$SLAMKIT_DATA/lidar2d/SOURCES.md`. Skipped when `SLAMKIT_DATA`
//! is not set; run with `--release`.

use slamkit_core::Pose2;
use slamkit_slam::map_updates::{
    laser_scan_cdr_bytes, MapUpdate, RobotInbox, UpdateBody, UpdateConfig, UpdateOutbox,
};
use slamkit_slam::{LidarSlam, LidarSlamConfig};

/// The Zenoh key a message of robot `r1` of fleet `f` goes out on (as `slamkit-fleet` names
/// it): its bytes travel with every message.
fn key_bytes(update: &MapUpdate) -> usize {
    format!("slamkit/f/r1/{}/{}", update.stream().name(), update.seq).len()
}

#[test]
fn intel_map_updates_cost_under_five_percent_of_the_scans() {
    let Some(dir) = slamkit_testdata::data(
        "intel_map_updates_cost_under_five_percent_of_the_scans",
        "lidar2d/intel",
    ) else {
        return;
    };
    let scans = slamkit_io::carmen::read_carmen(&dir.join("intel.fromrosbag.clf.gz"))
        .unwrap()
        .scans;
    let config = UpdateConfig::default();
    let mut slam = LidarSlam::new(LidarSlamConfig::default(), Pose2::identity()).unwrap();
    let mut outbox = UpdateOutbox::new(config.clone()).unwrap();
    let mut inbox = RobotInbox::default();
    let (mut raw, mut sent, mut messages) = (0usize, 0usize, 0usize);
    // bytes per stream (keyframes, edges, status) and keyframes sent again
    let (mut per_stream, mut moved) = ([0usize; 3], 0usize);
    let mut send = |updates: Vec<MapUpdate>, inbox: &mut RobotInbox| {
        for u in updates {
            let bytes = u.to_bytes().unwrap();
            sent += bytes.len() + key_bytes(&u);
            per_stream[u.stream() as usize] += bytes.len() + key_bytes(&u);
            if let UpdateBody::Edges { moved: m, .. } = &u.body {
                moved += m.len();
            }
            messages += 1;
            inbox.apply(MapUpdate::from_bytes(&bytes).unwrap()).unwrap();
        }
    };
    let mut last_status = 0.0;
    for scan in &scans {
        raw += laser_scan_cdr_bytes(scan.ranges_m.len());
        let t = scan.timestamp;
        let update = slam.push_scan(scan.clone());
        send(outbox.poll(slam.live_map().unwrap(), t), &mut inbox);
        // a status message every 10 s
        if t - last_status >= 10.0 {
            last_status = t;
            send(vec![outbox.status(&update)], &mut inbox);
        }
    }
    send(outbox.flush(slam.live_map().unwrap()), &mut inbox);
    let seconds = scans.last().unwrap().timestamp - scans[0].timestamp;
    let own = slam.map();
    let map = inbox.map();
    let share = sent as f64 / raw as f64;
    eprintln!(
        "intel: {} scans over {seconds:.0} s, {} keyframes, {} edges; scans as ROS 2 LaserScan \
         {raw} B ({:.0} B/s); map updates {sent} B in {messages} messages ({:.0} B/s), {:.2} % \
         of the scans",
        scans.len(),
        own.keyframes.len(),
        own.edges.len(),
        raw as f64 / seconds,
        sent as f64 / seconds,
        100.0 * share
    );
    eprintln!(
        "intel: keyframes {} B, edges {} B ({moved} keyframes sent again), status {} B",
        per_stream[0], per_stream[1], per_stream[2]
    );
    assert!(share < 0.05, "{:.2} %", 100.0 * share);
    assert!(inbox.missing().is_empty());
    assert_eq!(map.keyframes.len(), own.keyframes.len());
    assert_eq!(map.edges.len(), own.edges.len());
    let worst = map
        .keyframes
        .iter()
        .zip(&own.keyframes)
        .map(|(a, b)| {
            (a.world_from_base.inverse() * b.world_from_base)
                .translation
                .vector
                .norm()
        })
        .fold(0.0, f64::max);
    eprintln!("intel: rebuilt keyframes at most {worst:.4} m from the session's");
    assert!(worst <= config.moved_m + 1e-4, "{worst}");
}
