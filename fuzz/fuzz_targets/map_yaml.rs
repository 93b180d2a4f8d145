//! ROS `map_server` YAML parser on arbitrary text: never panics; an accepted map has a finite
//! positive resolution, a finite origin and thresholds inside \[0, 1\].
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_map::grid_io::parse_map_yaml;
use std::path::Path;

fuzz_target!(|text: &str| {
    if let Ok(meta) = parse_map_yaml(text, Path::new("map.yaml")) {
        assert!(meta.resolution_m > 0.0 && meta.resolution_m.is_finite());
        assert!(meta.origin.iter().all(|c| c.is_finite()));
        for t in [meta.occupied_thresh, meta.free_thresh] {
            assert!((0.0..=1.0).contains(&t), "threshold {t}");
        }
    }
});
