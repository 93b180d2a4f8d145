//! Drone CSV parsers (`ranges.csv`, `imu.csv`, `flow.csv`) on arbitrary text: never panic;
//! accepted readings have finite, non-decreasing timestamps, finite non-negative ranges,
//! finite attitudes and gyro headings, positive finite integration times and finite
//! velocities.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::drone_csv::{parse_flow, parse_imu, parse_ranges};

fn ordered(times: impl Iterator<Item = f64>) -> bool {
    let mut previous = f64::NEG_INFINITY;
    times.into_iter().all(|t| {
        let ok = t.is_finite() && t >= previous;
        previous = t;
        ok
    })
}

fuzz_target!(|text: &str| {
    if let Ok(ranges) = parse_ranges(text, "fuzz") {
        assert!(ordered(ranges.iter().map(|r| r.timestamp)));
        for r in &ranges {
            for v in [r.up_m, r.down_m].into_iter().flatten() {
                assert!(v.is_finite() && v >= 0.0, "{r:?}");
            }
        }
    }
    if let Ok(imu) = parse_imu(text, "fuzz") {
        assert!(ordered(imu.iter().map(|i| i.timestamp)));
        for i in &imu {
            assert!(i.roll_rad.is_finite() && i.pitch_rad.is_finite(), "{i:?}");
            assert!(i.gyro_yaw_rad.map_or(true, f64::is_finite), "{i:?}");
        }
    }
    if let Ok(flow) = parse_flow(text, "fuzz") {
        assert!(ordered(flow.iter().map(|f| f.timestamp)));
        for f in &flow {
            assert!(f.integration_s.is_finite() && f.integration_s > 0.0, "{f:?}");
            assert!(f.velocity_mps.map_or(true, |v| v.iter().all(|c| c.is_finite())), "{f:?}");
        }
    }
});
