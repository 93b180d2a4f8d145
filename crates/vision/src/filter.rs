//! Linear filters on 8-bit images: separable Gaussian blur and 3×3 Sobel / Scharr gradients,
//! with OpenCV's default border (`BORDER_REFLECT_101`) and fixed-point arithmetic.
//!
//! Each filter runs as two 1-D passes over row slices (horizontal into a `u16`/`i16` buffer,
//! then vertical), so the inner loops are straight multiply–adds the compiler vectorises.
//! Gaussian weights follow OpenCV's `getGaussianKernel`; Scharr's 3×3 kernel is
//! `\[3 10 3\]ᵀ·\[-1 0 1\]` (H. Scharr, "Optimale Operatoren in der digitalen Bildverarbeitung",
//! 2000).

use slamkit_core::image::{GrayImage, Image};

use crate::border::{pad_row, reflect101};
use crate::color::image_like;
use crate::error::VisionError;
use crate::simd::dispatch_avx2;

/// Horizontal and vertical derivatives of an image, in the filter's own scale
/// (Sobel: 8× the per-pixel intensity slope, Scharr: 32×).
#[derive(Debug, Clone, PartialEq)]
pub struct Gradients {
    /// d/dx (rightwards).
    pub gx: Image<i16>,
    /// d/dy (downwards).
    pub gy: Image<i16>,
}

/// Gaussian kernel of OpenCV's `getGaussianKernel(ksize, sigma)` (sigma ≤ 0 picks
/// `0.3·((ksize−1)/2 − 1) + 0.8`), normalised to sum 1.
pub fn gaussian_kernel(ksize: usize, sigma: f64) -> Vec<f64> {
    let sigma = if sigma > 0.0 {
        sigma
    } else {
        ((ksize as f64 - 1.0) * 0.5 - 1.0) * 0.3 + 0.8
    };
    let c = (ksize as f64 - 1.0) * 0.5;
    let k: Vec<f64> = (0..ksize)
        .map(|i| {
            let x = i as f64 - c;
            (-(x * x) / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let sum: f64 = k.iter().sum();
    k.into_iter().map(|v| v / sum).collect()
}

/// Kernel size OpenCV picks for 8-bit images when given only sigma: `round(6σ + 1) | 1`.
pub fn gaussian_ksize_for_sigma(sigma: f64) -> usize {
    ((sigma * 6.0 + 1.0).round().max(1.0) as usize) | 1
}

/// Converts a normalised kernel to 8-bit fixed point that sums to exactly 256.
fn fixed_kernel(k: &[f64]) -> Vec<u16> {
    let mut w: Vec<u16> = k.iter().map(|v| (v * 256.0).round() as u16).collect();
    let sum: i32 = w.iter().map(|&v| i32::from(v)).sum();
    let mid = w.len() / 2;
    if let Some(c) = w.get_mut(mid) {
        *c = (i32::from(*c) + 256 - sum).clamp(0, 256) as u16;
    }
    w
}

/// Gaussian blur with an odd `ksize` and standard deviation `sigma` \[px\] (σ ≤ 0: derived
/// from `ksize` as OpenCV does), as `cv::GaussianBlur(src, ksize×ksize, σ, σ)`.
pub fn gaussian_blur(img: &GrayImage, ksize: usize, sigma: f64) -> Result<GrayImage, VisionError> {
    if ksize % 2 == 0 {
        return Err(VisionError::config("ksize", ksize, "must be odd"));
    }
    let k = fixed_kernel(&gaussian_kernel(ksize, sigma));
    Ok(separable_u8(img, &k))
}

dispatch_avx2! {
    /// Convolves with the symmetric kernel `k` along x then y (weights sum to 256 each),
    /// rounding once at the end.
    fn separable_u8(img: &GrayImage, k: &[u16]) -> GrayImage;
    /// [`separable_u8`]'s body. The kernel is symmetric (Gaussian), so each pass adds the two
    /// samples that share a weight before multiplying: `r + 1` products per pixel instead of
    /// `2r + 1`.
    portable separable_u8_portable {
        let (w, h) = (img.width(), img.height());
        if w == 0 || h == 0 || k.is_empty() {
            return img.clone();
        }
        let r = k.len() / 2;
        let (pairs, centre) = (&k[..r], k[r]);
        // Horizontal: Σ kⱼ·p ≤ 256·255 fits u16; the partial sums only grow, so wrapping u16
        // arithmetic is exact.
        let mut tmp = vec![0u16; w * h];
        let mut padded = Vec::with_capacity(w + 2 * r);
        for (src, dst) in img.data().chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
            pad_row(src, r, &mut padded);
            for (d, &p) in dst.iter_mut().zip(&padded[r..r + w]) {
                *d = centre.wrapping_mul(u16::from(p));
            }
            for (j, &wk) in pairs.iter().enumerate() {
                let (left, right) = (&padded[j..j + w], &padded[2 * r - j..2 * r - j + w]);
                for ((d, &a), &b) in dst.iter_mut().zip(left).zip(right) {
                    *d = d.wrapping_add(wk.wrapping_mul(u16::from(a) + u16::from(b)));
                }
            }
        }
        let mut out = vec![0u8; w * h];
        let mut acc = vec![0u32; w];
        let row = |dy: isize, y: usize| {
            let sy = reflect101(y as isize + dy, h);
            &tmp[sy * w..(sy + 1) * w]
        };
        for (y, dst) in out.chunks_exact_mut(w).enumerate() {
            let mid = row(0, y);
            for (a, &v) in acc.iter_mut().zip(mid) {
                *a = (1 << 15) + u32::from(centre) * u32::from(v);
            }
            for (j, &wk) in pairs.iter().enumerate() {
                let (up, dn) = (row(j as isize - r as isize, y), row((r - j) as isize, y));
                for ((a, &u), &d) in acc.iter_mut().zip(up).zip(dn) {
                    *a += u32::from(wk) * (u32::from(u) + u32::from(d));
                }
            }
            for (d, &a) in dst.iter_mut().zip(&acc) {
                *d = (a >> 16) as u8;
            }
        }
        image_like(img, out)
    }
}

/// 3×3 Sobel derivatives (`cv::Sobel(src, CV_16S, 1, 0, 3)` and `(0, 1)`).
pub fn sobel(img: &GrayImage) -> Gradients {
    gradients_3x3(img, [1, 2])
}

/// 3×3 Scharr derivatives (`cv::Scharr(src, CV_16S, 1, 0)` and `(0, 1)`).
pub fn scharr(img: &GrayImage) -> Gradients {
    gradients_3x3(img, [3, 10])
}

dispatch_avx2! {
    /// Derivative `\[-1 0 1\]` along one axis, smoothing `\[s0 s1 s0\]` along the other.
    fn gradients_3x3(img: &GrayImage, s: [i16; 2]) -> Gradients;
    portable gradients_3x3_portable {
        let [s0, s1] = s;
        let (w, h) = (img.width(), img.height());
        let mut gx = vec![0i16; w * h];
        let mut gy = vec![0i16; w * h];
        if w > 0 && h > 0 {
            let pw = w + 2;
            let mut padded = vec![0i16; pw * h];
            let mut buf = Vec::with_capacity(pw);
            for (src, dst) in img.data().chunks_exact(w).zip(padded.chunks_exact_mut(pw)) {
                pad_row(src, 1, &mut buf);
                for (d, &p) in dst.iter_mut().zip(&buf) {
                    *d = i16::from(p);
                }
            }
            let mut vs = vec![0i16; pw];
            let mut vd = vec![0i16; pw];
            let rows = gx.chunks_exact_mut(w).zip(gy.chunks_exact_mut(w));
            for (y, (ox, oy)) in rows.enumerate() {
                let up = reflect101(y as isize - 1, h);
                let dn = reflect101(y as isize + 1, h);
                let (ru, rm, rd) = (
                    &padded[up * pw..(up + 1) * pw],
                    &padded[y * pw..(y + 1) * pw],
                    &padded[dn * pw..(dn + 1) * pw],
                );
                for (((s, d), (&u, &m)), &b) in vs
                    .iter_mut()
                    .zip(vd.iter_mut())
                    .zip(ru.iter().zip(rm))
                    .zip(rd)
                {
                    *s = s0 * (u + b) + s1 * m;
                    *d = b - u;
                }
                for (o, win) in ox.iter_mut().zip(vs.windows(3)) {
                    *o = win[2] - win[0];
                }
                for (o, win) in oy.iter_mut().zip(vd.windows(3)) {
                    *o = s0 * (win[0] + win[2]) + s1 * win[1];
                }
            }
        }
        Gradients {
            gx: image_like(img, gx),
            gy: image_like(img, gy),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize) -> GrayImage {
        Image::from_vec(
            w,
            h,
            (0..w * h)
                .map(|i| ((i % w) * 3 + (i / w) * 5) as u8)
                .collect(),
        )
        .unwrap()
    }

    #[test]
    fn gaussian_kernel_matches_opencv() {
        // cv2.getGaussianKernel(5, 1.0).ravel()
        let k = gaussian_kernel(5, 1.0);
        let want = [0.05448868, 0.24420134, 0.40261995, 0.24420134, 0.05448868];
        for (a, b) in k.iter().zip(want) {
            assert!((a - b).abs() < 1e-7, "{k:?}");
        }
        assert_eq!(gaussian_ksize_for_sigma(2.0), 13);
        assert_eq!(
            fixed_kernel(&k).iter().map(|&v| u32::from(v)).sum::<u32>(),
            256
        );
    }

    /// 2-D convolution with the outer product of the fixed-point kernel, pixel by pixel.
    fn blur_reference(img: &GrayImage, k: &[u16]) -> Vec<u8> {
        let (w, h) = (img.width(), img.height());
        let r = (k.len() / 2) as isize;
        let mut out = Vec::new();
        for y in 0..h as isize {
            for x in 0..w as isize {
                let mut acc = 1u64 << 15;
                for (i, &ky) in k.iter().enumerate() {
                    for (j, &kx) in k.iter().enumerate() {
                        let sy = reflect101(y + i as isize - r, h);
                        let sx = reflect101(x + j as isize - r, w);
                        let p = u64::from(*img.get(sx, sy).unwrap());
                        acc += u64::from(ky) * u64::from(kx) * p;
                    }
                }
                out.push((acc >> 16) as u8);
            }
        }
        out
    }

    /// The symmetric two-pass blur (portable and AVX2 builds) equals the 2-D definition, and
    /// the fixed-point Gaussian kernels are symmetric, as the two passes assume.
    #[test]
    fn blur_matches_the_definition() {
        let img = crate::test_images::hashed(41, 29);
        for (ksize, sigma) in [(1, 0.0), (3, 0.8), (5, 1.0), (7, 2.0), (9, 3.0), (13, 2.0)] {
            let k = fixed_kernel(&gaussian_kernel(ksize, sigma));
            assert!(k.iter().eq(k.iter().rev()), "{k:?}");
            let want = blur_reference(&img, &k);
            assert_eq!(gaussian_blur(&img, ksize, sigma).unwrap().data(), want);
            assert_eq!(separable_u8_portable(&img, &k).data(), want, "{ksize}");
        }
        let white = Image::filled(10, 3, 255u8);
        assert_eq!(gaussian_blur(&white, 7, 2.0).unwrap(), white);
    }

    #[test]
    fn blur_keeps_constant_and_linear_images() {
        let c = Image::filled(9, 7, 77u8);
        assert_eq!(gaussian_blur(&c, 7, 2.0).unwrap(), c);
        let r = ramp(20, 20);
        let b = gaussian_blur(&r, 5, 1.0).unwrap();
        // A linear ramp is unchanged away from the borders (symmetric kernel).
        for y in 3..17 {
            for x in 3..17 {
                assert_eq!(b.get(x, y), r.get(x, y), "at {x},{y}");
            }
        }
        assert!(gaussian_blur(&r, 4, 1.0).is_err());
    }

    #[test]
    fn gradients_of_a_ramp() {
        let r = ramp(10, 8);
        let s = sobel(&r);
        let c = scharr(&r);
        // interior: dI/dx = 3, dI/dy = 5; Sobel gain 8, Scharr gain 32
        assert_eq!(s.gx.get(4, 4), Some(&24));
        assert_eq!(s.gy.get(4, 4), Some(&40));
        assert_eq!(c.gx.get(4, 4), Some(&96));
        assert_eq!(c.gy.get(4, 4), Some(&160));
        // reflect-101 border: derivative across the edge is zero
        assert_eq!(s.gx.get(0, 4), Some(&0));
        assert_eq!(s.gy.get(4, 0), Some(&0));
    }

    /// The AVX2 build of the 3×3 gradients equals the portable one.
    #[test]
    fn gradient_builds_agree() {
        let img = crate::test_images::hashed(37, 23);
        assert_eq!(sobel(&img), gradients_3x3_portable(&img, [1, 2]));
        assert_eq!(scharr(&img), gradients_3x3_portable(&img, [3, 10]));
    }

    #[test]
    fn empty_images_are_fine() {
        let e: GrayImage = Image::from_vec(0, 0, vec![]).unwrap();
        assert_eq!(gaussian_blur(&e, 3, 0.0).unwrap().data().len(), 0);
        assert_eq!(sobel(&e).gx.data().len(), 0);
    }
}
