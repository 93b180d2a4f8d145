//! The ROS 1 bags of the Freiburg benchmark (`$SLAMKIT_DATA/lidar2d/{intel,aces}/*.clf.orig.bag`,
//! written by github.com/INESCTEC/ricoslam's converter from the CARMEN logs, bz2 chunks) read
//! end to end, and compared scan by scan with the CARMEN logs derived from the same bags
//! (`*.fromrosbag.clf.gz`, see `$SLAMKIT_DATA/lidar2d/SOURCES.md` §2.3).

use slamkit_io::bag::info::bag_info;
use slamkit_io::bag::scans::Mounting;
use slamkit_io::bag::{read_scan_log, Bag, Order, ScanTopics};
use slamkit_io::carmen::read_carmen;

/// Largest differences between the bag's scans and the CARMEN log's, field by field.
#[derive(Debug, Default)]
struct Differences {
    timestamp_s: f64,
    range_m: f64,
    angle_min_rad: f64,
    angle_increment_rad: f64,
    odometry_m: f64,
    odometry_rad: f64,
    max_range_m: f64,
}

fn compare(name: &str, scans: usize, odometry: usize) -> Option<Differences> {
    let dir = slamkit_testdata::data(&format!("bag_{name}"), &format!("lidar2d/{name}"))?;
    let bag_path = dir.join(format!("{name}.clf.orig.bag"));
    let bag = read_scan_log(&bag_path, &ScanTopics::default()).unwrap();
    let carmen = read_carmen(&dir.join(format!("{name}.fromrosbag.clf.gz"))).unwrap();
    assert_eq!(bag.scan_topic, "/scan");
    assert_eq!(bag.odom_topic.as_deref(), Some("/odom"));
    assert!(bag.log.skipped.is_empty(), "{:?}", &bag.log.skipped[..1]);
    assert!(bag.read.damaged_chunks.is_empty() && bag.read.truncated.is_none());
    assert_eq!(bag.log.scans.len(), scans);
    assert_eq!(carmen.scans.len(), scans);
    assert_eq!(bag.log.odometry_lines, odometry);
    assert_eq!(
        bag.log.time_order.backward_steps,
        carmen.time_order.backward_steps
    );
    // The converter put the laser at the base: /tf_static base_link -> laser is identity.
    let Mounting::TfStatic {
        x_y_yaw, mirrored, ..
    } = &bag.mounting
    else {
        panic!("{:?}", bag.mounting);
    };
    assert!(
        x_y_yaw.iter().all(|v| v.abs() < 1e-12) && !mirrored,
        "{x_y_yaw:?}"
    );
    let mut d = Differences::default();
    for (b, c) in bag.log.scans.iter().zip(&carmen.scans) {
        let up = |m: &mut f64, v: f64| *m = m.max(v.abs());
        up(&mut d.timestamp_s, b.timestamp - c.timestamp);
        up(&mut d.angle_min_rad, b.angle_min_rad - c.angle_min_rad);
        up(
            &mut d.angle_increment_rad,
            b.angle_increment_rad - c.angle_increment_rad,
        );
        up(&mut d.max_range_m, b.max_range_m - c.max_range_m);
        assert_eq!(b.ranges_m.len(), c.ranges_m.len());
        for (rb, rc) in b.ranges_m.iter().zip(&c.ranges_m) {
            up(&mut d.range_m, rb - rc);
            // half a float32 step: the bag's float32 is the nearest to the log's decimal
            assert!(
                (rb - rc).abs() <= rc.abs() * f64::from(f32::EPSILON) / 2.0,
                "{rb} {rc}"
            );
        }
        let (ob, oc) = (b.odometry.unwrap(), c.odometry.unwrap());
        up(
            &mut d.odometry_m,
            (ob.translation.vector - oc.translation.vector).norm(),
        );
        up(
            &mut d.odometry_rad,
            (ob.rotation.inverse() * oc.rotation).angle(),
        );
    }
    println!("{name}: bag vs CARMEN scans, largest differences: {d:?}");
    Some(d)
}

/// The differences are the CARMEN text's rounding, nothing else: timestamps printed with 6
/// decimals from the bag's nanoseconds (they parse back to the same f64), ranges (float32 in
/// the bag: each within half a float32 step of the log's 2- or 3-decimal value, at most
/// 3.8e-6 m at 81.83 m), beam angles (float32, against 6 decimals in the log), odometry
/// (float64, the same numbers; the yaw from the bag's quaternion to 1e-12 rad).
fn check_rounding_only(d: &Differences) {
    assert!(d.timestamp_s <= 5e-7, "{d:?}");
    assert!(d.range_m <= 2e-6, "{d:?}");
    assert!(
        d.angle_min_rad <= 5e-7 && d.angle_increment_rad <= 5e-7,
        "{d:?}"
    );
    assert!(d.odometry_m == 0.0 && d.odometry_rad <= 1e-12, "{d:?}");
    assert_eq!(d.max_range_m, 0.0, "{d:?}");
}

#[test]
fn intel_bag_gives_the_carmen_logs_scans() {
    if let Some(d) = compare("intel", 13631, 26915) {
        check_rounding_only(&d);
    }
}

#[test]
fn aces_bag_gives_the_carmen_logs_scans() {
    if let Some(d) = compare("aces", 7374, 7375) {
        check_rounding_only(&d);
    }
}

#[test]
fn intel_bag_info_from_the_index_and_time_order() {
    let Some(dir) = slamkit_testdata::data("bag_intel_info", "lidar2d/intel") else {
        return;
    };
    let mut bag = Bag::open(&dir.join("intel.clf.orig.bag")).unwrap();
    let info = bag_info(&mut bag).unwrap();
    let counts: Vec<(&str, &str, usize)> = info
        .topics
        .iter()
        .map(|t| (t.topic.as_str(), t.message_type.as_str(), t.messages))
        .collect();
    assert_eq!(
        counts,
        vec![
            ("/odom", "nav_msgs/Odometry", 26915),
            ("/scan", "sensor_msgs/LaserScan", 13631),
            ("/tf", "tf2_msgs/TFMessage", 26915),
            ("/tf_static", "tf2_msgs/TFMessage", 1),
        ]
    );
    assert_eq!(info.chunks, 45);
    // SOURCES.md: scan time span 976052857.34–976055548.63
    let (start, end) = (info.start_s.unwrap(), info.end_s.unwrap());
    assert!((start - 976052857.337).abs() < 1e-2 && (end - 976055548.63).abs() < 1e-2);
    // In time order the record times never step back; in storage order they do 631 times
    // on /scan (the log's physical order).
    for (order, want) in [(Order::Time, 0), (Order::Storage, 631)] {
        let (mut last, mut back, mut n) = (None, 0, 0);
        bag.read_messages(order, |conn, msg| {
            if conn.topic == "/scan" {
                back += usize::from(last.is_some_and(|l| msg.time < l));
                last = Some(msg.time);
                n += 1;
            }
        })
        .unwrap();
        assert_eq!((n, back), (13631, want), "{order:?}");
    }
}
