//! The ROS 1 bag reader on arbitrary bytes: never panics. The input is tried as a whole bag
//! (as it is, and behind the `#ROSBAG V2.0` magic so the fuzzer starts past it): header,
//! index, chunks in storage and time order, the lidar log; and as one serialised message of
//! each type slamkit decodes. A lidar log the reader accepts has finite timestamps, odometry
//! and mounting.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::bag::messages::{LaserScanMsg, OdometryMsg, RosMessage, TfMessageMsg};
use slamkit_io::bag::record::MAGIC;
use slamkit_io::bag::{bag_info, scans::scan_log, Bag, Order, ScanTopics};
use std::io::Cursor;

fn whole_bag(bytes: Vec<u8>) {
    let Ok(mut bag) = Bag::from_reader(Cursor::new(bytes), "<fuzz>") else {
        return;
    };
    let _ = bag_info(&mut bag);
    let _ = bag.read_messages(Order::Time, |_, _| {});
    let Ok(log) = scan_log(&mut bag, &ScanTopics::default()) else {
        return;
    };
    for scan in &log.log.scans {
        assert!(scan.timestamp.is_finite());
        assert!(scan.angle_min_rad.is_finite() && scan.angle_increment_rad.is_finite());
        let m = scan.base_from_laser;
        assert!(m.translation.vector.iter().all(|v| v.is_finite()) && m.rotation.angle().is_finite());
        if let Some(o) = scan.odometry {
            assert!(o.translation.vector.iter().all(|v| v.is_finite()) && o.rotation.angle().is_finite());
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let _ = LaserScanMsg::decode(data);
    let _ = OdometryMsg::decode(data);
    let _ = TfMessageMsg::decode(data);
    whole_bag(data.to_vec());
    let mut bytes = MAGIC.to_vec();
    bytes.extend_from_slice(data);
    whole_bag(bytes);
});
