//! Sparse stereo matching on a rectified pair: the disparity of chosen left-image points, found
//! along their epipolar line (the same row of the right image), with sub-pixel precision and a
//! per-point confidence.
//!
//! Each point's window is compared with every candidate window of the right row by zero-mean
//! normalised cross-correlation (ZNCC; invariant to gain and offset between the two cameras,
//! Faugeras et al., "Real time correlation-based stereo", INRIA RR-2013, 1993); the window sums
//! of the right image come from integral images (Crow, SIGGRAPH 1984), so each candidate costs
//! one dot product. The best score is refined to sub-pixel disparity by fitting a parabola
//! through it and its two neighbours (the usual three-point interpolation, e.g. Scharstein &
//! Szeliski, IJCV 2002, §5).
//!
//! The coarse-to-fine search (the default) first scores every second disparity on the pair
//! averaged over 2×2 blocks, with a window of half the side — an eighth of the work per
//! disparity — then computes the full-resolution score only within ±2 px of the
//! `coarse_peaks` best local maxima of the coarse scores, and climbs from the best of those until
//! its ±2 px neighbours are all scored (a two-level form of the hierarchical search of L. Quam,
//! "Hierarchical warp stereo", DARPA Image Understanding Workshop, 1984). Scores not computed count as absent, so the
//! result equals the exhaustive search whenever the true peak and its nearest competitor lie
//! near coarse peaks (tests on synthetic pairs and on KITTI measure how often).
//!
//! Confidence in \[0, 1\] plays the role of a stereo camera's confidence map (the ZED's): the best
//! ZNCC score, scaled down when another disparity outside ±1 px of the best scores nearly as
//! well (ambiguous, repetitive texture). Points below `min_confidence` get no disparity.

use std::cell::OnceCell;

use serde::{Deserialize, Serialize};
use slamkit_core::image::GrayImage;

use crate::error::VisionError;
use crate::simd::dispatch_avx2;

/// Sparse stereo settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StereoConfig {
    /// Half side of the square correlation window \[px\] (window side `2r + 1`).
    pub half_window_px: usize,
    /// Smallest disparity searched \[px\].
    pub min_disparity_px: usize,
    /// Largest disparity searched \[px\].
    pub max_disparity_px: usize,
    /// Points whose confidence is below this get no disparity, in \[0, 1\].
    pub min_confidence: f32,
    /// Score gap to the best competitor outside ±1 px under which the confidence is scaled
    /// down proportionally \[ZNCC\].
    pub uniqueness_margin: f32,
    /// Smallest grey-level standard deviation of the left window (flat windows have no match)
    /// \[grey levels\].
    pub min_texture: f32,
    /// Exhaustive or coarse-to-fine disparity search.
    pub search: DisparitySearch,
    /// Coarse-to-fine: the best coarse peaks refined at full resolution.
    pub coarse_peaks: usize,
}

impl Default for StereoConfig {
    fn default() -> Self {
        Self {
            half_window_px: 9,
            min_disparity_px: 1,
            max_disparity_px: 128,
            min_confidence: 0.5,
            uniqueness_margin: 0.1,
            min_texture: 2.0,
            search: DisparitySearch::CoarseToFine,
            coarse_peaks: 3,
        }
    }
}

/// The disparity found for one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoMatch {
    /// `x_left − x_right` \[px\], sub-pixel.
    pub disparity_px: f32,
    /// Confidence in \[0, 1\] (see the module documentation).
    pub confidence: f32,
}

/// How the disparity range of a point is searched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DisparitySearch {
    /// Full-resolution ZNCC at every disparity of the range (the reference).
    Exhaustive,
    /// ZNCC on the 2×2-averaged pair (half the window, every second disparity), then
    /// full-resolution ZNCC only around the best coarse peaks, climbing to the local maximum
    /// (module documentation).
    CoarseToFine,
}

/// Window rows are padded with zeros to a multiple of this many columns, so that the dot
/// product runs in whole 8-lane `i16 × i16 → i32` steps (SSE2 `pmaddwd`) without a scalar tail.
const LANES: usize = 8;

/// Largest `half_window_px`: the sums over a window (at most 129 × 129 pixels) of grey levels
/// and of their squares then stay below 2³², and the `i32` dot product cannot overflow.
const MAX_HALF_WINDOW: usize = 64;

/// Largest coarse half window: sums of 15 × 15 products of grey levels stay below 2²⁴.
const MAX_COARSE_HALF_WINDOW: usize = 7;

/// Full-resolution disparities evaluated on each side of a coarse peak `2D` and of the best
/// full-resolution score: ±2 covers the odd disparities between coarse samples and the
/// competitors just outside ±1 px that the confidence looks at.
const FINE_RADIUS: usize = 2;

/// The right image of a pair prepared for ZNCC: widened to `i16` and its integral images.
#[derive(Debug, Clone)]
struct RightImage {
    width: usize,
    /// The image as `i16`, followed by `LANES` zeros so that a padded window row never leaves
    /// the buffer.
    values: Vec<i16>,
    /// `(width + 1) × (height + 1)` integral of the image, modulo 2³² (window sums below 2³²
    /// come out exact from wrapping arithmetic).
    sum: Vec<u32>,
    /// Integral of the squared image, modulo 2³².
    sum_sq: Vec<u32>,
}

impl RightImage {
    fn new(right: &GrayImage) -> Self {
        let (w, h) = (right.width(), right.height());
        let stride = w + 1;
        let mut sum = vec![0u32; stride * (h + 1)];
        let mut sum_sq = vec![0u32; stride * (h + 1)];
        for (y, row) in right.data().chunks_exact(w.max(1)).enumerate().take(h) {
            let (mut s, mut s2) = (0u32, 0u32);
            for (x, &v) in row.iter().enumerate() {
                s = s.wrapping_add(u32::from(v));
                s2 = s2.wrapping_add(u32::from(v) * u32::from(v));
                let i = (y + 1) * stride + x + 1;
                sum[i] = sum[i - stride].wrapping_add(s);
                sum_sq[i] = sum_sq[i - stride].wrapping_add(s2);
            }
        }
        let mut values: Vec<i16> = right.data().iter().map(|&v| i16::from(v)).collect();
        values.resize(values.len() + LANES, 0);
        Self {
            width: w,
            values,
            sum,
            sum_sq,
        }
    }

    /// ZNCC of the left `patch` with the window of half side `r` centred at (`xr`, `y`); the
    /// caller keeps the window inside the image.
    fn zncc(&self, patch: &Patch, xr: usize, y: usize, r: usize) -> f32 {
        zncc_window(self, patch, xr, y, r)
    }

    /// ZNCC from the dot product of the left `patch` with the right window of side `side` whose
    /// top-left pixel is (`x0`, `y0`).
    #[inline(always)]
    fn normalise(&self, patch: &Patch, dot: i32, x0: usize, y0: usize, side: usize) -> f32 {
        let n = (side * side) as f32;
        let stride = self.width + 1;
        let (x1, y1) = (x0 + side, y0 + side);
        // exact: the window sums are below 2³² (MAX_HALF_WINDOW)
        let rect = |s: &[u32]| {
            s[y1 * stride + x1]
                .wrapping_add(s[y0 * stride + x0])
                .wrapping_sub(s[y0 * stride + x1])
                .wrapping_sub(s[y1 * stride + x0])
        };
        let sum = rect(&self.sum) as f32;
        let var = rect(&self.sum_sq) as f32 - sum * sum / n;
        if var <= 1e-3 {
            return -1.0;
        }
        // Σ (l − l̄)(r − r̄) = Σ l′r − (Σ l′)(Σ r)/n for l′ = l − any constant
        let cov = f64::from(dot) - f64::from(patch.sum) * f64::from(sum) / f64::from(n);
        (cov / f64::from(patch.norm * var.sqrt())) as f32
    }
}

/// The 2×2-averaged pair of the coarse search.
#[derive(Debug, Clone)]
struct CoarsePair {
    left: GrayImage,
    right: RightImage,
    /// The right image as `f32`: the coarse dot products (at most 15 × 15 products of grey
    /// levels) are integers below 2²⁴, exact in `f32`, whose multiply-add SSE2 vectorises.
    right_f32: Vec<f32>,
}

impl CoarsePair {
    fn new(left: &GrayImage, right: &GrayImage) -> Self {
        let right = half_box(right);
        Self {
            left: half_box(left),
            right_f32: right.data().iter().map(|&v| f32::from(v)).collect(),
            right: RightImage::new(&right),
        }
    }

    /// ZNCC of the left `patch` (half side `r` ≤ 7) with the `count` right windows on row `y`
    /// centred at `x_first, x_first + 1, …`, appended to `out` in that order: one pass over the
    /// run per patch pixel, which vectorises over the windows.
    fn zncc_run(
        &self,
        patch: &Patch,
        at: (usize, usize),
        r: usize,
        count: usize,
        scratch: (&mut Vec<f32>, &mut Vec<f32>),
    ) {
        zncc_run_lanes(self, patch, at, r, count, scratch);
    }
}

dispatch_avx2! {
    /// [`CoarsePair::zncc_run`], compiled for AVX2 as well.
    fn zncc_run_lanes(
        pair: &CoarsePair,
        patch: &Patch,
        at: (usize, usize),
        r: usize,
        count: usize,
        scratch: (&mut Vec<f32>, &mut Vec<f32>),
    );
    portable zncc_run_lanes_portable {
        let (x_first, y) = at;
        let (dots, out) = scratch;
        let side = 2 * r + 1;
        let padded = side.next_multiple_of(LANES);
        let x0 = x_first - r;
        let w = pair.right.width;
        dots.clear();
        dots.resize(count, 0.0);
        for (row, prow) in (y - r..=y + r).zip(patch.values.chunks_exact(padded)) {
            let start = row * w + x0;
            let Some(rrow) = pair.right_f32.get(start..start + count + side - 1) else {
                out.extend(std::iter::repeat(-1.0).take(count));
                return;
            };
            for (c, &p) in prow.iter().take(side).enumerate() {
                let p = f32::from(p);
                for (d, &v) in dots.iter_mut().zip(&rrow[c..c + count]) {
                    *d += p * v;
                }
            }
        }
        out.extend(
            dots.iter()
                .enumerate()
                .map(|(k, &dot)| pair.right.normalise(patch, dot as i32, x0 + k, y - r, side)),
        );
    }
}

dispatch_avx2! {
    /// [`RightImage::zncc`], compiled for AVX2 as well.
    fn zncc_window(img: &RightImage, patch: &Patch, xr: usize, y: usize, r: usize) -> f32;
    portable zncc_window_portable {
        let side = 2 * r + 1;
        let (x0, y0, y1) = (xr - r, y - r, y + r + 1);
        let padded = side.next_multiple_of(LANES);
        // integer dot product over zero-padded rows (exact), in eight i32 lanes reduced once per
        // window
        let mut acc = [0i32; LANES];
        for (row, prow) in (y0..y1).zip(patch.values.chunks_exact(padded)) {
            let start = row * img.width + x0;
            let Some(rrow) = img.values.get(start..start + padded) else {
                return -1.0;
            };
            for (a, b) in prow.chunks_exact(LANES).zip(rrow.chunks_exact(LANES)) {
                let (Ok(a), Ok(b)) = (<&[i16; LANES]>::try_from(a), <&[i16; LANES]>::try_from(b))
                else {
                    continue;
                };
                for l in 0..LANES {
                    acc[l] += i32::from(a[l]) * i32::from(b[l]);
                }
            }
        }
        img.normalise(patch, acc.iter().sum(), x0, y0, side)
    }
}

/// A rectified pair prepared for matching; keep it to match more points of the same pair (the
/// preparation, integral images and the coarse pair, is done once).
#[derive(Debug, Clone)]
pub struct StereoPair {
    left: GrayImage,
    right_image: GrayImage,
    right: RightImage,
    /// Built on the first coarse-to-fine search.
    coarse: OnceCell<CoarsePair>,
}

/// Reusable buffers of one `match_points` call.
struct Scratch {
    patch: Patch,
    coarse_patch: Patch,
    /// Full-resolution scores by disparity − `min_disparity_px`; `NEG_INFINITY` = not evaluated.
    scores: Vec<f32>,
    coarse_scores: Vec<f32>,
    dots: Vec<f32>,
    peaks: Vec<(usize, f32)>,
}

impl StereoPair {
    /// Prepares `left`/`right` (rectified, same size) for matching.
    ///
    /// # Errors
    /// [`VisionError::SizeMismatch`] when the images differ in size.
    pub fn new(left: GrayImage, right: GrayImage) -> Result<Self, VisionError> {
        if (left.width(), left.height()) != (right.width(), right.height()) {
            return Err(VisionError::SizeMismatch {
                a_width: left.width(),
                a_height: left.height(),
                b_width: right.width(),
                b_height: right.height(),
            });
        }
        Ok(Self {
            left,
            right: RightImage::new(&right),
            right_image: right,
            coarse: OnceCell::new(),
        })
    }

    /// Matches every point `(x, y)` of the left image; `None` where no disparity reaches the
    /// confidence threshold (or the window leaves the image).
    ///
    /// # Errors
    /// [`VisionError::InvalidConfig`] for an empty disparity range or a confidence outside
    /// \[0, 1\].
    pub fn match_points(
        &self,
        points: &[(f32, f32)],
        config: &StereoConfig,
    ) -> Result<Vec<Option<StereoMatch>>, VisionError> {
        check(config)?;
        let side = 2 * config.half_window_px + 1;
        let mut scratch = Scratch {
            patch: Patch::with_side(side),
            coarse_patch: Patch::with_side(side / 2 + 1),
            scores: Vec::with_capacity(config.max_disparity_px + 1),
            coarse_scores: Vec::new(),
            dots: Vec::new(),
            peaks: Vec::new(),
        };
        // row by row, so that consecutive points read nearby rows of the right image
        let mut order: Vec<usize> = (0..points.len()).collect();
        order.sort_by(|&a, &b| points[a].1.total_cmp(&points[b].1));
        let mut out = vec![None; points.len()];
        for i in order {
            if let (Some(&p), Some(slot)) = (points.get(i), out.get_mut(i)) {
                *slot = self.match_point(p, config, &mut scratch);
            }
        }
        Ok(out)
    }

    fn match_point(
        &self,
        (x, y): (f32, f32),
        config: &StereoConfig,
        scratch: &mut Scratch,
    ) -> Option<StereoMatch> {
        let r = config.half_window_px;
        let (w, h) = (self.left.width(), self.left.height());
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
        let (xi, yi) = (x.round(), y.round());
        if xi < r as f32 || yi < r as f32 || xi + r as f32 >= w as f32 || yi + r as f32 >= h as f32
        {
            return None;
        }
        let (xi, yi) = (xi as usize, yi as usize);
        left_patch(
            &self.left,
            xi,
            yi,
            r,
            &mut scratch.patch,
            config.min_texture,
        )?;
        // candidate right column xr = xi − d must keep its window inside: xr ≥ r
        let d_max = config.max_disparity_px.min(xi - r);
        if d_max < config.min_disparity_px {
            return None;
        }
        let d_min = config.min_disparity_px;
        scratch.scores.clear();
        let searched = config.search == DisparitySearch::CoarseToFine
            && self.coarse_to_fine((xi, yi), (d_min, d_max), config, scratch);
        if !searched {
            scratch.scores.clear();
            for d in d_min..=d_max {
                let s = self.right.zncc(&scratch.patch, xi - d, yi, r);
                scratch.scores.push(s);
            }
        }
        best_disparity(&scratch.scores, config)
    }

    /// Fills `scratch.scores` with full-resolution scores around the best coarse peaks and the
    /// best full-resolution score (`NEG_INFINITY` elsewhere); `false` when the coarse window
    /// does not fit or is flat (the caller then searches exhaustively).
    fn coarse_to_fine(
        &self,
        (xi, yi): (usize, usize),
        (d_min, d_max): (usize, usize),
        config: &StereoConfig,
        scratch: &mut Scratch,
    ) -> bool {
        let coarse = self
            .coarse
            .get_or_init(|| CoarsePair::new(&self.left, &self.right_image));
        let rc = (config.half_window_px / 2).min(MAX_COARSE_HALF_WINDOW);
        let (xc, yc) = (xi / 2, yi / 2);
        if rc == 0
            || xc < rc
            || yc < rc
            || xc + rc >= coarse.left.width()
            || yc + rc >= coarse.left.height()
            || left_patch(&coarse.left, xc, yc, rc, &mut scratch.coarse_patch, 0.0).is_none()
        {
            return false;
        }
        // coarse disparity D stands for full-resolution 2D; keep the coarse window inside
        let (dc_min, dc_max) = (d_min / 2, (d_max / 2).min(xc - rc));
        scratch.coarse_scores.clear();
        if dc_max >= dc_min {
            coarse.zncc_run(
                &scratch.coarse_patch,
                (xc - dc_max, yc),
                rc,
                dc_max - dc_min + 1,
                (&mut scratch.dots, &mut scratch.coarse_scores),
            );
        }
        // by coarse disparity from dc_min
        scratch.coarse_scores.reverse();
        let c = &scratch.coarse_scores;
        scratch.peaks.clear();
        scratch
            .peaks
            .extend(c.iter().enumerate().filter_map(|(i, &s)| {
                let left_ok = i == 0 || c[i - 1] <= s;
                let right_ok = c.get(i + 1).map_or(true, |&n| n < s);
                (left_ok && right_ok).then_some((2 * (dc_min + i), s))
            }));
        scratch
            .peaks
            .sort_unstable_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        scratch.peaks.truncate(config.coarse_peaks);
        scratch.scores.clear();
        scratch.scores.resize(d_max - d_min + 1, f32::NEG_INFINITY);
        let fine = |d: usize, scores: &mut [f32], patch: &Patch| {
            let lo = d.saturating_sub(FINE_RADIUS).max(d_min);
            for dd in lo..=(d + FINE_RADIUS).min(d_max) {
                if let Some(s) = scores.get_mut(dd - d_min) {
                    if *s == f32::NEG_INFINITY {
                        *s = self.right.zncc(patch, xi - dd, yi, config.half_window_px);
                    }
                }
            }
        };
        for &(d, _) in &scratch.peaks {
            fine(d, &mut scratch.scores, &scratch.patch);
        }
        // climb until the best score's ±FINE_RADIUS neighbours are all evaluated
        loop {
            let Some(best) = argmax(&scratch.scores) else {
                return false;
            };
            let lo = best.saturating_sub(FINE_RADIUS);
            let hi = (best + FINE_RADIUS).min(scratch.scores.len() - 1);
            if scratch.scores[lo..=hi]
                .iter()
                .all(|&s| s > f32::NEG_INFINITY)
            {
                return true;
            }
            fine(best + d_min, &mut scratch.scores, &scratch.patch);
        }
    }
}

/// Index of the largest score (the last of equals).
fn argmax(scores: &[f32]) -> Option<usize> {
    scores
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, _)| i)
}

/// The disparity, confidence and sub-pixel offset from the scores by disparity −
/// `min_disparity_px` (`NEG_INFINITY` where not evaluated).
fn best_disparity(scores: &[f32], config: &StereoConfig) -> Option<StereoMatch> {
    let best = argmax(scores)?;
    let s1 = scores[best];
    let s2 = scores
        .iter()
        .enumerate()
        .filter(|(i, _)| i.abs_diff(best) > 1)
        .map(|(_, &s)| s)
        .fold(-1.0f32, f32::max);
    let confidence = s1.max(0.0) * ((s1 - s2) / config.uniqueness_margin).clamp(0.0, 1.0);
    if confidence.is_nan() || confidence < config.min_confidence {
        return None;
    }
    let offset = match (
        best.checked_sub(1).and_then(|i| scores.get(i)),
        scores.get(best + 1),
    ) {
        (Some(&a), Some(&c)) => {
            let denom = a - 2.0 * s1 + c;
            if denom < 0.0 {
                (0.5 * (a - c) / denom).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        }
        _ => 0.0,
    };
    // the window is centred on the rounded pixel; the disparity of a smooth surface is the
    // same a fraction of a pixel away, so it is not shifted by the rounding
    Some(StereoMatch {
        disparity_px: (config.min_disparity_px + best) as f32 + offset,
        confidence,
    })
}

/// The image averaged over 2×2 blocks (rounded), `⌊w/2⌋ × ⌊h/2⌋`: pixel (X, Y) covers
/// (2X..2X+1, 2Y..2Y+1), so disparity D there is disparity 2D at full resolution.
fn half_box(img: &GrayImage) -> GrayImage {
    let (w, h) = (img.width() / 2, img.height() / 2);
    let src = img.data();
    let stride = img.width();
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        let (a, b) = (&src[2 * y * stride..], &src[(2 * y + 1) * stride..]);
        out.extend((0..w).map(|x| {
            let s = u16::from(a[2 * x]) + u16::from(a[2 * x + 1]);
            let s = s + u16::from(b[2 * x]) + u16::from(b[2 * x + 1]);
            ((s + 2) / 4) as u8
        }));
    }
    match GrayImage::from_vec(w, h, out) {
        Some(img) => img,
        None => unreachable!("half_box buffer has w*h pixels"),
    }
}

/// A left window: grey levels minus their rounded mean (each row followed by zeros up to a
/// multiple of `LANES` columns), their sum and the window's centred norm `sqrt(Σ (l − l̄)²)`.
struct Patch {
    values: Vec<i16>,
    sum: i32,
    norm: f32,
}

impl Patch {
    /// An empty patch with room for a window of `side × side`.
    fn with_side(side: usize) -> Self {
        Self {
            values: Vec::with_capacity(side * side.next_multiple_of(LANES)),
            sum: 0,
            norm: 0.0,
        }
    }
}

/// Fills `patch` with the left window at (`x`, `y`); `None` when the window is flatter than
/// `min_texture`.
fn left_patch(
    img: &GrayImage,
    x: usize,
    y: usize,
    r: usize,
    patch: &mut Patch,
    min_texture: f32,
) -> Option<()> {
    let side = 2 * r + 1;
    let padded = side.next_multiple_of(LANES);
    let values = &mut patch.values;
    values.clear();
    let mut total = 0i32;
    for row in y - r..=y + r {
        let start = row * img.width() + x - r;
        let pixels = img.data().get(start..start + side)?;
        total += pixels.iter().map(|&v| i32::from(v)).sum::<i32>();
        values.extend(pixels.iter().map(|&v| i16::from(v)));
        values.resize(values.len() + padded - side, 0);
    }
    let n = (side * side) as f32;
    let offset = (total as f32 / n).round() as i16;
    for row in values.chunks_exact_mut(padded) {
        row.iter_mut().take(side).for_each(|v| *v -= offset);
    }
    let sum: i32 = values.iter().map(|&v| i32::from(v)).sum();
    let sum_sq: i64 = values.iter().map(|&v| i64::from(v) * i64::from(v)).sum();
    let var = sum_sq as f32 - sum as f32 * sum as f32 / n;
    if var.is_nan() || (var.max(0.0) / n).sqrt() < min_texture || var <= 0.0 {
        return None;
    }
    patch.sum = sum;
    patch.norm = var.sqrt();
    Some(())
}

fn check(config: &StereoConfig) -> Result<(), VisionError> {
    if config.max_disparity_px < config.min_disparity_px {
        return Err(VisionError::config(
            "max_disparity_px",
            config.max_disparity_px,
            "must be >= min_disparity_px",
        ));
    }
    if !(0.0..=1.0).contains(&config.min_confidence) {
        return Err(VisionError::config(
            "min_confidence",
            config.min_confidence,
            "must be in [0, 1]",
        ));
    }
    if config.half_window_px > MAX_HALF_WINDOW {
        return Err(VisionError::config(
            "half_window_px",
            config.half_window_px,
            "must be <= 64 (window sums in 32 bits)",
        ));
    }
    if config.search == DisparitySearch::CoarseToFine && config.coarse_peaks == 0 {
        return Err(VisionError::config(
            "coarse_peaks",
            config.coarse_peaks,
            "must be >= 1 for the coarse-to-fine search",
        ));
    }
    if config.uniqueness_margin.is_nan() || config.uniqueness_margin <= 0.0 {
        return Err(VisionError::config(
            "uniqueness_margin",
            config.uniqueness_margin,
            "must be > 0",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests;
