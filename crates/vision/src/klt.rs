//! Pyramidal Lucas–Kanade feature tracking in Bouguet's formulation (J.-Y. Bouguet, "Pyramidal
//! implementation of the Lucas Kanade feature tracker", Intel, 2001), as OpenCV's
//! `calcOpticalFlowPyrLK`: from the coarsest level to the finest, each level refines the
//! displacement by Gauss–Newton steps `δ = G⁻¹ b` with `G = Σ ∇I ∇Iᵀ` over a window of the
//! previous image and `b = Σ (I − J) ∇I`, sampling both images bilinearly at sub-pixel
//! positions; the result, doubled, seeds the next finer level.
//!
//! A forward–backward check (Z. Kalal, K. Mikolajczyk and J. Matas, "Forward-backward error",
//! ICPR 2010) tracks every result back to the first image and rejects points that do not land
//! within a threshold of where they started.
//!
//! The window arithmetic is OpenCV's fixed point: bilinear weights in 14 bits, the template and
//! the next image interpolated to `i16` with 5 fractional bits (×32, the scale of the raw Scharr
//! gradients, also kept in `i16`), and the sums `G` and `b` as exact integer dot products of
//! `i16` lanes, which SSE2 computes eight at a time (`pmaddwd`). Points are visited top to bottom
//! so that neighbouring windows find their image rows in cache.

use serde::{Deserialize, Serialize};
use slamkit_core::image::{GrayImage, Image};

use crate::error::VisionError;
use crate::filter::scharr;
use crate::pyramid::Pyramid;
use crate::round::round_ties_even;
use crate::simd::dispatch_avx2;

/// KLT parameters (OpenCV defaults where OpenCV has them).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct KltConfig {
    /// Side of the square integration window \[px\], odd (OpenCV `winSize` 21).
    pub window_px: usize,
    /// Coarsest pyramid level, 0 = no pyramid (OpenCV `maxLevel` 3: four levels in all).
    pub max_level: usize,
    /// Gauss–Newton iterations per level at most (OpenCV criteria count 30).
    pub max_iterations: usize,
    /// Stop when an update is shorter than this \[px\] (OpenCV criteria epsilon 0.01).
    pub epsilon_px: f32,
    /// Lose points whose window's smaller mean structure-tensor eigenvalue is below this
    /// \[(grey level/px)²\]. OpenCV's `minEigThreshold` 1e-4 is this value / 1024.
    pub min_eigenvalue: f32,
    /// Forward–backward error above which a track is rejected \[px\]; ≤ 0 disables the check.
    pub fb_threshold_px: f32,
}

impl Default for KltConfig {
    fn default() -> Self {
        Self {
            window_px: 21,
            max_level: 3,
            max_iterations: 30,
            epsilon_px: 0.01,
            min_eigenvalue: 1e-4 * 1024.0,
            fb_threshold_px: 1.0,
        }
    }
}

/// The outcome of tracking one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Track {
    /// Position in the next image \[px\].
    pub x: f32,
    /// Position in the next image \[px\].
    pub y: f32,
    /// Whether the track is valid (converged, textured, inside, forward–backward consistent).
    pub ok: bool,
    /// Forward–backward error \[px\] (NaN when the check is off or the track failed first).
    pub fb_error_px: f32,
}

/// One level of a tracking pyramid: the image and its raw Scharr gradients (32× grey/px),
/// kept in 8 and 16 bits so that a window's rows stay few cache lines.
#[derive(Debug, Clone)]
struct Level {
    img: GrayImage,
    gx: Image<i16>,
    gy: Image<i16>,
}

/// Scharr's gain: its 3×3 kernel returns 32× the intensity slope.
const SCHARR_GAIN: f32 = 32.0;

/// An image prepared for tracking: its `pyrDown` pyramid with gradients. Build it once per
/// frame and use it both as "previous" and "next".
#[derive(Debug, Clone)]
pub struct KltPyramid {
    levels: Vec<Level>,
}

impl KltPyramid {
    /// Builds levels `0..=max_level` of `img`.
    pub fn new(img: &GrayImage, max_level: usize) -> Self {
        let levels = Pyramid::new(img, max_level)
            .into_levels()
            .into_iter()
            .map(|img| {
                let g = scharr(&img);
                Level {
                    img,
                    gx: g.gx,
                    gy: g.gy,
                }
            })
            .collect();
        Self { levels }
    }

    /// Size of level 0 \[px\].
    pub fn size(&self) -> (usize, usize) {
        self.levels
            .first()
            .map_or((0, 0), |l| (l.img.width(), l.img.height()))
    }
}

/// Tracks `points` from `prev` to `next` (forward–backward checked when configured).
pub fn track(
    prev: &KltPyramid,
    next: &KltPyramid,
    points: &[(f32, f32)],
    config: &KltConfig,
) -> Result<Vec<Track>, VisionError> {
    check(prev, next, config)?;
    let mut win = Window::new(config.window_px);
    // Points are independent; visiting them top to bottom lets neighbouring windows share the
    // image rows already in cache (same results, fewer cache misses).
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| points[a].1.total_cmp(&points[b].1));
    let mut out: Vec<Track> = points
        .iter()
        .map(|&(x, y)| Track {
            x,
            y,
            ok: false,
            fb_error_px: f32::NAN,
        })
        .collect();
    for &k in &order {
        let (Some(t), Some(&p)) = (out.get_mut(k), points.get(k)) else {
            continue;
        };
        if let Some(q) = track_point(prev, next, p, p, config, &mut win) {
            (t.x, t.y, t.ok) = (q.0, q.1, true);
        }
    }
    if config.fb_threshold_px > 0.0 {
        for &k in &order {
            let (Some(t), Some(&p)) = (out.get_mut(k), points.get(k)) else {
                continue;
            };
            if !t.ok {
                continue;
            }
            let back = track_point(next, prev, (t.x, t.y), p, config, &mut win);
            let err = back.map_or(f32::INFINITY, |b| (b.0 - p.0).hypot(b.1 - p.1));
            t.fb_error_px = err;
            t.ok = err <= config.fb_threshold_px;
        }
    }
    Ok(out)
}

fn check(prev: &KltPyramid, next: &KltPyramid, config: &KltConfig) -> Result<(), VisionError> {
    if config.window_px < 3 || config.window_px % 2 == 0 || config.window_px > 101 {
        return Err(VisionError::config(
            "window_px",
            config.window_px,
            "must be odd, 3..=101",
        ));
    }
    if !(config.epsilon_px >= 0.0 && config.min_eigenvalue >= 0.0) {
        return Err(VisionError::config(
            "epsilon_px/min_eigenvalue",
            config.epsilon_px,
            "must be >= 0",
        ));
    }
    let (a, b) = (prev.size(), next.size());
    if a != b || prev.levels.len() != next.levels.len() {
        return Err(VisionError::SizeMismatch {
            a_width: a.0,
            a_height: a.1,
            b_width: b.0,
            b_height: b.1,
        });
    }
    Ok(())
}

/// Bouguet's coarse-to-fine LK for one point; `guess` seeds the position in `next`.
fn track_point(
    prev: &KltPyramid,
    next: &KltPyramid,
    p: (f32, f32),
    guess: (f32, f32),
    cfg: &KltConfig,
    win: &mut Window,
) -> Option<(f32, f32)> {
    if !(p.0.is_finite() && p.1.is_finite() && guess.0.is_finite() && guess.1.is_finite()) {
        return None;
    }
    let n = prev.levels.len().min(next.levels.len());
    let top = n.checked_sub(1)?;
    let r = (cfg.window_px / 2) as f32;
    let s = (1u32 << top) as f32;
    // displacement estimate at the current level
    let mut d = ((guess.0 - p.0) / s, (guess.1 - p.1) / s);
    for level in (0..n).rev() {
        let (lp, ln) = (&prev.levels[level], &next.levels[level]);
        let scale = (1u32 << level) as f32;
        let (px, py) = (p.0 / scale, p.1 / scale);
        let (w, h) = (lp.img.width() as f32, lp.img.height() as f32);
        if px < -r || py < -r || px >= w + r || py >= h + r {
            return None;
        }
        win.sample_template(lp, px - r, py - r);
        let (a11, a12, a22) = win.structure_tensor();
        let area = (cfg.window_px * cfg.window_px) as f32;
        let det = a11 * a22 - a12 * a12;
        let min_eig = (a11 + a22 - ((a11 - a22).powi(2) + 4.0 * a12 * a12).sqrt()) / (2.0 * area);
        if min_eig < cfg.min_eigenvalue || det < f32::EPSILON {
            return None;
        }
        let mut prev_step = (0f32, 0f32);
        for it in 0..cfg.max_iterations {
            let (qx, qy) = (px + d.0, py + d.1);
            if qx < -r || qy < -r || qx >= w + r || qy >= h + r {
                return None;
            }
            let (b1, b2) = win.mismatch(&ln.img, qx - r, qy - r);
            let step = ((a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det);
            d = (d.0 + step.0, d.1 + step.1);
            if step.0 * step.0 + step.1 * step.1 <= cfg.epsilon_px * cfg.epsilon_px {
                break;
            }
            // OpenCV: an update that undoes the previous one means oscillation; split it.
            if it > 0 && (step.0 + prev_step.0).abs() < 0.01 && (step.1 + prev_step.1).abs() < 0.01
            {
                d = (d.0 - step.0 * 0.5, d.1 - step.1 * 0.5);
                break;
            }
            prev_step = step;
        }
        if level > 0 {
            d = (d.0 * 2.0, d.1 * 2.0);
        }
    }
    let q = (p.0 + d.0, p.1 + d.1);
    let (w, h) = (prev.size().0 as f32, prev.size().1 as f32);
    (q.0.is_finite() && q.1.is_finite() && q.0 >= 0.0 && q.1 >= 0.0 && q.0 < w && q.1 < h)
        .then_some(q)
}

/// Fractional bits of the bilinear weights (OpenCV's `W_BITS`).
const W_BITS: u32 = 14;

/// Fractional bits kept of interpolated intensities: I and J are stored ×32 as `i16`, the
/// scale of the raw Scharr gradients, as OpenCV does.
const I_BITS: u32 = 5;

/// Window sums multiply two factors stored ×32 (I − J and ∇I, or ∇I twice); this brings them
/// back to grey levels and grey/px, the units of [`KltConfig::min_eigenvalue`].
const SUM_SCALE: f32 = 1.0 / ((1u32 << I_BITS) as f32 * SCHARR_GAIN);

/// Window rows are padded to a multiple of this many `i16` (one SSE2 register), so that the
/// sampling loops run in whole chunks the compiler turns into vector code.
const LANES: usize = 8;

/// Products summed in one `i32` before the sum is widened to `i64`: |I − J| ≤ 8160 + 1 and
/// |∇I| ≤ 4080 + 1 (Scharr on 8 bits, one unit of weight rounding each), so 64 products stay
/// below 2³¹.
const BLOCK: usize = 64;

/// The per-point integration window, reused per level: template intensities `i` (×32) and
/// gradients `ix`, `iy` (×32 grey/px), and `j`, the next image sampled at the current estimate.
/// Rows are `stride` long (`side` rounded up to [`LANES`]); the padding columns keep zero
/// gradients, so whatever `j` holds there adds nothing to the mismatch vector.
struct Window {
    side: usize,
    stride: usize,
    i: Vec<i16>,
    ix: Vec<i16>,
    iy: Vec<i16>,
    j: Vec<i16>,
}

impl Window {
    fn new(side: usize) -> Self {
        let stride = side.next_multiple_of(LANES);
        let n = side * stride;
        Self {
            side,
            stride,
            i: vec![0; n],
            ix: vec![0; n],
            iy: vec![0; n],
            j: vec![0; n],
        }
    }

    fn sample_template(&mut self, l: &Level, x0: f32, y0: f32) {
        let (origin, w) = split(x0, y0);
        let size = (self.side, self.stride);
        sample(&l.img, origin, w, W_BITS - I_BITS, &mut self.i, size);
        sample(&l.gx, origin, w, W_BITS, &mut self.ix, size);
        sample(&l.gy, origin, w, W_BITS, &mut self.iy, size);
        for row in self
            .ix
            .chunks_exact_mut(self.stride)
            .chain(self.iy.chunks_exact_mut(self.stride))
        {
            row[self.side..].fill(0);
        }
    }

    /// `G = Σ ∇I ∇Iᵀ` in grey²/px².
    fn structure_tensor(&self) -> (f32, f32, f32) {
        let f = |a: &[i16], b: &[i16]| dot(a, b) as f32 * SUM_SCALE;
        (
            f(&self.ix, &self.ix),
            f(&self.ix, &self.iy),
            f(&self.iy, &self.iy),
        )
    }

    /// `b = Σ (I − J) ∇I` in grey²/px, with J sampled at window origin (x0, y0) of `next`.
    fn mismatch(&mut self, next: &GrayImage, x0: f32, y0: f32) -> (f32, f32) {
        let (origin, w) = split(x0, y0);
        let size = (self.side, self.stride);
        sample(next, origin, w, W_BITS - I_BITS, &mut self.j, size);
        let b1 = diff_dot(&self.i, &self.j, &self.ix);
        let b2 = diff_dot(&self.i, &self.j, &self.iy);
        (b1 as f32 * SUM_SCALE, b2 as f32 * SUM_SCALE)
    }
}

dispatch_avx2! {
    /// `Σ a·b` over equal-length slices, in [`BLOCK`]-long `i32` sums (plain multiply-add of
    /// sign-extended `i16`, which the compiler turns into `pmaddwd`).
    fn dot(a: &[i16], b: &[i16]) -> i64;
    portable dot_portable {
        a.chunks(BLOCK)
            .zip(b.chunks(BLOCK))
            .map(|(a, b)| {
                let s: i32 = a
                    .iter()
                    .zip(b)
                    .map(|(&a, &b)| i32::from(a) * i32::from(b))
                    .sum();
                i64::from(s)
            })
            .sum()
    }
}

dispatch_avx2! {
    /// `Σ (i − j)·g` over equal-length slices, as [`dot`].
    fn diff_dot(i: &[i16], j: &[i16], g: &[i16]) -> i64;
    portable diff_dot_portable {
        i.chunks(BLOCK)
            .zip(j.chunks(BLOCK))
            .zip(g.chunks(BLOCK))
            .map(|((i, j), g)| {
                let s: i32 = i
                    .iter()
                    .zip(j)
                    .zip(g)
                    .map(|((&i, &j), &g)| i32::from(i.wrapping_sub(j)) * i32::from(g))
                    .sum();
                i64::from(s)
            })
            .sum()
    }
}

/// Splits a window origin into its integer pixel and the 14-bit bilinear weights of its
/// fraction `(ax, ay)`: `[(1−ax)(1−ay), ax(1−ay), (1−ax)ay, ax·ay]`, the last one taking the
/// rounding remainder so that they sum to exactly 2¹⁴ (OpenCV's `iw00 … iw11`).
fn split(x0: f32, y0: f32) -> ((isize, isize), [i16; 4]) {
    let floor = |v: f32| {
        let i = v as isize;
        if (i as f32) > v {
            i - 1
        } else {
            i
        }
    };
    let (ix, iy) = (floor(x0), floor(y0));
    let (ax, ay) = (x0 - ix as f32, y0 - iy as f32);
    let one = (1u32 << W_BITS) as f32;
    let w00 = round_ties_even((1.0 - ax) * (1.0 - ay) * one) as i32;
    let w01 = round_ties_even(ax * (1.0 - ay) * one) as i32;
    let w10 = round_ties_even((1.0 - ax) * ay * one) as i32;
    let w11 = (1 << W_BITS) - w00 - w01 - w10;
    // (w11 is −1 when the other three round up together: clamped, the sum is then 2¹⁴ + 1)
    let w = [w00, w01, w10, w11].map(|w| w.clamp(0, 1 << W_BITS) as i16);
    ((ix, iy), w)
}

/// Bilinear samples of `img` on the `side × side` grid with unit spacing at integer `origin`
/// plus the fraction whose weights are `w`, rounded and shifted right by `shift` bits, into
/// the `stride`-long rows of `out` (all `stride` columns are sampled). The source rows are read
/// in place when the `(side + 1) × (stride + 1)` patch lies inside the image; otherwise the patch
/// is first gathered with coordinates clamped to the image (replicated border).
fn sample<T: Copy + Into<i32>>(
    img: &Image<T>,
    (ix, iy): (isize, isize),
    w: [i16; 4],
    shift: u32,
    out: &mut [i16],
    (side, stride): (usize, usize),
) {
    let (width, height) = (img.width(), img.height());
    let inside = ix >= 0 && iy >= 0 && ix as usize + stride < width && iy as usize + side < height;
    let (x, y) = (ix as usize, iy as usize);
    let rows = inside
        .then(|| {
            img.data()
                .get(y * width + x..(y + side) * width + x + stride + 1)
        })
        .flatten();
    if let Some(rows) = rows {
        interpolate(rows, width, w, shift, out, stride);
        return;
    }
    // columns ix..=ix+stride: `left` of them left of the image, then `first..end` inside, then
    // the rest right of it
    let n = stride + 1;
    let left = (-ix).clamp(0, n as isize) as usize;
    let first = ix.max(0) as usize;
    let end = (ix + n as isize).clamp(0, width as isize) as usize;
    let right = n - left - end.saturating_sub(first);
    let mut patch: Vec<T> = Vec::with_capacity((side + 1) * n);
    for py in iy..=iy + side as isize {
        let start = py.min(height as isize - 1).max(0) as usize * width;
        let Some(line) = img.data().get(start..start + width) else {
            break;
        };
        let (Some(&lo), Some(&hi)) = (line.first(), line.last()) else {
            break;
        };
        patch.extend(std::iter::repeat(lo).take(left));
        patch.extend_from_slice(line.get(first..end).unwrap_or_default());
        patch.extend(std::iter::repeat(hi).take(right));
    }
    if patch.len() == (side + 1) * (stride + 1) {
        interpolate(&patch, stride + 1, w, shift, out, stride);
    } else {
        out.fill(0); // an empty image
    }
}

/// A pixel type [`interpolate`] reads: `u8` intensities or `i16` gradients.
trait Pixel: Copy + Into<i32> {}
impl<T: Copy + Into<i32>> Pixel for T {}

dispatch_avx2! {
    /// The interpolation loop of [`sample`]: `src` holds the patch's rows `pitch` apart, each
    /// at least `stride + 1` long.
    fn interpolate<T: Pixel>(
        src: &[T],
        pitch: usize,
        w: [i16; 4],
        shift: u32,
        out: &mut [i16],
        stride: usize,
    );
    portable interpolate_portable {
        // The mask (a no-op: weights are in 0..=2¹⁴) tells the compiler the products are of 15-bit
        // non-negative numbers, which it then multiplies in 16-bit lanes (SSE2 pmaddwd/pmullw).
        let [w00, w01, w10, w11] = w.map(|v| [i32::from(v) & 0x7fff; LANES]);
        let half = 1i32 << (shift - 1);
        let rows = src
            .chunks(pitch)
            .map(|r| r.get(..=stride).unwrap_or_default());
        for ((top, bottom), o) in rows
            .clone()
            .zip(rows.skip(1))
            .zip(out.chunks_exact_mut(stride))
        {
            if top.len() != stride + 1 || bottom.len() != stride + 1 {
                break;
            }
            let (t0, t1) = (
                top[..stride].chunks_exact(LANES),
                top[1..].chunks_exact(LANES),
            );
            let (b0, b1) = (
                bottom[..stride].chunks_exact(LANES),
                bottom[1..].chunks_exact(LANES),
            );
            for ((((o, a), b), c), d) in o.chunks_exact_mut(LANES).zip(t0).zip(t1).zip(b0).zip(b1) {
                for k in 0..LANES {
                    let v = a[k].into() * w00[k]
                        + b[k].into() * w01[k]
                        + c[k].into() * w10[k]
                        + d[k].into() * w11[k];
                    o[k] = ((v + half) >> shift) as i16;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A smooth random texture: a sum of random sinusoids, evaluated at (x − dx, y − dy) so
    /// that the second image is the first shifted by exactly (dx, dy).
    fn texture(w: usize, h: usize, dx: f32, dy: f32, seed: u64) -> GrayImage {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let waves: Vec<(f32, f32, f32, f32)> = (0..24)
            .map(|_| {
                let f = rng.gen_range(0.05..0.35f32);
                let a = rng.gen_range(0.0..std::f32::consts::TAU);
                (
                    f * a.cos(),
                    f * a.sin(),
                    rng.gen_range(0.0..std::f32::consts::TAU),
                    rng.gen_range(3.0..9.0),
                )
            })
            .collect();
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32 - dx, (i / w) as f32 - dy);
                let v: f32 = waves
                    .iter()
                    .map(|&(kx, ky, ph, amp)| amp * (kx * x + ky * y + ph).sin())
                    .sum();
                (128.0 + v).round().clamp(0.0, 255.0) as u8
            })
            .collect();
        Image::from_vec(w, h, data).unwrap()
    }

    fn grid_points(w: usize, h: usize, margin: usize, step: usize) -> Vec<(f32, f32)> {
        let mut p = Vec::new();
        for y in (margin..h - margin).step_by(step) {
            for x in (margin..w - margin).step_by(step) {
                p.push((x as f32, y as f32));
            }
        }
        p
    }

    #[test]
    fn recovers_subpixel_shifts() {
        for &(dx, dy) in &[(0.37f32, -1.62f32), (-2.8, 0.45), (5.3, 3.9)] {
            let a = texture(320, 240, 0.0, 0.0, 7);
            let b = texture(320, 240, dx, dy, 7);
            let (pa, pb) = (KltPyramid::new(&a, 3), KltPyramid::new(&b, 3));
            let pts = grid_points(320, 240, 40, 30);
            let tracks = track(&pa, &pb, &pts, &KltConfig::default()).unwrap();
            let mut errs: Vec<f32> = tracks
                .iter()
                .zip(&pts)
                .filter(|(t, _)| t.ok)
                .map(|(t, p)| (t.x - p.0 - dx).hypot(t.y - p.1 - dy))
                .collect();
            assert!(
                errs.len() * 10 >= pts.len() * 9,
                "{} of {} tracked",
                errs.len(),
                pts.len()
            );
            errs.sort_by(f32::total_cmp);
            let median = errs[errs.len() / 2];
            let worst = errs[errs.len() - 1];
            assert!(
                median < 0.05 && worst < 0.1,
                "shift ({dx},{dy}): median {median}, worst {worst}"
            );
        }
    }

    #[test]
    fn forward_backward_rejects_occluded_points() {
        let a = texture(200, 160, 0.0, 0.0, 3);
        // Next image: same texture shifted, but the right half replaced by another texture.
        let shifted = texture(200, 160, 1.5, 0.5, 3);
        let other = texture(200, 160, 0.0, 0.0, 99);
        let data = (0..200 * 160)
            .map(|i| {
                if i % 200 < 100 {
                    shifted.data()[i]
                } else {
                    other.data()[i]
                }
            })
            .collect();
        let b = Image::from_vec(200, 160, data).unwrap();
        let (pa, pb) = (KltPyramid::new(&a, 2), KltPyramid::new(&b, 2));
        let left = vec![(40.0, 80.0), (60.0, 50.0)];
        let right = vec![(150.0, 80.0), (160.0, 40.0), (140.0, 120.0)];
        let cfg = KltConfig {
            fb_threshold_px: 0.5,
            ..KltConfig::default()
        };
        let tl = track(&pa, &pb, &left, &cfg).unwrap();
        assert!(tl.iter().all(|t| t.ok && t.fb_error_px < 0.1), "{tl:?}");
        let tr = track(&pa, &pb, &right, &cfg).unwrap();
        assert!(tr.iter().filter(|t| t.ok).count() <= 1, "{tr:?}");
    }

    /// Float bilinear interpolation with clamped taps, the reference of the fixed-point sampler.
    fn bilinear<T: Copy + Into<f32>>(img: &Image<T>, x: f32, y: f32) -> f32 {
        let (w, h) = (img.width() as isize, img.height() as isize);
        let at = |x: isize, y: isize| {
            let (x, y) = (x.clamp(0, w - 1), y.clamp(0, h - 1));
            (*img.get(x as usize, y as usize).unwrap()).into()
        };
        let (fx, fy) = (x.floor(), y.floor());
        let (ax, ay) = (x - fx, y - fy);
        let (ix, iy) = (fx as isize, fy as isize);
        let top = at(ix, iy) * (1.0 - ax) + at(ix + 1, iy) * ax;
        let bottom = at(ix, iy + 1) * (1.0 - ax) + at(ix + 1, iy + 1) * ax;
        top * (1.0 - ay) + bottom * ay
    }

    #[test]
    fn fixed_point_sampling_matches_float_bilinear() {
        let img = texture(64, 48, 0.0, 0.0, 11);
        let grads = scharr(&img);
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let (side, stride) = (11, 16);
        let mut out = vec![0i16; side * stride];
        // origins inside, across every border and fully outside (clamped path)
        for _ in 0..300 {
            let (x0, y0) = (rng.gen_range(-20.0..60.0f32), rng.gen_range(-20.0..45.0f32));
            let (origin, w) = split(x0, y0);
            for k in 0..3 {
                let (reference, scale): (Box<dyn Fn(f32, f32) -> f32>, f32) = match k {
                    0 => {
                        sample(&img, origin, w, W_BITS - I_BITS, &mut out, (side, stride));
                        (Box::new(|x, y| bilinear(&img, x, y)), 32.0)
                    }
                    1 => {
                        sample(&grads.gx, origin, w, W_BITS, &mut out, (side, stride));
                        (Box::new(|x, y| bilinear(&grads.gx, x, y)), 1.0)
                    }
                    _ => {
                        sample(&grads.gy, origin, w, W_BITS, &mut out, (side, stride));
                        (Box::new(|x, y| bilinear(&grads.gy, x, y)), 1.0)
                    }
                };
                for r in 0..side {
                    for c in 0..side {
                        let want = reference(x0 + c as f32, y0 + r as f32) * scale;
                        let got = f32::from(out[r * stride + c]);
                        assert!(
                            (got - want).abs() <= 1.5,
                            "kernel {k} at ({x0}, {y0}) + ({c}, {r}): {got} vs {want}"
                        );
                    }
                }
            }
        }
    }

    /// The AVX2 build of the interpolation loop equals the portable one, for intensities and
    /// gradients, at extreme weights too.
    #[test]
    fn interpolation_builds_agree() {
        let img = texture(40, 30, 0.0, 0.0, 3);
        let grads = scharr(&img);
        let (side, stride) = (21, 24);
        let (mut a, mut b) = (vec![0i16; side * stride], vec![0i16; side * stride]);
        for (x0, y0) in [(3.25f32, 4.5f32), (0.0, 0.0), (10.999, 2.001), (7.5, 8.75)] {
            let (_, w) = split(x0, y0);
            let start = 4 * 40 + 3;
            interpolate(&img.data()[start..], 40, w, W_BITS - I_BITS, &mut a, stride);
            interpolate_portable(&img.data()[start..], 40, w, W_BITS - I_BITS, &mut b, stride);
            assert_eq!(a, b, "intensity at ({x0}, {y0})");
            interpolate(&grads.gx.data()[start..], 40, w, W_BITS, &mut a, stride);
            interpolate_portable(&grads.gx.data()[start..], 40, w, W_BITS, &mut b, stride);
            assert_eq!(a, b, "gradient at ({x0}, {y0})");
        }
    }

    /// The AVX2 builds of the window sums equal the portable ones.
    #[test]
    fn window_sum_builds_agree() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut v = || -> Vec<i16> { (0..21 * 24).map(|_| rng.gen_range(-4081..=4081)).collect() };
        let (a, b, c) = (v(), v(), v());
        assert_eq!(dot(&a, &b), dot_portable(&a, &b));
        assert_eq!(diff_dot(&a, &b, &c), diff_dot_portable(&a, &b, &c));
        let naive: i64 = a
            .iter()
            .zip(&b)
            .map(|(&x, &y)| i64::from(x) * i64::from(y))
            .sum();
        assert_eq!(dot(&a, &b), naive);
    }

    #[test]
    fn window_sums_do_not_overflow_at_the_extremes() {
        // the largest magnitudes the window can hold (I, J in 0..=8161 with one unit of weight
        // rounding, |∇I| ≤ 4081), over the largest window
        let n = 101 * 104;
        let (bright, dark, g) = (vec![8161i16; n], vec![0i16; n], vec![-4081i16; n]);
        let want = n as i64 * 8161 * 4081;
        assert_eq!(diff_dot(&dark, &bright, &g), want);
        assert_eq!(diff_dot(&bright, &dark, &g), -want);
        assert_eq!(dot(&g, &g), n as i64 * 4081 * 4081);
    }

    #[test]
    fn flat_images_and_bad_points_fail_cleanly() {
        let flat = Image::filled(64, 64, 50u8);
        let p = KltPyramid::new(&flat, 2);
        let t = track(
            &p,
            &p,
            &[(32.0, 32.0), (f32::NAN, 3.0), (-500.0, 10.0)],
            &KltConfig::default(),
        )
        .unwrap();
        assert!(t.iter().all(|t| !t.ok));
        let other = KltPyramid::new(&Image::filled(32, 64, 0u8), 2);
        assert!(track(&p, &other, &[], &KltConfig::default()).is_err());
        let bad = KltConfig {
            window_px: 4,
            ..KltConfig::default()
        };
        assert!(track(&p, &p, &[], &bad).is_err());
    }
}
