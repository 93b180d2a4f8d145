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

use serde::{Deserialize, Serialize};
use slamkit_core::image::{GrayImage, Image};

use crate::error::VisionError;
use crate::filter::scharr;
use crate::pyramid::Pyramid;

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
        let pyr = Pyramid::new(img, max_level);
        let levels = pyr
            .levels()
            .iter()
            .map(|l| {
                let g = scharr(l);
                Level {
                    img: l.clone(),
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
    let mut out: Vec<Track> = points
        .iter()
        .map(|&p| {
            let r = track_point(prev, next, p, p, config, &mut win);
            Track {
                x: r.map_or(p.0, |q| q.0),
                y: r.map_or(p.1, |q| q.1),
                ok: r.is_some(),
                fb_error_px: f32::NAN,
            }
        })
        .collect();
    if config.fb_threshold_px > 0.0 {
        for (t, &p) in out.iter_mut().zip(points) {
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

/// Lanes of the explicit f32 accumulators: window rows are padded to a multiple of this so
/// that every sum runs in fixed-width chunks the compiler turns into vector adds.
const LANES: usize = 8;

/// The per-point integration window: template intensities and gradients, reused per level.
/// Rows are `stride` long (`side` rounded up to [`LANES`]); the padding columns keep zero
/// gradients, so they add nothing to the structure tensor or the mismatch vector.
struct Window {
    side: usize,
    stride: usize,
    i: Vec<f32>,
    ix: Vec<f32>,
    iy: Vec<f32>,
    j: Vec<f32>,
    rows: RowScratch,
}

impl Window {
    fn new(side: usize) -> Self {
        let stride = side.next_multiple_of(LANES);
        let n = side * stride;
        Self {
            side,
            stride,
            i: vec![0.0; n],
            ix: vec![0.0; n],
            iy: vec![0.0; n],
            j: vec![0.0; n],
            rows: RowScratch::new(stride),
        }
    }

    fn sample_template(&mut self, l: &Level, x0: f32, y0: f32) {
        let (at, size, rows) = ((x0, y0), (self.side, self.stride), &mut self.rows);
        sample(&l.img, at, 1.0, &mut self.i, size, rows);
        sample(&l.gx, at, 1.0 / SCHARR_GAIN, &mut self.ix, size, rows);
        sample(&l.gy, at, 1.0 / SCHARR_GAIN, &mut self.iy, size, rows);
    }

    fn structure_tensor(&self) -> (f32, f32, f32) {
        let (mut a11, mut a12, mut a22) = ([0f32; LANES], [0f32; LANES], [0f32; LANES]);
        for (gx, gy) in self.ix.chunks_exact(LANES).zip(self.iy.chunks_exact(LANES)) {
            for k in 0..LANES {
                a11[k] += gx[k] * gx[k];
                a12[k] += gx[k] * gy[k];
                a22[k] += gy[k] * gy[k];
            }
        }
        (a11.iter().sum(), a12.iter().sum(), a22.iter().sum())
    }

    /// `b = Σ (I − J) ∇I` with J sampled at window origin (x0, y0) of `next`.
    fn mismatch(&mut self, next: &GrayImage, x0: f32, y0: f32) -> (f32, f32) {
        let size = (self.side, self.stride);
        sample(next, (x0, y0), 1.0, &mut self.j, size, &mut self.rows);
        let (mut b1, mut b2) = ([0f32; LANES], [0f32; LANES]);
        let grads = lanes(&self.ix).zip(lanes(&self.iy));
        for ((i, j), (gx, gy)) in lanes(&self.i).zip(lanes(&self.j)).zip(grads) {
            for k in 0..LANES {
                let diff = i[k] - j[k];
                b1[k] += diff * gx[k];
                b2[k] += diff * gy[k];
            }
        }
        (b1.iter().sum(), b2.iter().sum())
    }
}

fn lanes(v: &[f32]) -> std::slice::ChunksExact<'_, f32> {
    v.chunks_exact(LANES)
}

/// Row buffers of the separable bilinear sampler, `stride` (+1) long so that the loops run in
/// whole [`LANES`]-wide chunks: one source row converted to f32 (zero past the window), and
/// the horizontally interpolated current and previous rows.
struct RowScratch {
    src: Vec<f32>,
    cur: Vec<f32>,
    prev: Vec<f32>,
}

impl RowScratch {
    fn new(stride: usize) -> Self {
        Self {
            src: vec![0.0; stride + 1],
            cur: vec![0.0; stride],
            prev: vec![0.0; stride],
        }
    }
}

/// Bilinearly samples a `side × side` grid with unit spacing whose first sample is at (x0, y0),
/// times `gain`, into the first `side` entries of each `stride`-long row of `out` (the rest of
/// each row is set to zero), clamping coordinates to the image (replicated border) when the
/// window leaves it.
///
/// Inside the image the interpolation runs separably: each of the `side + 1` source rows is
/// converted and interpolated along x once, then consecutive rows are blended along y, so every
/// source pixel is converted once instead of four times.
fn sample<T: Copy + Into<f32>>(
    img: &Image<T>,
    (x0, y0): (f32, f32),
    gain: f32,
    out: &mut [f32],
    (side, stride): (usize, usize),
    rows: &mut RowScratch,
) {
    let (w, h) = (img.width(), img.height());
    let (fx, fy) = (x0.floor(), y0.floor());
    let (ax, ay) = (x0 - fx, y0 - fy);
    let (ix, iy) = (fx as isize, fy as isize);
    let data = img.data();
    let inside = ix >= 0 && iy >= 0 && ix as usize + side < w && iy as usize + side < h;
    if !inside {
        sample_clamped(img, (ix, iy), (ax, ay), gain, out, (side, stride));
        return;
    }
    let (ix, iy) = (ix as usize, iy as usize);
    let src_rows = data[iy * w..(iy + side + 1) * w].chunks_exact(w);
    let mut dst_rows = out.chunks_exact_mut(stride);
    for (r, src) in src_rows.enumerate() {
        for (c, &v) in rows.src.iter_mut().zip(&src[ix..=ix + side]) {
            *c = gain * v.into();
        }
        let (left, right) = (lanes(&rows.src[..stride]), lanes(&rows.src[1..]));
        for ((o, a), b) in rows.cur.chunks_exact_mut(LANES).zip(left).zip(right) {
            for k in 0..LANES {
                o[k] = a[k] + ax * (b[k] - a[k]);
            }
        }
        if r > 0 {
            let Some(dst) = dst_rows.next() else { break };
            let (top, bottom) = (lanes(&rows.prev), lanes(&rows.cur));
            for ((o, t), b) in dst.chunks_exact_mut(LANES).zip(top).zip(bottom) {
                for k in 0..LANES {
                    o[k] = t[k] + ay * (b[k] - t[k]);
                }
            }
            dst[side..].fill(0.0);
        }
        std::mem::swap(&mut rows.cur, &mut rows.prev);
    }
}

/// [`sample`] near the border: four clamped taps per sample.
fn sample_clamped<T: Copy + Into<f32>>(
    img: &Image<T>,
    (ix, iy): (isize, isize),
    (ax, ay): (f32, f32),
    gain: f32,
    out: &mut [f32],
    (side, stride): (usize, usize),
) {
    let (w, h) = (img.width(), img.height());
    let data = img.data();
    let at = |x: isize, y: isize| {
        let (x, y) = (
            x.clamp(0, w as isize - 1) as usize,
            y.clamp(0, h as isize - 1) as usize,
        );
        data.get(y * w + x).map_or(0.0, |&v| gain * v.into())
    };
    for (r, o) in out.chunks_exact_mut(stride).enumerate() {
        let y = iy + r as isize;
        for (c, o) in o[..side].iter_mut().enumerate() {
            let x = ix + c as isize;
            let top = at(x, y) + ax * (at(x + 1, y) - at(x, y));
            let bottom = at(x, y + 1) + ax * (at(x + 1, y + 1) - at(x, y + 1));
            *o = top + ay * (bottom - top);
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
