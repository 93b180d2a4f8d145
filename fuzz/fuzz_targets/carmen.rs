//! CARMEN log parser on arbitrary bytes (plain or, when the bytes start with the gzip magic,
//! compressed): never panics, and whatever it accepts is a usable scan in a log that is not
//! mostly out of time order (non-finite ranges are kept as beams without a return).
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::carmen::parse_carmen;

fuzz_target!(|data: &[u8]| {
    let Ok(log) = parse_carmen(data, "<fuzz>") else {
        return;
    };
    assert!(!log.scans.is_empty());
    let order = log.time_order;
    assert_eq!(order.steps, log.scans.len() - 1);
    assert!(order.backward_steps <= order.steps && !order.is_mostly_out_of_order());
    assert!(order.backward_s.is_finite() && order.span_s.is_finite(), "{order:?}");
    for scan in &log.scans {
        assert!(scan.timestamp.is_finite());
        assert!(!scan.ranges_m.is_empty());
        let hits = scan.hit_points();
        assert!(hits.iter().all(|p| p.x.is_finite() && p.y.is_finite()));
        assert!(scan.angle_min_rad.is_finite() && scan.angle_increment_rad.is_finite());
        assert!(scan.angle_increment_rad != 0.0);
        assert!(scan.max_range_m > 0.0 && scan.max_range_m.is_finite());
        let odometry_finite = scan.odometry.map_or(true, |o| {
            o.translation.vector.iter().all(|v| v.is_finite()) && o.rotation.angle().is_finite()
        });
        assert!(odometry_finite, "odometry {:?}", scan.odometry);
        let mount = scan.base_from_laser;
        assert!(
            mount.translation.vector.iter().all(|v| v.is_finite()),
            "{mount:?}"
        );
        assert!(mount.rotation.angle().is_finite(), "{mount:?}");
    }
});
