//! `.relations` parser on arbitrary text: never panics, accepted relations are finite.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::relations::parse_relations;

fuzz_target!(|text: &str| {
    if let Ok(relations) = parse_relations(text) {
        assert!(!relations.is_empty());
        for r in &relations {
            assert!(r.t1.is_finite() && r.t2.is_finite());
            let q = r.t1_from_t2.rotation.coords;
            assert!(q.iter().all(|c| c.is_finite()) && (q.norm() - 1.0).abs() < 1e-9);
        }
    }
});
