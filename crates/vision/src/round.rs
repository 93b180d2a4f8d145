//! Branch-free rounding for hot loops. `f32::round_ties_even` compiles to a call into libm's
//! `rintf` on the baseline x86-64 target (no SSE4.1 `roundss`), which costs more than the
//! arithmetic around it and stops vectorisation; the classic magic-number trick gives the same
//! result with one add and one subtract.

/// 1.5 · 2²³: adding it moves any |x| < 2²² into the range where the f32 spacing is exactly 1.
const MAGIC: f32 = 12_582_912.0;

/// Rounds half to even, bit-exact with `f32::round_ties_even` for |x| < 2²² (the caller's
/// values are pixel coordinates and grey levels, far inside that range).
#[inline]
pub(crate) fn round_ties_even(x: f32) -> f32 {
    (x + MAGIC) - MAGIC
}

/// [`round_ties_even`] as an `i32`, for |x| < 2²²: the integer is read from the bits of
/// `x + MAGIC` (whose exponent is fixed), so no float → int conversion (scalar on SSE2 for the
/// saturating `as`) is needed and loops vectorise.
#[inline]
pub(crate) fn round_to_i32(x: f32) -> i32 {
    (x + MAGIC).to_bits() as i32 - MAGIC.to_bits() as i32
}

/// `saturate_cast<uchar>(float)` of OpenCV: round half to even, clamp to 0..=255 (NaN gives 0).
/// Branch-free through [`round_to_i32`], so loops over it vectorise.
#[inline]
#[allow(clippy::manual_clamp)] // `clamp` keeps NaN, and NaN's bits are not a grey level
pub(crate) fn round_to_u8(v: f32) -> u8 {
    // `max` first: it returns 0 for NaN
    round_to_i32(v.max(0.0).min(255.0)) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_std_rounding() {
        let mut x = -5000.0f32;
        while x < 5000.0 {
            assert_eq!(round_ties_even(x), x.round_ties_even(), "{x}");
            assert_eq!(round_to_i32(x), x.round_ties_even() as i32, "{x}");
            x += 0.125;
        }
        for v in [
            0.5f32,
            1.5,
            2.5,
            -0.5,
            -1.5,
            254.5,
            4_194_303.5,
            -4_194_303.5,
        ] {
            assert_eq!(round_ties_even(v), v.round_ties_even(), "{v}");
        }
        assert_eq!(round_to_u8(-3.0), 0);
        assert_eq!(round_to_u8(300.0), 255);
        assert_eq!(round_to_u8(127.5), 128);
        assert_eq!(round_to_u8(126.5), 126);
        assert_eq!(round_to_u8(f32::NAN), 0);
        for v in 0..=1020 {
            let v = v as f32 * 0.25;
            assert_eq!(round_to_u8(v), v.round_ties_even() as u8, "{v}");
        }
    }
}
