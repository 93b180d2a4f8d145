//! Image pyramids: OpenCV's `pyrDown` (5-tap binomial `\[1 4 6 4 1\]/16` per axis, then drop every
//! other row and column; P. Burt and E. Adelson, "The Laplacian pyramid as a compact image
//! code", 1983) for KLT, and a bilinear resize (OpenCV `INTER_LINEAR` pixel-centre convention)
//! for ORB's non-dyadic scale pyramid.

use slamkit_core::image::{GrayImage, Image};

use crate::border::{pad_row, reflect101};
use crate::simd::dispatch_avx2;

dispatch_avx2! {
    /// Halves an image as `cv::pyrDown`: output `⌈w/2⌉ × ⌈h/2⌉`, reflect-101 border, rounded.
    pub fn pyr_down(img: &GrayImage) -> GrayImage;
    portable pyr_down_portable {
        let (w, h) = (img.width(), img.height());
        let (dw, dh) = (w.div_ceil(2), h.div_ceil(2));
        if w == 0 || h == 0 {
            return Image::filled(dw, dh, 0);
        }
        // Horizontal pass with decimation: one u16 row (≤ 16·255) per source row.
        let mut tmp = vec![0u16; dw * h];
        let mut padded = Vec::with_capacity(w + 5);
        for (src, dst) in img.data().chunks_exact(w).zip(tmp.chunks_exact_mut(dw)) {
            pad_row(src, 2, &mut padded);
            for (d, win) in dst.iter_mut().zip(padded.windows(5).step_by(2)) {
                let (a, b, c, e, f) = (win[0], win[1], win[2], win[3], win[4]);
                *d = u16::from(a)
                    + u16::from(f)
                    + 4 * (u16::from(b) + u16::from(e))
                    + 6 * u16::from(c);
            }
        }
        let mut out = vec![0u8; dw * dh];
        for (y, dst) in out.chunks_exact_mut(dw).enumerate() {
            let row = |k: isize| {
                let sy = reflect101(2 * y as isize + k, h);
                &tmp[sy * dw..(sy + 1) * dw]
            };
            let (r0, r1, r2, r3, r4) = (row(-2), row(-1), row(0), row(1), row(2));
            for (i, d) in dst.iter_mut().enumerate() {
                let s = u32::from(r0[i])
                    + u32::from(r4[i])
                    + 4 * (u32::from(r1[i]) + u32::from(r3[i]))
                    + 6 * u32::from(r2[i]);
                *d = ((s + 128) >> 8) as u8;
            }
        }
        match Image::from_vec(dw, dh, out) {
            Some(img) => img,
            None => unreachable!("pyr_down buffer has dw*dh pixels"),
        }
    }
}

/// A Gaussian pyramid: level 0 is the input, each next level is [`pyr_down`] of the previous.
#[derive(Debug, Clone)]
pub struct Pyramid {
    levels: Vec<GrayImage>,
}

impl Pyramid {
    /// Builds levels `0..=max_level`, stopping early once a level would be smaller than 1 px.
    pub fn new(img: &GrayImage, max_level: usize) -> Self {
        let mut levels = vec![img.clone()];
        for _ in 0..max_level {
            let Some(last) = levels.last() else { break };
            if last.width() < 2 || last.height() < 2 {
                break;
            }
            let next = pyr_down(last);
            levels.push(next);
        }
        Self { levels }
    }

    /// The levels, finest first.
    pub fn levels(&self) -> &[GrayImage] {
        &self.levels
    }

    /// The levels, finest first, by value.
    pub fn into_levels(self) -> Vec<GrayImage> {
        self.levels
    }
}

/// One output coordinate's source index and 11-bit weight of the next source sample.
type Tap = (usize, u32);

const RESIZE_ONE: u32 = 1 << 11;

/// Source taps of OpenCV's `INTER_LINEAR` along one axis: sample `(i + 0.5)·n_in/n_out − 0.5`,
/// clamped to the image, split into an index and a rounded 11-bit fraction.
fn resize_taps(n_out: usize, n_in: usize) -> Vec<Tap> {
    let scale = n_in as f64 / n_out as f64;
    (0..n_out)
        .map(|i| {
            let s = ((i as f64 + 0.5) * scale - 0.5).max(0.0);
            let i0 = (s.floor() as usize).min(n_in - 1);
            let f = if i0 + 1 >= n_in { 0.0 } else { s - i0 as f64 };
            (i0, (f * f64::from(RESIZE_ONE)).round() as u32)
        })
        .collect()
}

dispatch_avx2! {
    /// Bilinear resize to `dw × dh` with OpenCV's `INTER_LINEAR` sample positions
    /// (`(x + 0.5)·w/dw − 0.5`, clamped to the image) and 11-bit fixed-point weights.
    ///
    /// Each output row first blends its two source rows over the full width (a vectorised
    /// multiply–add), then blends pairs of columns; the products are exact integers, so the
    /// order of the two passes does not change the result.
    pub fn resize_bilinear(img: &GrayImage, dw: usize, dh: usize) -> GrayImage;
    portable resize_bilinear_portable {
        let (w, h) = (img.width(), img.height());
        if w == 0 || h == 0 || dw == 0 || dh == 0 {
            return Image::filled(dw, dh, 0);
        }
        let xt = resize_taps(dw, w);
        let yt = resize_taps(dh, h);
        let data = img.data();
        // one spare column so that the right tap of the last column exists (its weight is 0)
        let mut blend = vec![0u32; w + 1];
        let mut pairs = vec![[0u32; 2]; dw];
        let mut out = vec![0u8; dw * dh];
        for (dst, &(y0, fy)) in out.chunks_exact_mut(dw).zip(&yt) {
            let y1 = (y0 + 1).min(h - 1);
            let (r0, r1) = (&data[y0 * w..(y0 + 1) * w], &data[y1 * w..(y1 + 1) * w]);
            // 8-bit samples times 12-bit weights: 16-bit operands, exact 32-bit sums
            let (w0, w1) = ((RESIZE_ONE - fy) as i16, fy as i16);
            for ((b, &p0), &p1) in blend.iter_mut().zip(r0).zip(r1) {
                let v = i32::from(p0 as i16) * i32::from(w0) + i32::from(p1 as i16) * i32::from(w1);
                *b = v as u32;
            }
            blend[w] = blend[w - 1];
            // the two taps of every output column (scalar loads), then the blend in lanes
            for (p, &(x0, _)) in pairs.iter_mut().zip(&xt) {
                if let Some(&[a, b]) = blend
                    .get(x0..x0 + 2)
                    .and_then(|s| <&[u32; 2]>::try_from(s).ok())
                {
                    *p = [a, b];
                }
            }
            for ((d, &[a, b]), &(_, fx)) in dst.iter_mut().zip(&pairs).zip(&xt) {
                // a·(1 − f) + b·f as a + (b − a)·f: one product, below 2³¹ (a, b < 2²⁰, f ≤ 2¹¹)
                let (a, b, f) = (a as i32, b as i32, fx as i32);
                *d = (((a << 11) + (b - a) * f + (1 << 21)) >> 22) as u8;
            }
        }
        match Image::from_vec(dw, dh, out) {
            Some(img) => img,
            None => unreachable!("resize buffer has dw*dh pixels"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pyr_down_matches_hand_computation() {
        // 1-D along x: [0, 16, 32, 48, 64] on 5x1; reflect101 rows make the vertical pass a no-op.
        let img = Image::from_vec(5, 1, vec![0u8, 16, 32, 48, 64]).unwrap();
        let d = pyr_down(&img);
        assert_eq!((d.width(), d.height()), (3, 1));
        // x=0: taps at -2..2 -> [32,16,0,16,32] -> (32+64+0+64+32)/16 = 12
        // x=1: taps 0..4 -> (0+64+192+192+64)/16 = 32; x=2: taps 2..6 -> [32,48,64,48,32] -> 52
        assert_eq!(d.data(), &[12, 32, 52]);
        let c = Image::filled(7, 6, 200u8);
        assert_eq!(pyr_down(&c), Image::filled(4, 3, 200u8));
    }

    /// The AVX2 build equals the portable one (odd and even sizes).
    #[test]
    fn pyr_down_builds_agree() {
        for (w, h) in [(53, 37), (64, 48), (7, 3)] {
            let img = crate::test_images::hashed(w, h);
            assert_eq!(pyr_down(&img), pyr_down_portable(&img), "{w}x{h}");
        }
    }

    #[test]
    fn pyramid_sizes() {
        let img = Image::filled(640, 480, 1u8);
        let p = Pyramid::new(&img, 3);
        let sizes: Vec<_> = p.levels().iter().map(|l| (l.width(), l.height())).collect();
        assert_eq!(sizes, vec![(640, 480), (320, 240), (160, 120), (80, 60)]);
        let tiny = Pyramid::new(&Image::filled(1, 1, 0u8), 3);
        assert_eq!(tiny.levels().len(), 1);
    }

    /// Bilinear resize by its definition: horizontal blend of each source row, then vertical.
    fn resize_reference(img: &GrayImage, dw: usize, dh: usize) -> Vec<u8> {
        let (xt, yt) = (resize_taps(dw, img.width()), resize_taps(dh, img.height()));
        let at = |x: usize, y: usize| u32::from(*img.get(x, y).unwrap());
        let (wm, hm) = (img.width() - 1, img.height() - 1);
        let mut out = Vec::new();
        for &(y0, fy) in &yt {
            for &(x0, fx) in &xt {
                let hrow = |y| at(x0, y) * (RESIZE_ONE - fx) + at((x0 + 1).min(wm), y) * fx;
                let v = hrow(y0) * (RESIZE_ONE - fy) + hrow((y0 + 1).min(hm)) * fy;
                out.push(((v + (1 << 21)) >> 22) as u8);
            }
        }
        out
    }

    /// Vertical-first blending (portable and AVX2 builds) equals the definition, shrinking and
    /// enlarging, on one-pixel axes too.
    #[test]
    fn resize_matches_the_definition() {
        let img = crate::test_images::hashed(53, 37);
        for (dw, dh) in [(44, 31), (37, 26), (80, 50), (1, 1), (53, 37), (7, 90)] {
            let want = resize_reference(&img, dw, dh);
            assert_eq!(resize_bilinear(&img, dw, dh).data(), want, "{dw}x{dh}");
            assert_eq!(resize_bilinear_portable(&img, dw, dh).data(), want);
        }
        let column = Image::from_vec(1, 5, vec![0u8, 50, 100, 150, 255]).unwrap();
        assert_eq!(
            resize_bilinear(&column, 3, 4).data(),
            resize_reference(&column, 3, 4)
        );
    }

    #[test]
    fn resize_keeps_constants_and_halves_exactly() {
        let c = Image::filled(100, 80, 90u8);
        assert_eq!(resize_bilinear(&c, 83, 67), Image::filled(83, 67, 90u8));
        let img = Image::from_vec(4, 1, vec![0u8, 100, 200, 250]).unwrap();
        // halving samples at 0.5 and 2.5
        assert_eq!(resize_bilinear(&img, 2, 1).data(), &[50, 225]);
    }
}
