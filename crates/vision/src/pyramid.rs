//! Image pyramids: OpenCV's `pyrDown` (5-tap binomial `\[1 4 6 4 1\]/16` per axis, then drop every
//! other row and column; P. Burt and E. Adelson, "The Laplacian pyramid as a compact image
//! code", 1983) for KLT, and a bilinear resize (OpenCV `INTER_LINEAR` pixel-centre convention)
//! for ORB's non-dyadic scale pyramid.

use slamkit_core::image::{GrayImage, Image};

use crate::border::{pad_row, reflect101};

/// Halves an image as `cv::pyrDown`: output `⌈w/2⌉ × ⌈h/2⌉`, reflect-101 border, rounded.
pub fn pyr_down(img: &GrayImage) -> GrayImage {
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
            *d = u16::from(a) + u16::from(f) + 4 * (u16::from(b) + u16::from(e)) + 6 * u16::from(c);
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

/// Bilinear resize to `dw × dh` with OpenCV's `INTER_LINEAR` sample positions
/// (`(x + 0.5)·w/dw − 0.5`, clamped to the image) and 11-bit fixed-point weights.
pub fn resize_bilinear(img: &GrayImage, dw: usize, dh: usize) -> GrayImage {
    let (w, h) = (img.width(), img.height());
    if w == 0 || h == 0 || dw == 0 || dh == 0 {
        return Image::filled(dw, dh, 0);
    }
    const ONE: u32 = 1 << 11;
    let taps = |n_out: usize, n_in: usize| -> Vec<(usize, u32)> {
        let scale = n_in as f64 / n_out as f64;
        (0..n_out)
            .map(|i| {
                let s = ((i as f64 + 0.5) * scale - 0.5).max(0.0);
                let i0 = (s.floor() as usize).min(n_in - 1);
                let f = if i0 + 1 >= n_in { 0.0 } else { s - i0 as f64 };
                (i0, (f * f64::from(ONE)).round() as u32)
            })
            .collect()
    };
    let xt = taps(dw, w);
    let yt = taps(dh, h);
    let data = img.data();
    let mut h0 = vec![0u32; dw];
    let mut h1 = vec![0u32; dw];
    let mut out = vec![0u8; dw * dh];
    let hrow = |sy: usize, dst: &mut [u32]| {
        let row = &data[sy * w..(sy + 1) * w];
        for (d, &(x0, fx)) in dst.iter_mut().zip(&xt) {
            let a = u32::from(row[x0]);
            let b = u32::from(*row.get(x0 + 1).unwrap_or(&row[x0]));
            *d = a * (ONE - fx) + b * fx;
        }
    };
    for (dst, &(y0, fy)) in out.chunks_exact_mut(dw).zip(&yt) {
        hrow(y0, &mut h0);
        hrow((y0 + 1).min(h - 1), &mut h1);
        for ((d, &a), &b) in dst.iter_mut().zip(&h0).zip(&h1) {
            *d = ((a * (ONE - fy) + b * fy + (1 << 21)) >> 22) as u8;
        }
    }
    match Image::from_vec(dw, dh, out) {
        Some(img) => img,
        None => unreachable!("resize buffer has dw*dh pixels"),
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

    #[test]
    fn pyramid_sizes() {
        let img = Image::filled(640, 480, 1u8);
        let p = Pyramid::new(&img, 3);
        let sizes: Vec<_> = p.levels().iter().map(|l| (l.width(), l.height())).collect();
        assert_eq!(sizes, vec![(640, 480), (320, 240), (160, 120), (80, 60)]);
        let tiny = Pyramid::new(&Image::filled(1, 1, 0u8), 3);
        assert_eq!(tiny.levels().len(), 1);
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
