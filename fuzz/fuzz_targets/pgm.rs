//! Binary PGM (P5) parser on arbitrary bytes: never panics; an accepted image has exactly
//! width × height pixels.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_map::grid_io::parse_pgm;

fuzz_target!(|bytes: &[u8]| {
    if let Ok((width, height, pixels)) = parse_pgm(bytes) {
        assert_eq!(Some(pixels.len()), width.checked_mul(height));
    }
});
