//! KITTI `calib.txt` parser on arbitrary text: never panics; an accepted calibration has the
//! positive baseline its documentation promises.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::kitti::parse_calib;

fuzz_target!(|text: &str| {
    if let Ok(calib) = parse_calib(text) {
        let baseline = calib.baseline_m();
        assert!(
            baseline > 0.0 && baseline.is_finite(),
            "baseline {baseline}"
        );
    }
});
