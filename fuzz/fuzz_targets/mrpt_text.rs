//! MRPT rawlog text dump and ground-truth parsers on arbitrary text: never panic, and accepted
//! scans carry finite geometry, in a log that is not mostly out of time order.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::mrpt_text::{parse_mrpt_ground_truth, parse_mrpt_text};

fuzz_target!(|text: &str| {
    if let Ok(log) = parse_mrpt_text(text, "<fuzz>") {
        let order = log.time_order;
        assert_eq!(order.steps, log.scans.len() - 1);
        assert!(!order.is_mostly_out_of_order(), "{order:?}");
        assert!(order.backward_s.is_finite() && order.span_s.is_finite(), "{order:?}");
        for scan in &log.scans {
            let hits = scan.hit_points();
            assert!(hits.iter().all(|p| p.x.is_finite() && p.y.is_finite()));
            assert!(scan.timestamp.is_finite() && scan.ranges_m.len() >= 2);
            assert!(scan.angle_min_rad.is_finite() && scan.angle_increment_rad.is_finite());
            assert!(scan.max_range_m > 0.0 && scan.max_range_m.is_finite());
            assert!(scan.base_from_laser.rotation.angle().is_finite());
            let odometry = scan.odometry.map(|o| o.translation.vector);
            assert!(odometry.is_some_and(|t| t.iter().all(|v| v.is_finite())));
        }
    }
    if let Ok(gt) = parse_mrpt_ground_truth(text, "<fuzz>") {
        assert!(!gt.is_empty());
        assert!(gt
            .poses
            .iter()
            .all(|p| p.pose.rotation.coords.iter().all(|c| c.is_finite())));
    }
});
