//! The ROS 2 side of the bag reader on arbitrary bytes: never panics. The input is decoded as
//! one CDR message of each type slamkit reads, and opened as a ROS 2 storage file (as it is,
//! which an SQLite header makes a `.db3`, and behind the MCAP magic so the fuzzer starts past
//! it): summary, messages in storage order, the lidar log. The file goes through a temporary
//! file because the storage readers open paths.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::bag::messages::{LaserScanMsg, OdometryMsg, RosMessage, TfMessageMsg};
use slamkit_io::bag::{open, scans::scan_log, ScanTopics};

fn storage_file(path: &std::path::Path, bytes: &[u8]) {
    if std::fs::write(path, bytes).is_err() {
        return;
    }
    let Ok(mut bag) = open(path) else {
        return;
    };
    let _ = bag.summary();
    let _ = bag.read_stored(&mut |_, _| {});
    if let Ok(log) = scan_log(bag.as_mut(), &ScanTopics::default()) {
        for scan in &log.log.scans {
            assert!(scan.timestamp.is_finite());
            assert!(scan.angle_min_rad.is_finite() && scan.angle_increment_rad.is_finite());
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let _ = LaserScanMsg::decode_cdr(data);
    let _ = OdometryMsg::decode_cdr(data);
    let _ = TfMessageMsg::decode_cdr(data);
    let path = std::env::temp_dir().join(format!("slamkit_fuzz_ros2_{}", std::process::id()));
    storage_file(&path, data);
    let mut mcap = b"\x89MCAP0\r\n".to_vec();
    mcap.extend_from_slice(data);
    storage_file(&path, &mcap);
    let _ = std::fs::remove_file(&path);
});
