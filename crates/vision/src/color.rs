//! Colour conversions, bit-exact with OpenCV's 8-bit paths so that CLAHE on colour images gives
//! OpenCV's results:
//!
//! * RGB → grey: ITU-R BT.601 luma, `Y = 0.299 R + 0.587 G + 0.114 B`, in OpenCV's 14-bit fixed
//!   point (`cvtColor(..., COLOR_RGB2GRAY)`).
//! * RGB ↔ CIE L\*a\*b\* (D65, sRGB gamma), 8-bit encoding `L·255/100, a + 128, b + 128`, using
//!   the same integer tables as OpenCV's `RGB2Lab_b` and `Lab2RGBinteger`
//!   (`modules/imgproc/src/color_lab.cpp`). The matrices are the sRGB/D65 ones of
//!   IEC 61966-2-1; the cube root and gamma curves are tabulated once.

use std::sync::OnceLock;

use slamkit_core::image::{GrayImage, Image, RgbImage};

use crate::simd::dispatch_avx2;

/// An 8-bit L\*a\*b\* image: `[L·255/100, a + 128, b + 128]` per pixel, as OpenCV stores it.
pub type LabImage = Image<[u8; 3]>;

/// Fixed-point BT.601 weights of OpenCV (`yuv_shift = 14`): R, G, B.
const GRAY_WEIGHTS: [u32; 3] = [4899, 9617, 1868];

dispatch_avx2! {
    /// Converts RGB to 8-bit grey with BT.601 weights, rounding like OpenCV.
    pub fn rgb_to_gray(rgb: &RgbImage) -> GrayImage;
    /// [`rgb_to_gray`]'s body: 16-bit operands and exact 32-bit sums, which vectorise as
    /// multiply–adds of 16-bit pairs.
    portable rgb_to_gray_portable {
        let [wr, wg, wb] = GRAY_WEIGHTS.map(|w| w as i16);
        let mut data = vec![0u8; rgb.data().len()];
        for (d, &[r, g, b]) in data.iter_mut().zip(rgb.data()) {
            let y = i32::from(r as i16) * i32::from(wr)
                + i32::from(g as i16) * i32::from(wg)
                + i32::from(b as i16) * i32::from(wb);
            *d = ((y + (1 << 13)) >> 14) as u8;
        }
        image_like(rgb, data)
    }
}

/// Builds an image of the same size as `like` from a buffer of exactly `width * height` pixels.
pub(crate) fn image_like<A, B>(like: &Image<A>, data: Vec<B>) -> Image<B> {
    let (w, h) = (like.width(), like.height());
    match Image::from_vec(w, h, data) {
        Some(img) => img,
        // Callers build `data` pixel for pixel from `like`, so the sizes always agree.
        None => unreachable!("buffer size differs from {w}x{h}"),
    }
}

const LAB_SHIFT: i32 = 12;
const GAMMA_SHIFT: i32 = 3;
const LAB_SHIFT2: i32 = LAB_SHIFT + GAMMA_SHIFT;
const CBRT_TAB_SIZE: usize = 256 * 3 / 2 * (1 << GAMMA_SHIFT);
const INV_GAMMA_TAB_SIZE: usize = 1 << 12;
const LUT_BASE: i32 = 1 << 14;
const MIN_AB: i32 = -8145;
const AB_TAB_SIZE: usize = (LUT_BASE as usize) * 9 / 4;

/// sRGB → XYZ (D65), rows X, Y, Z; columns R, G, B.
const RGB_TO_XYZ: [[f64; 3]; 3] = [
    [0.412453, 0.357580, 0.180423],
    [0.212671, 0.715160, 0.072169],
    [0.019334, 0.119193, 0.950227],
];
/// XYZ → sRGB (D65), rows R, G, B; columns X, Y, Z.
const XYZ_TO_RGB: [[f64; 3]; 3] = [
    [3.240479, -1.53715, -0.498535],
    [-0.969256, 1.875991, 0.041556],
    [0.055648, -0.204043, 1.057311],
];
const D65_WHITE: [f64; 3] = [0.950456, 1.0, 1.088754];

/// Integer tables of the 8-bit Lab conversions, built once.
struct LabTables {
    /// sRGB gamma expansion of each 8-bit value, scaled by `255·2^GAMMA_SHIFT`.
    gamma: [i32; 256],
    /// `f(t)` of CIE Lab (cube root with the linear toe), scaled by `2^LAB_SHIFT2`.
    cbrt: Vec<i32>,
    /// RGB → XYZ/white in `2^LAB_SHIFT` fixed point, rows X, Y, Z.
    to_xyz: [[i32; 3]; 3],
    /// sRGB gamma compression of a `2^12`-step linear value, to 8 bits.
    inv_gamma: Vec<u8>,
    /// Per 8-bit L: (Y, f(Y)) in `LUT_BASE` fixed point.
    l_to_yf: [(i32, i32); 256],
    /// f⁻¹ for the a/b axes, indexed from `MIN_AB`.
    ab_to_xz: Vec<i32>,
    /// XYZ·white → RGB in `2^LAB_SHIFT` fixed point, rows R, G, B.
    to_rgb: [[i64; 3]; 3],
}

/// Rounds half to even, as OpenCV's `cvRound`.
fn round_even(x: f64) -> i32 {
    let r = x.round();
    let r = if (x - x.trunc()).abs() == 0.5 && r % 2.0 != 0.0 {
        r - x.signum()
    } else {
        r
    };
    r as i32
}

fn apply_gamma(x: f32) -> f32 {
    let x = f64::from(x);
    (if x <= 0.04045 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }) as f32
}

fn apply_inv_gamma(x: f32) -> f32 {
    let x = f64::from(x);
    (if x <= 0.0031308 {
        x * 12.92
    } else {
        x.powf(1.0 / 2.4) * 1.055 - 0.055
    }) as f32
}

impl LabTables {
    fn get() -> &'static Self {
        static TABLES: OnceLock<LabTables> = OnceLock::new();
        TABLES.get_or_init(Self::build)
    }

    fn build() -> Self {
        let mut gamma = [0i32; 256];
        for (i, g) in gamma.iter_mut().enumerate() {
            let x = i as f32 / 255.0;
            *g = round_even(f64::from(2040.0f32 * apply_gamma(x)));
        }
        let lthresh = 216.0f32 / 24389.0;
        let lscale = 841.0f32 / 108.0;
        let lbias = 16.0f32 / 116.0;
        let cb_scale = 1.0f32 / 2040.0;
        let mut cbrt = (0..CBRT_TAB_SIZE)
            .map(|i| {
                let x = cb_scale * i as f32;
                let f = if x < lthresh {
                    x.mul_add(lscale, lbias)
                } else {
                    (f64::from(x).cbrt()) as f32
                };
                round_even(f64::from(32768.0f32 * f))
            })
            .collect::<Vec<i32>>();
        // Entry 324 is an exact tie (17745.5) in f32; OpenCV's soft-float cube root lands just
        // below it. Checked against cv2 on all 2^24 colours (scripts/clahe_reference.py).
        if let Some(e) = cbrt.get_mut(324) {
            *e = 17745;
        }
        let mut to_xyz = [[0i32; 3]; 3];
        for (row, (m, w)) in to_xyz.iter_mut().zip(RGB_TO_XYZ.iter().zip(D65_WHITE)) {
            for (c, &v) in row.iter_mut().zip(m) {
                *c = round_even(4096.0 * v / w);
            }
        }
        let inv_gamma = (0..INV_GAMMA_TAB_SIZE)
            .map(|i| {
                let x = (1.0f32 / INV_GAMMA_TAB_SIZE as f32) * i as f32;
                round_even(f64::from(255.0f32 * apply_inv_gamma(x))).clamp(0, 255) as u8
            })
            .collect();
        let mut to_rgb = [[0i64; 3]; 3];
        for (row, m) in to_rgb.iter_mut().zip(XYZ_TO_RGB) {
            for ((c, v), w) in row.iter_mut().zip(m).zip(D65_WHITE) {
                *c = i64::from(round_even(4096.0 * v * w));
            }
        }
        Self {
            gamma,
            cbrt,
            to_xyz,
            inv_gamma,
            l_to_yf: Self::l_table(),
            ab_to_xz: Self::ab_table(),
            to_rgb,
        }
    }

    fn l_table() -> [(i32, i32); 256] {
        let base = LUT_BASE as f32;
        let mut t = [(0, 0); 256];
        for (i, e) in t.iter_mut().enumerate() {
            let fi = i as i32;
            *e = if i <= 20 {
                let y = (fi * LUT_BASE * 20 * 9) as f32 / (17 * 29 * 29 * 29) as f32;
                let ify = base * (16.0f32 / 116.0 + (fi * 5) as f32 / (3 * 17 * 29) as f32);
                (round_even(f64::from(y)), round_even(f64::from(ify)))
            } else {
                let fy = (fi * 100 * LUT_BASE) as f32 / (255 * 116) as f32
                    + (16 * LUT_BASE) as f32 / 116.0;
                let y = fy * fy * fy / (LUT_BASE as f32 * LUT_BASE as f32);
                (round_even(f64::from(y)), round_even(f64::from(fy)))
            };
        }
        t
    }

    fn ab_table() -> Vec<i32> {
        (MIN_AB..MIN_AB + AB_TAB_SIZE as i32)
            .map(|i| {
                let i = i64::from(i);
                let base = i64::from(LUT_BASE);
                let v = if i <= 3390 {
                    i * 108 / 841 - base * 16 / 116 * 108 / 841
                } else {
                    i * i / base * i / base
                };
                v as i32
            })
            .collect()
    }

    /// RGB → 8-bit L, a, b of up to [`CHUNK`] pixels (OpenCV's `RGB2Lab_b`). Each table stage
    /// is a loop of scalar look-ups, each arithmetic stage a loop over all lanes (vectorised).
    #[inline(always)]
    fn rgb_to_lab_chunk(&self, rgb: &[[u8; 3]], out: &mut [[u8; CHUNK]; 3]) {
        let mut lin = [[0i32; CHUNK]; 3];
        for (i, &[r, g, b]) in rgb.iter().take(CHUNK).enumerate() {
            lin[0][i] = self.gamma[usize::from(r)];
            lin[1][i] = self.gamma[usize::from(g)];
            lin[2][i] = self.gamma[usize::from(b)];
        }
        // X, Y, Z / white → index into the cube-root table → f(X), f(Y), f(Z)
        let mut f = [[0i32; CHUNK]; 3];
        for (fk, c) in f.iter_mut().zip(&self.to_xyz) {
            let mut idx = [0i32; CHUNK];
            for (i, o) in idx.iter_mut().enumerate() {
                let v = lin[0][i] * c[0] + lin[1][i] * c[1] + lin[2][i] * c[2];
                *o = ((v + (1 << (LAB_SHIFT - 1))) >> LAB_SHIFT).clamp(0, CBRT_TAB_SIZE as i32 - 1);
            }
            for (o, &i) in fk.iter_mut().zip(&idx).take(rgb.len()) {
                *o = self.cbrt.get(i as usize).copied().unwrap_or(0);
            }
        }
        const L_SCALE: i32 = (116 * 255 + 50) / 100;
        const L_SHIFT: i32 = -((16 * 255 * (1 << LAB_SHIFT2) + 50) / 100);
        const HALF: i32 = 1 << (LAB_SHIFT2 - 1);
        const AB_BIAS: i32 = 128 * (1 << LAB_SHIFT2) + HALF;
        let [ol, oa, ob] = out;
        for i in 0..CHUNK {
            let (fx, fy, fz) = (f[0][i], f[1][i], f[2][i]);
            ol[i] = sat_u8((L_SCALE * fy + L_SHIFT + HALF) >> LAB_SHIFT2);
            oa[i] = sat_u8((500 * (fx - fy) + AB_BIAS) >> LAB_SHIFT2);
            ob[i] = sat_u8((200 * (fy - fz) + AB_BIAS) >> LAB_SHIFT2);
        }
    }

    /// 8-bit L, (a, b) → RGB of up to [`CHUNK`] pixels (OpenCV's `Lab2RGBinteger`), in stages
    /// as [`LabTables::rgb_to_lab_chunk`].
    #[inline(always)]
    fn lab_to_rgb_chunk(&self, l: &[u8], ab: &[[u8; 2]], out: &mut [[u8; 3]]) {
        let n = l.len().min(ab.len()).min(out.len()).min(CHUNK);
        let (mut y, mut ify) = ([0i32; CHUNK], [0i32; CHUNK]);
        let (mut a, mut b) = ([0i32; CHUNK], [0i32; CHUNK]);
        for i in 0..n {
            (y[i], ify[i]) = self.l_to_yf[usize::from(l[i])];
            let [pa, pb] = ab[i];
            (a[i], b[i]) = (i32::from(pa), i32::from(pb));
        }
        // indices of f⁻¹ for the X and Z axes
        let (mut ix, mut iz) = ([0i32; CHUNK], [0i32; CHUNK]);
        let last = AB_TAB_SIZE as i32 - 1;
        for i in 0..CHUNK {
            let adiv = ((5 * a[i] * 53687 + (1 << 7)) >> 13) - 128 * LUT_BASE / 500;
            let bdiv = ((b[i] * 41943 + (1 << 4)) >> 9) - 128 * LUT_BASE / 200 + 1;
            ix[i] = (ify[i] + adiv - MIN_AB).clamp(0, last);
            iz[i] = (ify[i] - bdiv - MIN_AB).clamp(0, last);
        }
        let (mut x, mut z) = ([0i32; CHUNK], [0i32; CHUNK]);
        for i in 0..n {
            x[i] = self.ab_to_xz.get(ix[i] as usize).copied().unwrap_or(0);
            z[i] = self.ab_to_xz.get(iz[i] as usize).copied().unwrap_or(0);
        }
        const SHIFT: i64 = 14;
        for (k, c) in self.to_rgb.iter().enumerate() {
            let mut idx = [0i32; CHUNK];
            for (i, o) in idx.iter_mut().enumerate() {
                let (xi, yi, zi) = (i64::from(x[i]), i64::from(y[i]), i64::from(z[i]));
                let v = (c[0] * xi + c[1] * yi + c[2] * zi + (1 << (SHIFT - 1))) >> SHIFT;
                *o = v.clamp(0, INV_GAMMA_TAB_SIZE as i64 - 1) as i32;
            }
            for (o, &i) in out.iter_mut().zip(&idx).take(n) {
                o[k] = self.inv_gamma.get(i as usize).copied().unwrap_or(0);
            }
        }
    }
}

#[inline]
fn sat_u8(v: i32) -> u8 {
    v.clamp(0, 255) as u8
}

/// Pixels converted per stage of the Lab conversions (their working set stays in L1).
const CHUNK: usize = 64;

/// Converts 8-bit sRGB to 8-bit L\*a\*b\* exactly as OpenCV's `COLOR_RGB2Lab`.
pub fn rgb_to_lab(rgb: &RgbImage) -> LabImage {
    let (l, ab) = rgb_to_lab_planes(rgb);
    let data = l
        .data()
        .iter()
        .zip(ab.data())
        .map(|(&l, &[a, b])| [l, a, b])
        .collect();
    image_like(rgb, data)
}

/// Converts 8-bit L\*a\*b\* back to sRGB exactly as OpenCV's `COLOR_Lab2RGB`.
pub fn lab_to_rgb(lab: &LabImage) -> RgbImage {
    let l = image_like(lab, lab.data().iter().map(|p| p[0]).collect());
    let ab = image_like(lab, lab.data().iter().map(|p| [p[1], p[2]]).collect());
    match lab_planes_to_rgb(&l, &ab) {
        Some(rgb) => rgb,
        None => unreachable!("planes of one image have its size"),
    }
}

dispatch_avx2! {
    /// Splits RGB into the 8-bit L channel and the (a, b) pair per pixel, for methods (CLAHE)
    /// that work on lightness only.
    pub fn rgb_to_lab_planes(rgb: &RgbImage) -> (GrayImage, Image<[u8; 2]>);
    portable rgb_to_lab_planes_portable {
        let t = LabTables::get();
        let n = rgb.data().len();
        let (mut l, mut ab) = (vec![0u8; n], vec![[0u8; 2]; n]);
        let mut lab = [[0u8; CHUNK]; 3];
        let chunks = rgb.data().chunks(CHUNK).zip(l.chunks_mut(CHUNK));
        for ((src, l), ab) in chunks.zip(ab.chunks_mut(CHUNK)) {
            t.rgb_to_lab_chunk(src, &mut lab);
            l.copy_from_slice(&lab[0][..l.len()]);
            for ((o, &a), &b) in ab.iter_mut().zip(&lab[1]).zip(&lab[2]) {
                *o = [a, b];
            }
        }
        (image_like(rgb, l), image_like(rgb, ab))
    }
}

dispatch_avx2! {
    /// Inverse of [`rgb_to_lab_planes`]; `l` and `ab` must have the same size (else `None`).
    pub fn lab_planes_to_rgb(l: &GrayImage, ab: &Image<[u8; 2]>) -> Option<RgbImage>;
    portable lab_planes_to_rgb_portable {
        if l.width() != ab.width() || l.height() != ab.height() {
            return None;
        }
        let t = LabTables::get();
        let mut data = vec![[0u8; 3]; l.data().len()];
        let chunks = l.data().chunks(CHUNK).zip(ab.data().chunks(CHUNK));
        for ((l, ab), out) in chunks.zip(data.chunks_mut(CHUNK)) {
            t.lab_to_rgb_chunk(l, ab, out);
        }
        Some(image_like(l, data))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// OpenCV's `RGB2Lab_b` one pixel at a time: the reference for the staged conversion.
    fn rgb_to_lab_pixel(t: &LabTables, [r, g, b]: [u8; 3]) -> [u8; 3] {
        let (r, g, b) = (
            t.gamma[r as usize],
            t.gamma[g as usize],
            t.gamma[b as usize],
        );
        let cbrt_at = |v: i32| {
            let idx = (v + (1 << (LAB_SHIFT - 1))) >> LAB_SHIFT;
            t.cbrt[idx.clamp(0, CBRT_TAB_SIZE as i32 - 1) as usize]
        };
        let [cx, cy, cz] = t.to_xyz;
        let fx = cbrt_at(r * cx[0] + g * cx[1] + b * cx[2]);
        let fy = cbrt_at(r * cy[0] + g * cy[1] + b * cy[2]);
        let fz = cbrt_at(r * cz[0] + g * cz[1] + b * cz[2]);
        let half = 1 << (LAB_SHIFT2 - 1);
        let l = ((116 * 255 + 50) / 100 * fy - (16 * 255 * (1 << LAB_SHIFT2) + 50) / 100 + half)
            >> LAB_SHIFT2;
        let a = (500 * (fx - fy) + 128 * (1 << LAB_SHIFT2) + half) >> LAB_SHIFT2;
        let bb = (200 * (fy - fz) + 128 * (1 << LAB_SHIFT2) + half) >> LAB_SHIFT2;
        [sat_u8(l), sat_u8(a), sat_u8(bb)]
    }

    /// OpenCV's `Lab2RGBinteger` one pixel at a time.
    fn lab_to_rgb_pixel(t: &LabTables, [l, a, b]: [u8; 3]) -> [u8; 3] {
        let (y, ify) = t.l_to_yf[l as usize];
        let adiv = ((5 * i32::from(a) * 53687 + (1 << 7)) >> 13) - 128 * LUT_BASE / 500;
        let bdiv = ((i32::from(b) * 41943 + (1 << 4)) >> 9) - 128 * LUT_BASE / 200 + 1;
        let ab_at =
            |i: i32| i64::from(t.ab_to_xz[(i - MIN_AB).clamp(0, AB_TAB_SIZE as i32 - 1) as usize]);
        let (x, z, y) = (ab_at(ify + adiv), ab_at(ify - bdiv), i64::from(y));
        t.to_rgb.map(|c| {
            let v = (c[0] * x + c[1] * y + c[2] * z + (1 << 13)) >> 14;
            t.inv_gamma[v.clamp(0, INV_GAMMA_TAB_SIZE as i64 - 1) as usize]
        })
    }

    /// The staged conversions (portable and AVX2 builds) equal the per-pixel ones on every
    /// third level of each channel, both ways, on lengths that are not whole chunks.
    #[test]
    fn staged_lab_matches_per_pixel() {
        let t = LabTables::get();
        let levels = || (0..=255u8).step_by(3).chain([255]);
        let px: Vec<[u8; 3]> = levels()
            .flat_map(|r| levels().flat_map(move |g| levels().map(move |b| [r, g, b])))
            .collect();
        let n = px.len();
        let img = Image::from_vec(n, 1, px).unwrap();
        let want: Vec<[u8; 3]> = img.data().iter().map(|&p| rgb_to_lab_pixel(t, p)).collect();
        assert_eq!(rgb_to_lab(&img).data(), want);
        let (l, ab) = rgb_to_lab_planes_portable(&img);
        let lab: Vec<[u8; 3]> = l
            .data()
            .iter()
            .zip(ab.data())
            .map(|(&l, &[a, b])| [l, a, b])
            .collect();
        assert_eq!(lab, want);
        // Lab → RGB on Lab triples spread over the whole cube
        let lab = img.clone();
        let want: Vec<[u8; 3]> = lab.data().iter().map(|&p| lab_to_rgb_pixel(t, p)).collect();
        assert_eq!(lab_to_rgb(&lab).data(), want);
        let l = image_like(&lab, lab.data().iter().map(|p| p[0]).collect());
        let ab = image_like(&lab, lab.data().iter().map(|p| [p[1], p[2]]).collect());
        assert_eq!(lab_planes_to_rgb_portable(&l, &ab).unwrap().data(), want);
        assert!(lab_planes_to_rgb(&l, &Image::filled(1, 1, [0u8; 2])).is_none());
    }

    fn rgb(pixels: Vec<[u8; 3]>) -> RgbImage {
        let n = pixels.len();
        Image::from_vec(n, 1, pixels).unwrap()
    }

    /// The AVX2 build equals the portable one and the weighted sum, on every grey level.
    #[test]
    fn gray_builds_agree() {
        let img = rgb((0..3000u32)
            .map(|i| {
                let h = i.wrapping_mul(2_654_435_761);
                [h as u8, (h >> 8) as u8, (h >> 16) as u8]
            })
            .collect());
        let want: Vec<u8> = img
            .data()
            .iter()
            .map(|&[r, g, b]| {
                let y = 4899 * u32::from(r) + 9617 * u32::from(g) + 1868 * u32::from(b);
                ((y + 8192) >> 14) as u8
            })
            .collect();
        assert_eq!(rgb_to_gray(&img).data(), want);
        assert_eq!(rgb_to_gray_portable(&img).data(), want);
    }

    #[test]
    fn gray_uses_bt601_weights() {
        let img = rgb(vec![
            [255, 0, 0],
            [0, 255, 0],
            [0, 0, 255],
            [255, 255, 255],
            [10, 20, 30],
        ]);
        let g = rgb_to_gray(&img);
        // 0.299*255 = 76.2, 0.587*255 = 149.7, 0.114*255 = 29.1
        assert_eq!(g.data(), &[76, 150, 29, 255, 18]);
    }

    #[test]
    fn lab_of_known_colours_matches_opencv() {
        // cv2.cvtColor(np.uint8([[[255,255,255],[0,0,0],[255,0,0],[0,255,0],[0,0,255]]]), cv2.COLOR_RGB2Lab)
        let img = rgb(vec![
            [255, 255, 255],
            [0, 0, 0],
            [255, 0, 0],
            [0, 255, 0],
            [0, 0, 255],
        ]);
        let lab = rgb_to_lab(&img);
        assert_eq!(
            lab.data(),
            &[
                [255, 128, 128],
                [0, 128, 128],
                [136, 208, 195],
                [224, 42, 211],
                [82, 207, 20]
            ]
        );
    }

    #[test]
    fn lab_roundtrip_is_close() {
        let mut px = Vec::new();
        for r in (0..=255).step_by(15) {
            for g in (0..=255).step_by(15) {
                for b in (0..=255).step_by(15) {
                    px.push([r as u8, g as u8, b as u8]);
                }
            }
        }
        let img = rgb(px);
        let back = lab_to_rgb(&rgb_to_lab(&img));
        let worst = img
            .data()
            .iter()
            .zip(back.data())
            .flat_map(|(a, b)| (0..3).map(move |c| (i32::from(a[c]) - i32::from(b[c])).abs()))
            .max()
            .unwrap();
        // 8-bit Lab quantises a and b coarsely: OpenCV's own roundtrip is off by up to 27 levels
        // on saturated colours.
        assert!(worst <= 27, "worst roundtrip error {worst}");
        let (l, ab) = rgb_to_lab_planes(&img);
        assert_eq!(lab_planes_to_rgb(&l, &ab).unwrap(), back);
    }
}
