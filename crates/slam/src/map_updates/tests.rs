use super::*;
use crate::{LidarSlam, LidarSlamConfig};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use slamkit_lidar::sim_scan::SegmentWorld;

/// The messages of a session that drives twice round the test room (so loop closure moves
/// keyframes sent before), and the session.
fn messages() -> (Vec<MapUpdate>, LidarSlam) {
    let world = SegmentWorld::room();
    let mut slam = LidarSlam::new(LidarSlamConfig::default(), Pose2::identity()).unwrap();
    let config = UpdateConfig {
        batch_keyframes: 3,
        ..UpdateConfig::default()
    };
    let mut outbox = UpdateOutbox::new(config).unwrap();
    let mut out = Vec::new();
    for i in 0..240 {
        let a = i as f64 * std::f64::consts::PI / 60.0;
        let pose = Pose2::new([2.5 * a.cos(), 2.0 * a.sin()].into(), a + 1.5);
        let mut scan = world.scan(&pose, 361, 4.7, 20.0);
        scan.timestamp = 0.1 * i as f64;
        // a corner of every scan returns nothing, another is out of the sensor's range
        scan.ranges_m[7] = f64::NAN;
        scan.ranges_m[8] = 25.0;
        slam.push_scan(scan);
        out.extend(outbox.poll(slam.live_map().unwrap(), 0.1 * i as f64));
    }
    out.extend(outbox.flush(slam.live_map().unwrap()));
    (out, slam)
}

fn bytes(updates: &[MapUpdate]) -> Vec<Vec<u8>> {
    updates.iter().map(|u| u.to_bytes().unwrap()).collect()
}

#[test]
fn messages_round_trip_to_the_same_bytes_and_content() {
    let (updates, _) = messages();
    assert!(updates.len() > 10, "{}", updates.len());
    for (update, b) in updates.iter().zip(bytes(&updates)) {
        let back = MapUpdate::from_bytes(&b).unwrap();
        assert_eq!(back.to_bytes().unwrap(), b);
        assert_eq!(back.seq, update.seq);
        match (&back.body, &update.body) {
            (UpdateBody::Edges { .. }, _) => assert_eq!(&back, update),
            (
                UpdateBody::Keyframes { first, keyframes },
                UpdateBody::Keyframes {
                    first: f0,
                    keyframes: k0,
                },
            ) => {
                assert_eq!(first, f0);
                for (a, b) in keyframes.iter().zip(k0) {
                    assert_eq!(a.world_from_base, b.world_from_base);
                    assert_eq!(a.scan.timestamp, b.scan.timestamp);
                    let ranges = a.scan.ranges_m.iter().zip(&b.scan.ranges_m);
                    for (ra, rb) in ranges {
                        assert!(
                            ra.is_nan() && rb.is_nan() || (ra - rb).abs() <= 5e-4,
                            "{ra} {rb}"
                        );
                    }
                }
            }
            other => panic!("{other:?}"),
        }
    }
    let status = MapUpdate {
        seq: 9,
        body: UpdateBody::Status(RobotStatus {
            timestamp: 12.5,
            tracking: TrackingStatus::Predicted,
            pose: Some(quantised(&Pose2::new([1.0, -2.0].into(), 3.0))),
            keyframes: 40,
        }),
    };
    assert_eq!(
        MapUpdate::from_bytes(&status.to_bytes().unwrap()).unwrap(),
        status
    );
}

#[test]
fn the_rebuilt_map_follows_the_session_within_the_tolerance() {
    let (updates, slam) = messages();
    let mut inbox = RobotInbox::default();
    for u in &updates {
        assert_eq!(inbox.apply(u.clone()).unwrap(), Applied::New);
    }
    let (map, own) = (inbox.map(), slam.map());
    assert_eq!(map.keyframes.len(), own.keyframes.len());
    assert_eq!(map.edges.len(), own.edges.len());
    let config = UpdateConfig::default();
    for (a, b) in map.keyframes.iter().zip(&own.keyframes) {
        let d = a.world_from_base.inverse() * b.world_from_base;
        assert!(d.translation.vector.norm() <= config.moved_m + 1e-4);
        assert!(d.rotation.angle().abs() <= config.moved_rad + 1e-5);
    }
}

#[test]
fn apply_is_idempotent_and_order_free() {
    let (updates, _) = messages();
    let mut in_order = RobotInbox::default();
    for u in &updates {
        in_order.apply(u.clone()).unwrap();
    }
    let reference = bytes(&[MapUpdate {
        seq: 0,
        body: UpdateBody::Keyframes {
            first: 0,
            keyframes: in_order.map().keyframes.clone(),
        },
    }]);
    for seed in 0..5 {
        // every message twice, shuffled, through the wire
        let mut shuffled: Vec<Vec<u8>> = bytes(&updates);
        shuffled.extend(bytes(&updates));
        shuffled.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
        let mut inbox = RobotInbox::default();
        let mut duplicates = 0;
        for b in &shuffled {
            match inbox.apply(MapUpdate::from_bytes(b).unwrap()).unwrap() {
                Applied::Duplicate => duplicates += 1,
                Applied::New | Applied::Held | Applied::Status => {}
            }
        }
        assert_eq!(duplicates, updates.len());
        assert!(inbox.missing().is_empty());
        assert_eq!(inbox.applied(), updates.len() as u64);
        assert_eq!(inbox.map().edges, in_order.map().edges);
        let rebuilt = bytes(&[MapUpdate {
            seq: 0,
            body: UpdateBody::Keyframes {
                first: 0,
                keyframes: inbox.map().keyframes.clone(),
            },
        }]);
        assert_eq!(rebuilt, reference, "seed {seed}");
    }
}

#[test]
fn gaps_are_listed_and_filled_late() {
    let (updates, _) = messages();
    let n = updates.len() as u64;
    let mut inbox = RobotInbox::default();
    // messages 2 and 5 lost, and the last; the status says how many were sent
    for u in updates.iter().filter(|u| ![2, 5, n - 1].contains(&u.seq)) {
        inbox.apply(u.clone()).unwrap();
    }
    assert_eq!(inbox.applied(), 2);
    assert_eq!(inbox.missing(), [2, 5]);
    let status = MapUpdate {
        seq: n,
        body: UpdateBody::Status(RobotStatus {
            timestamp: 30.0,
            tracking: TrackingStatus::Tracking,
            pose: None,
            keyframes: 0,
        }),
    };
    assert_eq!(inbox.apply(status).unwrap(), Applied::Status);
    assert_eq!(inbox.missing(), [2, 5, n - 1]);
    for seq in [5, 2, n - 1] {
        inbox.apply(updates[seq as usize].clone()).unwrap();
    }
    assert!(inbox.missing().is_empty());
    assert_eq!(inbox.applied(), n);
}

#[test]
fn conflicting_broken_and_newer_messages_are_refused() {
    let (updates, _) = messages();
    let mut inbox = RobotInbox::default();
    inbox.apply(updates[0].clone()).unwrap();
    // the same number with other content
    let mut other = updates[1].clone();
    other.seq = 0;
    let err = inbox.apply(other).unwrap_err();
    assert!(err.to_string().contains("differs"), "{err}");
    // an edge to a keyframe the map lacks
    let bad = MapUpdate {
        seq: 1,
        body: UpdateBody::Edges {
            edges: Vec::new(),
            moved: vec![(1000, Pose2::identity())],
        },
    };
    assert!(inbox.apply(bad).unwrap_err().to_string().contains("beyond"));
    assert_eq!(inbox.applied(), 1);
    let good = updates[0].to_bytes().unwrap();
    for cut in [0, 3, 9, good.len() / 2, good.len() - 1] {
        assert!(MapUpdate::from_bytes(&good[..cut]).is_err(), "cut at {cut}");
    }
    let mut newer = good.clone();
    newer[4] = 99;
    let err = MapUpdate::from_bytes(&newer).unwrap_err();
    assert!(err.to_string().contains("newer"), "{err}");
    let mut kind = good;
    kind[8] = 7;
    assert!(MapUpdate::from_bytes(&kind).is_err());
    let nan = MapUpdate {
        seq: 0,
        body: UpdateBody::Edges {
            edges: Vec::new(),
            moved: vec![(0, Pose2::new([f64::NAN, 0.0].into(), 0.0))],
        },
    };
    assert!(nan.to_bytes().is_err());
}

#[test]
fn batches_wait_for_their_size_or_their_age() {
    let config = UpdateConfig {
        batch_keyframes: 3,
        max_delay_s: 2.0,
        ..UpdateConfig::default()
    };
    let mut outbox = UpdateOutbox::new(config).unwrap();
    let scan = SegmentWorld::room().scan(&Pose2::identity(), 11, 4.7, 20.0);
    let keyframes: Vec<_> = (0..4)
        .map(|i| slamkit_lidar::point_map::Keyframe {
            world_from_base: Pose2::new([i as f64, 0.0].into(), 0.0),
            points: Vec::new(),
            normals: Vec::new(),
        })
        .collect();
    let scans = vec![scan; 4];
    let mut poll = |n: usize, t: f64| {
        let map = crate::lidar::LiveMap {
            keyframes: &keyframes[..n],
            scans: &scans[..n],
            edges: &[],
        };
        outbox.poll(map, t).len()
    };
    // one keyframe waits 2 s of sensor time, then goes alone
    assert_eq!(poll(1, 0.0), 0);
    assert_eq!(poll(1, 1.9), 0);
    assert_eq!(poll(1, 2.0), 1);
    assert_eq!(poll(1, 2.1), 0);
    // two more wait; the third fills the batch, which goes at once
    assert_eq!(poll(3, 2.2), 0);
    assert_eq!(poll(4, 2.3), 1);
    assert!(UpdateOutbox::new(UpdateConfig {
        batch_keyframes: 0,
        ..UpdateConfig::default()
    })
    .is_err());
}

#[test]
fn keyframes_that_moved_are_sent_again() {
    use slamkit_lidar::point_map::Keyframe;
    let keyframe = |x: f64| Keyframe {
        world_from_base: Pose2::new([x, 0.0].into(), 0.0),
        points: Vec::new(),
        normals: Vec::new(),
    };
    let scan = SegmentWorld::room().scan(&Pose2::identity(), 11, 4.7, 20.0);
    let mut keyframes = vec![keyframe(0.0), keyframe(1.0), keyframe(2.0)];
    let scans = vec![scan.clone(), scan.clone(), scan];
    let mut outbox = UpdateOutbox::new(UpdateConfig::default()).unwrap();
    fn live(keyframes: &[Keyframe]) -> crate::lidar::LiveMap<'_> {
        crate::lidar::LiveMap {
            keyframes,
            scans: &[],
            edges: &[],
        }
    }
    let first = outbox.flush(crate::lidar::LiveMap {
        scans: &scans,
        ..live(&keyframes)
    });
    assert_eq!(first.len(), 1);
    // loop closure moves keyframe 1 by 3 cm and keyframe 2 by 1 cm (under the 2 cm tolerance)
    keyframes[1].world_from_base = Pose2::new([1.0, 0.03].into(), 0.0);
    keyframes[2].world_from_base = Pose2::new([2.01, 0.0].into(), 0.0);
    let second = outbox.flush(live(&keyframes));
    let [MapUpdate {
        seq: 1,
        body: UpdateBody::Edges { edges, moved },
    }] = second.as_slice()
    else {
        panic!("{second:?}");
    };
    assert!(edges.is_empty());
    assert_eq!(
        moved,
        &[(1, quantised(&Pose2::new([1.0, 0.03].into(), 0.0)))]
    );
    // nothing moved since: nothing to send
    assert!(outbox.flush(live(&keyframes)).is_empty());
    let mut inbox = RobotInbox::default();
    for u in first.into_iter().chain(second) {
        inbox.apply(u).unwrap();
    }
    let y = inbox.map().keyframes[1]
        .world_from_base
        .translation
        .vector
        .y;
    assert!((y - 0.03).abs() < 1e-12);
}
