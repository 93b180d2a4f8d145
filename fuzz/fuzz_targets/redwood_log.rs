//! Redwood / Open3D `.log` trajectory parser on arbitrary text: never panics; accepted poses
//! are finite with unit quaternions and increasing timestamps.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::redwood::parse_log;

fuzz_target!(|text: &str| {
    if let Ok(trajectory) = parse_log(text, "trajectory.log", 30.0) {
        let mut last = f64::NEG_INFINITY;
        for p in &trajectory.poses {
            assert!(p.timestamp.is_finite() && p.timestamp > last);
            last = p.timestamp;
            assert!(p.pose.translation.vector.iter().all(|c| c.is_finite()));
            let q = p.pose.rotation.coords;
            assert!(q.iter().all(|c| c.is_finite()) && (q.norm() - 1.0).abs() < 1e-9);
        }
    }
});
