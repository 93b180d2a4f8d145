//! ORB features (E. Rublee, V. Rabaud, K. Konolige, G. Bradski, "ORB: an efficient alternative
//! to SIFT or SURF", ICCV 2011), following OpenCV's `ORB_Impl`:
//!
//! 1. a scale pyramid (`scale_factor` per level, bilinear resize of the previous level);
//! 2. the feature budget split over levels in geometric proportion to their area, as OpenCV's
//!    `nfeaturesPerLevel`;
//! 3. per level: FAST-9 corners away from the border, the best `2n` by FAST score, then the
//!    best `n` by Harris response (7×7 block, k = 0.04);
//! 4. orientation from the intensity centroid of the radius-15 disc (P. Rosin, 1999);
//! 5. a 256-bit rotated-BRIEF descriptor on the level image blurred by a 7×7, σ = 2 Gaussian,
//!    using the learned pattern in the `orb_pattern` module.
//!
//! Keypoint positions are reported in level-0 pixels.

use serde::{Deserialize, Serialize};
use slamkit_core::image::GrayImage;

use crate::error::VisionError;
use crate::fast::{fast9, FastCorner};
use crate::filter::gaussian_blur;
use crate::orb_pattern::BIT_PATTERN_31;
use crate::pyramid::resize_bilinear;
use crate::round::round_to_i32;
use crate::simd::dispatch_avx2;

/// A 256-bit binary descriptor, bit i in word i / 64.
pub type Descriptor = [u64; 4];

/// ORB parameters (OpenCV `ORB::create` defaults).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OrbConfig {
    /// Total number of features wanted over all levels.
    pub n_features: usize,
    /// Scale ratio between consecutive pyramid levels (> 1).
    pub scale_factor: f32,
    /// Number of pyramid levels.
    pub n_levels: usize,
    /// Margin where no feature is detected \[px at each level\]; ≥ 19 so the pattern fits.
    pub edge_threshold: usize,
    /// FAST intensity threshold \[grey levels\].
    pub fast_threshold: u8,
    /// Side of the square cells a level's keypoints are spread over \[px at each level\]; 0
    /// keeps OpenCV's ranking over the whole image. With cells, the best of every cell is kept
    /// before the second best of any, a cell without corners leaving its share to the others.
    /// The global ranking gathers the budget on the most contrasted texture (foliage, far
    /// façades on KITTI) and leaves the weak but near ground with few keypoints; ORB-SLAM
    /// detects in 30-px cells for the same reason (Mur-Artal & Tardós, T-RO 2017, §III-A).
    pub cell_px: usize,
}

impl Default for OrbConfig {
    fn default() -> Self {
        Self {
            n_features: 500,
            scale_factor: 1.2,
            n_levels: 8,
            edge_threshold: 31,
            fast_threshold: 20,
            cell_px: 0,
        }
    }
}

/// An ORB keypoint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keypoint {
    /// Column in the level-0 image \[px\].
    pub x: f32,
    /// Row in the level-0 image \[px\].
    pub y: f32,
    /// Pyramid level it was found on.
    pub level: usize,
    /// Orientation of the intensity centroid, `atan2(m01, m10)` in `[0, 2π)` \[rad\], with y
    /// pointing down (OpenCV's `angle`, in radians).
    pub angle_rad: f32,
    /// Harris response.
    pub response: f32,
    /// Patch diameter at level 0 \[px\] (31 · scale).
    pub size: f32,
}

/// Keypoints and their descriptors, index for index.
#[derive(Debug, Clone, Default)]
pub struct OrbFeatures {
    /// Keypoints.
    pub keypoints: Vec<Keypoint>,
    /// Descriptors, `descriptors\[i\]` for `keypoints\[i\]`.
    pub descriptors: Vec<Descriptor>,
}

const HALF_PATCH: usize = 15;
const HARRIS_BLOCK: usize = 7;
const HARRIS_K: f32 = 0.04;

/// An ORB extractor with its precomputed tables.
#[derive(Debug, Clone)]
pub struct Orb {
    config: OrbConfig,
    per_level: Vec<usize>,
    umax: Vec<usize>,
    pattern: PatternPoints,
}

impl Orb {
    /// Checks the configuration and prepares the per-level budget and the disc table.
    pub fn new(config: OrbConfig) -> Result<Self, VisionError> {
        if !(config.scale_factor > 1.0 && config.scale_factor.is_finite()) {
            return Err(VisionError::config(
                "scale_factor",
                config.scale_factor,
                "must be > 1",
            ));
        }
        if config.n_levels == 0 || config.n_levels > 32 {
            return Err(VisionError::config(
                "n_levels",
                config.n_levels,
                "must be 1..=32",
            ));
        }
        if config.edge_threshold < 19 {
            return Err(VisionError::config(
                "edge_threshold",
                config.edge_threshold,
                "must be >= 19",
            ));
        }
        let per_level = features_per_level(config.n_features, config.scale_factor, config.n_levels);
        Ok(Self {
            config,
            per_level,
            umax: disc_table(HALF_PATCH),
            pattern: PatternPoints::new(),
        })
    }

    /// Detects keypoints and computes their descriptors.
    pub fn detect_and_compute(&self, img: &GrayImage) -> OrbFeatures {
        let mut out = OrbFeatures::default();
        let mut level_img = img.clone();
        for (level, &n) in self.per_level.iter().enumerate() {
            let scale = self.config.scale_factor.powi(level as i32);
            if level > 0 {
                level_img = next_level(img, &level_img, scale);
            }
            if level_img.width() <= 2 * self.config.edge_threshold
                || level_img.height() <= 2 * self.config.edge_threshold
            {
                break;
            }
            let kps = self.detect_level(&level_img, n);
            if kps.is_empty() {
                continue;
            }
            let Ok(blurred) = gaussian_blur(&level_img, 7, 2.0) else {
                continue;
            };
            for (k, response) in kps {
                let angle = self.ic_angle(&level_img, k.x, k.y);
                out.descriptors
                    .push(describe(&blurred, &self.pattern, k.x, k.y, angle));
                out.keypoints.push(Keypoint {
                    x: k.x as f32 * scale,
                    y: k.y as f32 * scale,
                    level,
                    angle_rad: angle,
                    response,
                    size: 31.0 * scale,
                });
            }
        }
        out
    }

    /// Descriptors of the level-0 pixels `points` computed on the coarser pyramid levels
    /// `1..=max_level` (the pyramid of [`Orb::detect_and_compute`], `scale_factor` apart,
    /// whatever `n_levels` is): `out[l - 1][i]` describes `points[i]` on level `l`, `None`
    /// where its patch leaves that level's image.
    ///
    /// A keypoint detected on level 0 of one image and seen `s` times larger in another
    /// (the camera moved towards it) has, on the second image's level `log(s) / log(scale)`,
    /// the patch it had in the first: describing it there matches across a scale change that
    /// the level-0 descriptors cannot span (about 1.4 at 3 m of forward motion on KITTI),
    /// while its position stays the level-0 keypoint's.
    pub fn describe_on_levels(
        &self,
        img: &GrayImage,
        points: &[(f32, f32)],
        max_level: usize,
    ) -> Vec<Vec<Option<Descriptor>>> {
        // the descriptor's pattern reaches 13·√2 < 19 px, the angle's disc 15 px
        let margin = 19.0;
        let mut out = Vec::with_capacity(max_level);
        let mut level_img = img.clone();
        for level in 1..=max_level {
            let scale = self.config.scale_factor.powi(level as i32);
            level_img = next_level(img, &level_img, scale);
            let (w, h) = (level_img.width() as f32, level_img.height() as f32);
            let Ok(blurred) = gaussian_blur(&level_img, 7, 2.0) else {
                out.push(vec![None; points.len()]);
                continue;
            };
            out.push(
                points
                    .iter()
                    .map(|&(x, y)| {
                        let (lx, ly) = ((x / scale).round(), (y / scale).round());
                        if !(lx >= margin && ly >= margin && lx < w - margin && ly < h - margin) {
                            return None;
                        }
                        let (lx, ly) = (lx as usize, ly as usize);
                        let angle = self.ic_angle(&level_img, lx, ly);
                        Some(describe(&blurred, &self.pattern, lx, ly, angle))
                    })
                    .collect(),
            );
        }
        out
    }

    /// FAST corners of one level, the best `2n` by FAST score, then the best `n` by Harris,
    /// with their Harris responses.
    fn detect_level(&self, img: &GrayImage, n: usize) -> Vec<(FastCorner, f32)> {
        let mut kps = fast9(
            img,
            self.config.fast_threshold,
            self.config.edge_threshold,
            true,
        );
        let cell = self.config.cell_px;
        if cell > 0 {
            spread_over_cells(
                &mut kps,
                2 * n,
                cell,
                |k| (k.x, k.y),
                |k| f32::from(k.score),
            );
        } else {
            retain_best(&mut kps, 2 * n, |k| f32::from(k.score));
        }
        let mut scored: Vec<(FastCorner, f32)> = kps
            .into_iter()
            .map(|k| (k, harris_response(img, k.x, k.y)))
            .collect();
        if cell > 0 {
            spread_over_cells(&mut scored, n, cell, |s| (s.0.x, s.0.y), |s| s.1);
        } else {
            retain_best(&mut scored, n, |s| s.1);
        }
        scored
    }

    /// Intensity-centroid angle over the radius-15 disc \[rad\], in `[0, 2π)`.
    fn ic_angle(&self, img: &GrayImage, x: usize, y: usize) -> f32 {
        let w = img.width();
        let d = img.data();
        let c = y * w + x;
        let (mut m01, mut m10) = (0i32, 0i32);
        let r = HALF_PATCH as isize;
        if let Some(row) = d.get(c - HALF_PATCH..=c + HALF_PATCH) {
            m10 += row
                .iter()
                .zip(-r..=r)
                .map(|(&v, u)| u as i32 * i32::from(v))
                .sum::<i32>();
        }
        for v in 1..=HALF_PATCH {
            let du = self.umax[v];
            let (lo, hi) = (c + v * w, c - v * w);
            let (Some(plus), Some(minus)) = (d.get(lo - du..=lo + du), d.get(hi - du..=hi + du))
            else {
                continue;
            };
            let mut v_sum = 0i32;
            for ((&p, &m), u) in plus.iter().zip(minus).zip(-(du as i32)..) {
                let (p, m) = (i32::from(p), i32::from(m));
                v_sum += p - m;
                m10 += u * (p + m);
            }
            m01 += v as i32 * v_sum;
        }
        let a = (m01 as f32).atan2(m10 as f32);
        if a < 0.0 {
            a + std::f32::consts::TAU
        } else {
            a
        }
    }
}

/// The pyramid level of scale `scale` of `img`, resized from the previous level `prev`.
fn next_level(img: &GrayImage, prev: &GrayImage, scale: f32) -> GrayImage {
    let dw = (img.width() as f32 / scale).round() as usize;
    let dh = (img.height() as f32 / scale).round() as usize;
    resize_bilinear(prev, dw, dh)
}

/// OpenCV's split of `n` features over `levels` levels in ratio `1/scale` per level.
fn features_per_level(n: usize, scale: f32, levels: usize) -> Vec<usize> {
    let factor = 1.0 / scale;
    let mut desired = n as f32 * (1.0 - factor) / (1.0 - factor.powi(levels as i32));
    let mut out = Vec::with_capacity(levels);
    let mut sum = 0usize;
    for _ in 0..levels.saturating_sub(1) {
        let k = desired.round_ties_even().max(0.0) as usize;
        out.push(k);
        sum += k;
        desired *= factor;
    }
    out.push(n.saturating_sub(sum));
    out
}

/// Half-widths of the rows of a digital disc of radius `r`, made symmetric as OpenCV's `umax`.
fn disc_table(r: usize) -> Vec<usize> {
    let mut umax = vec![0usize; r + 2];
    let half = r as f64 * std::f64::consts::SQRT_2 / 2.0;
    let vmax = (half + 1.0).floor() as usize;
    let vmin = half.ceil() as usize;
    for (v, u) in umax.iter_mut().enumerate().take(vmax + 1) {
        *u = ((r * r - v * v) as f64).sqrt().round() as usize;
    }
    let mut v0 = 0;
    for v in (vmin..=r).rev() {
        while umax[v0] == umax[v0 + 1] {
            v0 += 1;
        }
        umax[v] = v0;
        v0 += 1;
    }
    umax
}

/// Keeps the `n` items with the largest `key` (order not kept); deterministic on ties.
fn retain_best<T>(items: &mut Vec<T>, n: usize, key: impl Fn(&T) -> f32) {
    if items.len() > n {
        if n > 0 {
            items.select_nth_unstable_by(n - 1, |a, b| key(b).total_cmp(&key(a)));
        }
        items.truncate(n);
    }
}

/// Keeps `n` of `items` spread over square cells of side `cell_px` (> 0): ranked by `key`
/// within each cell, the items of rank 0 of every cell come first, then those of rank 1, and
/// so on, each rank ordered by `key` (ties by the original order: deterministic). A cell with
/// few corners gives its share to the others, so the budget is spent as with a global ranking
/// when every cell is full.
fn spread_over_cells<T>(
    items: &mut Vec<T>,
    n: usize,
    cell_px: usize,
    position: impl Fn(&T) -> (usize, usize),
    key: impl Fn(&T) -> f32,
) {
    if items.len() <= n {
        return;
    }
    let cell_of = |t: &T| {
        let (x, y) = position(t);
        (y / cell_px, x / cell_px)
    };
    let mut order: Vec<usize> = (0..items.len()).collect();
    order.sort_by(|&a, &b| {
        cell_of(&items[a])
            .cmp(&cell_of(&items[b]))
            .then(key(&items[b]).total_cmp(&key(&items[a])))
            .then(a.cmp(&b))
    });
    let mut rank = vec![0usize; items.len()];
    for pair in order.windows(2) {
        if let [prev, next] = *pair {
            if cell_of(&items[prev]) == cell_of(&items[next]) {
                rank[next] = rank[prev] + 1;
            }
        }
    }
    order.sort_by(|&a, &b| {
        rank[a]
            .cmp(&rank[b])
            .then(key(&items[b]).total_cmp(&key(&items[a])))
            .then(a.cmp(&b))
    });
    order.truncate(n);
    order.sort_unstable();
    let mut keep = vec![false; items.len()];
    for i in order {
        keep[i] = true;
    }
    let mut flags = keep.into_iter();
    items.retain(|_| flags.next().unwrap_or(false));
}

/// Harris corner response over the 7×7 block around (x, y), with OpenCV's Sobel and scale.
fn harris_response(img: &GrayImage, x: usize, y: usize) -> f32 {
    let w = img.width();
    let d = img.data();
    let r = HARRIS_BLOCK / 2;
    let (mut a, mut b, mut c) = (0i32, 0i32, 0i32);
    for yy in y - r..=y + r {
        let (Some(up), Some(mid), Some(dn)) = (
            d.get((yy - 1) * w + x - r - 1..(yy - 1) * w + x + r + 2),
            d.get(yy * w + x - r - 1..yy * w + x + r + 2),
            d.get((yy + 1) * w + x - r - 1..(yy + 1) * w + x + r + 2),
        ) else {
            return 0.0;
        };
        for ((u, m), n) in up.windows(3).zip(mid.windows(3)).zip(dn.windows(3)) {
            let p = |s: &[u8], i: usize| i32::from(s[i]);
            let ix = (p(m, 2) - p(m, 0)) * 2 + (p(u, 2) - p(u, 0)) + (p(n, 2) - p(n, 0));
            let iy = (p(n, 1) - p(u, 1)) * 2 + (p(n, 0) - p(u, 0)) + (p(n, 2) - p(u, 2));
            a += ix * ix;
            b += iy * iy;
            c += ix * iy;
        }
    }
    let scale = 1.0 / (4.0 * HARRIS_BLOCK as f32 * 255.0);
    let s4 = scale * scale * scale * scale;
    let (a, b, c) = (a as f32, b as f32, c as f32);
    (a * b - c * c - HARRIS_K * (a + b) * (a + b)) * s4
}

/// The BRIEF test points as coordinate arrays: point `k` of test `i` at index `2i + k`.
#[derive(Debug, Clone)]
struct PatternPoints {
    x: Vec<f32>,
    y: Vec<f32>,
}

impl PatternPoints {
    fn new() -> Self {
        let points = || {
            BIT_PATTERN_31
                .iter()
                .flat_map(|p| [(p[0], p[1]), (p[2], p[3])])
        };
        Self {
            x: points().map(|(x, _)| f32::from(x)).collect(),
            y: points().map(|(_, y)| f32::from(y)).collect(),
        }
    }
}

dispatch_avx2! {
    /// Rotated BRIEF: bit i compares the blurred image at the two rotated, rounded pattern
    /// points. The rotated offsets are computed first in a loop of their own (vectorised), then
    /// the image is sampled at them.
    fn describe(
        blurred: &GrayImage,
        pattern: &PatternPoints,
        x: usize,
        y: usize,
        angle: f32,
    ) -> Descriptor;
    portable describe_portable {
        let d = blurred.data();
        let centre = y * blurred.width() + x;
        // the row pitch as i32 (no image here is 2³¹ px wide; 0 would only keep it panic-free)
        let w = i32::try_from(blurred.width()).unwrap_or(0);
        let (s, c) = angle.sin_cos();
        // rotated, rounded offsets in i32 lanes, vectorised (|offsets| < 19 px)
        let mut offsets = [0i32; 512];
        for ((o, &px), &py) in offsets.iter_mut().zip(&pattern.x).zip(&pattern.y) {
            *o = round_to_i32(px * s + py * c) * w + round_to_i32(px * c - py * s);
        }
        let at = |o: i32| {
            d.get(centre.wrapping_add_signed(o as isize))
                .copied()
                .unwrap_or(0)
        };
        let mut desc = [0u64; 4];
        for (word, tests) in desc.iter_mut().zip(offsets.chunks_exact(128)) {
            // one bit per test without a branch (the comparisons are coin flips to a predictor)
            for (bit, pair) in tests.chunks_exact(2).enumerate() {
                *word |= u64::from(at(pair[0]) < at(pair[1])) << bit;
            }
        }
        desc
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budget_matches_opencv() {
        // 500·(1 − 1/1.2)/(1 − 1.2⁻⁸) = 108.6, then ×1/1.2 per level; the last takes the rest
        assert_eq!(
            features_per_level(500, 1.2, 8),
            vec![109, 90, 75, 63, 52, 44, 36, 31]
        );
        assert_eq!(features_per_level(500, 1.2, 8).iter().sum::<usize>(), 500);
    }

    #[test]
    fn disc_is_symmetric() {
        let u = disc_table(15);
        assert_eq!(u[0], 15);
        assert_eq!(u[15], 3);
        for v in 0..=15 {
            // the disc is symmetric under transposition: row v reaches column u[v] iff ...
            assert_eq!((0..=15).filter(|&k| u[k] >= v).count(), u[v] + 1, "row {v}");
        }
    }

    #[test]
    fn pattern_fits_the_edge_margin() {
        let max = BIT_PATTERN_31
            .iter()
            .flat_map(|p| p.iter())
            .map(|v| v.unsigned_abs())
            .max();
        assert_eq!(max, Some(13));
    }

    /// The two-pass descriptor equals the direct per-test rotation and sampling.
    #[test]
    fn describe_matches_the_direct_computation() {
        let img = crate::test_images::hashed(64, 64);
        let pattern = PatternPoints::new();
        for angle in [0.0f32, 0.3, 1.7, 3.2, 5.9] {
            let (s, c) = angle.sin_cos();
            let at = |px: i8, py: i8| {
                let (px, py) = (f32::from(px), f32::from(py));
                let ix = (px * c - py * s).round_ties_even() as isize;
                let iy = (px * s + py * c).round_ties_even() as isize;
                *img.get((32 + ix) as usize, (32 + iy) as usize).unwrap()
            };
            let mut want = [0u64; 4];
            for (i, p) in BIT_PATTERN_31.iter().enumerate() {
                if at(p[0], p[1]) < at(p[2], p[3]) {
                    want[i / 64] |= 1 << (i % 64);
                }
            }
            assert_eq!(describe(&img, &pattern, 32, 32, angle), want, "{angle}");
            assert_eq!(describe_portable(&img, &pattern, 32, 32, angle), want);
        }
    }

    #[test]
    fn cells_keep_the_best_of_every_cell_first() {
        // (x, y, key): cell (0, 0) holds three strong items, cell (0, 1) one weak one
        let mut items = vec![(1, 1, 9.0), (2, 2, 8.0), (12, 1, 1.0), (3, 3, 7.0)];
        spread_over_cells(&mut items, 2, 10, |t| (t.0, t.1), |t| t.2);
        assert_eq!(items, vec![(1, 1, 9.0), (12, 1, 1.0)]);
        // a budget larger than the cells' first ranks is filled by the next ranks, by key
        let mut items = vec![(1, 1, 9.0), (2, 2, 8.0), (12, 1, 1.0), (3, 3, 7.0)];
        spread_over_cells(&mut items, 3, 10, |t| (t.0, t.1), |t| t.2);
        assert_eq!(items, vec![(1, 1, 9.0), (2, 2, 8.0), (12, 1, 1.0)]);
    }

    #[test]
    fn cells_spread_keypoints_to_weak_texture() {
        // hashed noise at full contrast on the left half, at 0.6 of it on the right: the
        // global ranking takes (nearly) all its keypoints on the left
        let (w, h) = (320, 120);
        let noise = crate::test_images::hashed(w, h);
        let data: Vec<u8> = noise
            .data()
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let gain = if i % w < w / 2 { 1.0 } else { 0.6 };
                (128.0 + (f32::from(v) - 128.0) * gain) as u8
            })
            .collect();
        let img = GrayImage::from_vec(w, h, data).unwrap();
        let config = OrbConfig {
            n_features: 60,
            n_levels: 1,
            ..OrbConfig::default()
        };
        let right_half =
            |f: &OrbFeatures| f.keypoints.iter().filter(|k| k.x >= (w / 2) as f32).count();
        let global = Orb::new(config.clone()).unwrap().detect_and_compute(&img);
        let cells = Orb::new(OrbConfig {
            cell_px: 30,
            ..config
        })
        .unwrap()
        .detect_and_compute(&img);
        assert_eq!(global.keypoints.len(), 60);
        assert_eq!(cells.keypoints.len(), 60);
        assert!(
            right_half(&cells) > right_half(&global) + 10,
            "{} vs {}",
            right_half(&cells),
            right_half(&global)
        );
    }

    /// A view 1.44 times closer (the image upscaled by 1.2²) described two levels coarser
    /// gives the original's descriptors back, where the same level does not.
    #[test]
    fn coarser_levels_describe_a_closer_view() {
        let (w, h) = (200, 160);
        let texture = gaussian_blur(&crate::test_images::hashed(w, h), 7, 1.5).unwrap();
        let s = 1.44f32;
        let closer = resize_bilinear(
            &texture,
            (w as f32 * s).round() as usize,
            (h as f32 * s).round() as usize,
        );
        let orb = Orb::new(OrbConfig::default()).unwrap();
        let points: Vec<(f32, f32)> = (0..6)
            .flat_map(|i| (0..4).map(move |j| (60.0 + 16.0 * i as f32, 50.0 + 16.0 * j as f32)))
            .collect();
        let moved: Vec<(f32, f32)> = points
            .iter()
            .map(|&(x, y)| ((x + 0.5) * s - 0.5, (y + 0.5) * s - 0.5))
            .collect();
        let original = orb.describe_on_levels(&texture, &points, 1);
        let near = orb.describe_on_levels(&closer, &moved, 3);
        let mean_distance = |a: &[Option<Descriptor>], b: &[Option<Descriptor>]| {
            let d: Vec<u32> = a
                .iter()
                .zip(b)
                .map(|(a, b)| crate::matching::hamming(&a.unwrap(), &b.unwrap()))
                .collect();
            d.iter().sum::<u32>() as f32 / d.len() as f32
        };
        let same_level = mean_distance(&original[0], &near[0]);
        let scaled = mean_distance(&original[0], &near[2]);
        assert!(
            // measured: 36 bits against 127 (unrelated descriptors differ by 128)
            scaled < 64.0 && scaled < 0.5 * same_level,
            "{scaled} vs {same_level}"
        );
        // a patch that leaves the level's image is not described
        let edge = orb.describe_on_levels(&texture, &[(5.0, 5.0)], 2);
        assert_eq!(edge.len(), 2);
        assert!(edge.iter().all(|l| l[0].is_none()));
    }

    #[test]
    fn bad_config_is_an_error() {
        assert!(Orb::new(OrbConfig {
            scale_factor: 1.0,
            ..OrbConfig::default()
        })
        .is_err());
        assert!(Orb::new(OrbConfig {
            edge_threshold: 3,
            ..OrbConfig::default()
        })
        .is_err());
        assert!(Orb::new(OrbConfig {
            n_levels: 0,
            ..OrbConfig::default()
        })
        .is_err());
        let orb = Orb::new(OrbConfig::default()).unwrap();
        let tiny = GrayImage::filled(30, 30, 0);
        assert!(orb.detect_and_compute(&tiny).keypoints.is_empty());
    }
}
