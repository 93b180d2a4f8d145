//! ROS 1 bags written by an independent tool (PyPI `rosbags` 0.11.9, through
//! `scripts/make_ros1_bag_fixtures.py`: a robot driving 20 steps, see that script for the
//! messages) read with known answers, and then damaged: cut at every length, bit-flipped at
//! every byte, unindexed, of another type or another message version. A damaged bag gives a
//! clear error or skipped-and-counted messages, never a panic.

use slamkit_io::bag::info::bag_info;
use slamkit_io::bag::reader::IndexState;
use slamkit_io::bag::scans::{scan_log, Mounting};
use slamkit_io::bag::{Bag, BagError, Order, ScanTopics};
use std::io::Cursor;
use std::path::PathBuf;

fn fixture(name: &str) -> Vec<u8> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/ros1")
        .join(name);
    std::fs::read(path).unwrap()
}

fn open(bytes: &[u8]) -> Result<Bag<Cursor<Vec<u8>>>, BagError> {
    Bag::from_reader(Cursor::new(bytes.to_vec()), "<test>")
}

fn log_of(bytes: &[u8], topics: &ScanTopics) -> Result<slamkit_io::bag::BagScanLog, BagError> {
    scan_log(&mut open(bytes)?, topics)
}

#[test]
fn every_compression_gives_the_written_scans() {
    let mut logs = Vec::new();
    for name in ["robot_none.bag", "robot_bz2.bag", "robot_lz4.bag"] {
        let bag = log_of(&fixture(name), &ScanTopics::default()).unwrap();
        assert!(bag.read.damaged_chunks.is_empty() && bag.read.truncated.is_none());
        assert!(bag.read.chunks > 1, "{name}: {} chunks", bag.read.chunks);
        let log = &bag.log;
        assert_eq!((log.scans.len(), log.odometry_lines), (20, 20), "{name}");
        assert_eq!(log.other_message_lines, 5, "{name}: the /chatter strings");
        assert!(log.skipped.is_empty());
        for (k, scan) in log.scans.iter().enumerate() {
            let kf = k as f64;
            assert!((scan.timestamp - (100.05 + 0.1 * kf)).abs() < 1e-6);
            for (i, r) in scan.ranges_m.iter().enumerate() {
                let want = f64::from((1.0 + 0.01 * kf + 0.1 * i as f64) as f32);
                if i == 0 && k % 5 == 0 {
                    assert!(r.is_nan(), "below range_min: no return");
                } else {
                    assert_eq!(*r, want, "{name} scan {k} beam {i}");
                }
            }
            assert_eq!(scan.angle_min_rad, f64::from(-1.5f32));
            assert_eq!(scan.max_range_m, 30.0);
            // halfway between the odometry readings around it (the last: the nearer one)
            let o = scan.odometry.unwrap();
            let s = if k < 19 { 0.5 } else { 0.0 };
            assert!(
                (o.translation.x - 0.1 * (kf + s)).abs() < 1e-9,
                "{name} {k}: {o}"
            );
            assert!(
                (o.rotation.angle() - 0.05 * (kf + s)).abs() < 1e-9,
                "{name} {k}: {o}"
            );
            let m = scan.base_from_laser;
            assert!(
                (m.translation.x - 0.1).abs() < 1e-12 && (m.translation.y + 0.05).abs() < 1e-12
            );
            assert!((m.rotation.angle() - 0.3).abs() < 1e-12);
        }
        let Mounting::TfStatic {
            base_frame,
            laser_frame,
            tilt_deg,
            ..
        } = &bag.mounting
        else {
            panic!("{:?}", bag.mounting);
        };
        assert_eq!(
            (base_frame.as_str(), laser_frame.as_str()),
            ("base_link", "laser")
        );
        assert!(*tilt_deg < 1e-6);
        logs.push(bag.log);
    }
    assert!(logs
        .windows(2)
        .all(|w| format!("{:?}", w[0]) == format!("{:?}", w[1])));
}

#[test]
fn info_from_the_index_equals_a_walk_of_an_unindexed_copy() {
    let bytes = fixture("robot_lz4.bag");
    let indexed = bag_info(&mut open(&bytes).unwrap()).unwrap();
    assert_eq!(indexed.index, IndexState::Indexed);
    let topics: Vec<(&str, usize)> = indexed
        .topics
        .iter()
        .map(|t| (t.topic.as_str(), t.messages))
        .collect();
    assert_eq!(
        topics,
        [
            ("/chatter", 5),
            ("/odom", 20),
            ("/scan", 20),
            ("/tf_static", 1)
        ]
    );
    assert_eq!(
        (indexed.start_s, indexed.end_s),
        (Some(100.0), Some(101.95))
    );
    // A recording that was never closed: no index, index_pos 0.
    let unindexed = unindex(&bytes);
    let mut bag = open(&unindexed).unwrap();
    assert_eq!(*bag.index_state(), IndexState::NotIndexed);
    let walked = bag_info(&mut bag).unwrap();
    assert_eq!(walked.topics, indexed.topics);
    assert_eq!(
        (walked.messages, walked.chunks),
        (indexed.messages, indexed.chunks)
    );
    assert_eq!(
        walked.compression,
        vec![slamkit_io::bag::chunk::Compression::Lz4]
    );
    let a = log_of(&bytes, &ScanTopics::default()).unwrap();
    let b = log_of(&unindexed, &ScanTopics::default()).unwrap();
    // (Debug text: NaN ranges are not == themselves)
    assert_eq!(format!("{:?}", a.log), format!("{:?}", b.log));
}

/// The bag as a recorder leaves it before closing: cut where the index starts, index_pos 0.
fn unindex(bytes: &[u8]) -> Vec<u8> {
    let field = bytes.windows(10).position(|w| w == b"index_pos=").unwrap() + 10;
    let pos = u64::from_le_bytes(bytes[field..field + 8].try_into().unwrap()) as usize;
    let mut out = bytes[..pos].to_vec();
    out[field..field + 8].fill(0);
    out
}

#[test]
fn time_order_and_storage_order_hold_the_same_messages() {
    let mut bag = open(&fixture("robot_bz2.bag")).unwrap();
    let mut seen = [Vec::new(), Vec::new()];
    for (i, order) in [Order::Storage, Order::Time].into_iter().enumerate() {
        bag.read_messages(order, |conn, msg| {
            seen[i].push((conn.topic.clone(), msg.time, msg.data.to_vec()))
        })
        .unwrap();
    }
    assert_eq!(seen[0].len(), 46);
    assert!(seen[1].windows(2).all(|w| w[0].1 <= w[1].1));
    seen[0].sort_by(|a, b| a.1.cmp(&b.1).then(a.0.cmp(&b.0)));
    seen[1].sort_by(|a, b| a.1.cmp(&b.1).then(a.0.cmp(&b.0)));
    assert_eq!(seen[0], seen[1]);
}

#[test]
fn topics_chosen_by_type_or_by_name() {
    let bytes = fixture("two_lasers.bag");
    let err = log_of(&bytes, &ScanTopics::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("/scan, /scan_rear") && err.contains("--scan-topic"),
        "{err}"
    );
    let rear = ScanTopics {
        scan: Some("/scan_rear".into()),
        odom: None,
    };
    let bag = log_of(&bytes, &rear).unwrap();
    assert_eq!(bag.log.scans.len(), 20);
    // /tf_static knows no laser_rear frame: the laser is taken at the base
    assert!(
        matches!(bag.mounting, Mounting::Identity { .. }),
        "{:?}",
        bag.mounting
    );
    for (topic, want) in [
        (
            "/chatter",
            "carries std_msgs/String, not sensor_msgs/LaserScan",
        ),
        (
            "/nope",
            "no topic /nope (topics: /chatter [std_msgs/String]",
        ),
    ] {
        let asked = ScanTopics {
            scan: Some(topic.into()),
            odom: None,
        };
        let err = log_of(&bytes, &asked).unwrap_err().to_string();
        assert!(err.starts_with("<test>: ") && err.contains(want), "{err}");
    }
}

#[test]
fn another_version_of_a_message_is_refused_by_md5sum() {
    let mut bytes = fixture("robot_none.bag");
    let md5 = b"90c7ef2dc6895d81024acba2ac42f369";
    let mut replaced = 0;
    while let Some(at) = bytes.windows(32).position(|w| w == md5) {
        bytes[at..at + 8].copy_from_slice(b"00000000");
        replaced += 1;
    }
    assert_eq!(replaced, 2, "once in the chunk, once in the index");
    let err = log_of(&bytes, &ScanTopics::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("another version of the message"), "{err}");
}

#[test]
fn not_a_ros1_bag_says_what_it_is() {
    for (head, want) in [
        (&b"\x89MCAP0\r\n"[..], "MCAP"),
        (b"#ROSBAG V1.2\n", "format 1.2"),
        (b"RAWLASER1 0 1 2", "no '#ROSBAG V2.0' magic"),
        (b"", "no '#ROSBAG V2.0' magic"),
    ] {
        let err = open(head).unwrap_err().to_string();
        assert!(
            err.starts_with("<test>: not a ROS 1 bag") && err.contains(want),
            "{err}"
        );
    }
}

/// Every third length (cuts inside every kind of record): an error, or the scans before the
/// cut with the cut reported.
#[test]
fn truncated_at_every_length_never_panics() {
    for name in ["robot_none.bag", "robot_bz2.bag", "robot_lz4.bag"] {
        let bytes = fixture(name);
        let (mut errors, mut partial) = (0, 0);
        for len in (0..bytes.len()).step_by(3) {
            match log_of(&bytes[..len], &ScanTopics::default()) {
                Ok(bag) => {
                    assert!(bag.log.scans.len() <= 20);
                    // a cut inside a record is reported; one between records leaves the
                    // index beyond the end, and so unreadable
                    let reported = bag.read.truncated.is_some()
                        || matches!(bag.index, IndexState::Unreadable(_));
                    assert!(reported || bag.log.scans.len() == 20, "{name} {len}");
                    partial += 1;
                }
                Err(e) => {
                    assert!(!e.to_string().contains('\n'));
                    errors += 1;
                }
            }
            let _ = open(&bytes[..len]).map(|mut b| bag_info(&mut b));
        }
        println!(
            "{name}: {} cuts: {errors} errors, {partial} partial logs",
            bytes.len() / 3
        );
        assert!(errors > 0 && partial > 0);
    }
}

/// Every fifth byte flipped (all record kinds are hit): an error, skipped messages or chunks,
/// or the same log; never a panic.
#[test]
fn bit_flips_never_panic() {
    for name in ["robot_none.bag", "robot_bz2.bag", "robot_lz4.bag"] {
        let bytes = fixture(name);
        let clean = log_of(&bytes, &ScanTopics::default()).unwrap();
        let (mut errors, mut damaged, mut skipped) = (0, 0, 0);
        for at in (0..bytes.len()).step_by(5) {
            let mut flipped = bytes.clone();
            flipped[at] ^= 0x20;
            match log_of(&flipped, &ScanTopics::default()) {
                Ok(bag) => {
                    damaged += usize::from(!bag.read.damaged_chunks.is_empty());
                    skipped += usize::from(!bag.log.skipped.is_empty());
                }
                Err(e) => {
                    assert!(!e.to_string().contains('\n'));
                    errors += 1;
                }
            }
            if let Ok(mut b) = open(&flipped) {
                let _ = bag_info(&mut b);
                let _ = b.read_messages(Order::Time, |_, _| {});
            }
        }
        println!(
            "{name}: {} flips: {errors} errors, {damaged} with a chunk skipped, {skipped} with \
             messages skipped",
            bytes.len() / 5
        );
        assert!(errors > 0, "{name}");
        if name != "robot_none.bag" {
            assert!(
                damaged > 0,
                "{name}: a flip inside compressed data skips its chunk"
            );
        } else {
            assert!(skipped > 0, "{name}: a flip in a plain message skips it");
        }
        assert_eq!(clean.log.scans.len(), 20);
    }
}
