//! Shi–Tomasi "good features to track" (J. Shi and C. Tomasi, CVPR 1994): the score of a pixel
//! is the smaller eigenvalue of the structure tensor `Σ \[gx² gxgy; gxgy gy²\]` summed over a 3×3
//! window of 3×3 Sobel gradients, as OpenCV's `cornerMinEigenVal(blockSize=3, ksize=3)`.
//! Corners are the 3×3 local maxima above `quality_level × best score`, taken strongest first
//! and kept at least `min_distance_px` apart (OpenCV's `goodFeaturesToTrack`). On top of that,
//! grid bucketing caps the number per cell so that corners spread over the whole image, which
//! visual odometry needs for a well-conditioned motion estimate.

use serde::{Deserialize, Serialize};
use slamkit_core::image::{GrayImage, Image};

use crate::border::reflect101;
use crate::color::image_like;
use crate::error::VisionError;
use crate::filter::sobel;

/// Shi–Tomasi detector parameters.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShiTomasiConfig {
    /// Minimum score as a fraction of the image's best score (OpenCV `qualityLevel`).
    pub quality_level: f32,
    /// Minimum distance between two corners \[px\] (OpenCV `minDistance`).
    pub min_distance_px: f32,
    /// Number of bucketing cells across the image \[cells\].
    pub grid_cols: usize,
    /// Number of bucketing cells down the image \[cells\].
    pub grid_rows: usize,
    /// Maximum corners kept per cell (0 = no per-cell limit).
    pub max_per_cell: usize,
    /// Maximum corners over the whole image (0 = no limit; OpenCV `maxCorners`).
    pub max_corners: usize,
}

impl Default for ShiTomasiConfig {
    fn default() -> Self {
        Self {
            quality_level: 0.01,
            min_distance_px: 10.0,
            grid_cols: 8,
            grid_rows: 6,
            max_per_cell: 20,
            max_corners: 0,
        }
    }
}

/// A detected corner: position \[px\] (pixel centres at integers) and its min-eigenvalue score
/// (Sobel units², summed over the 3×3 window).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    /// Column \[px\].
    pub x: f32,
    /// Row \[px\].
    pub y: f32,
    /// Smaller structure-tensor eigenvalue.
    pub score: f32,
}

/// The min-eigenvalue map of the 3×3-window structure tensor of 3×3 Sobel gradients.
pub fn min_eigenvalue_map(img: &GrayImage) -> Image<f32> {
    let (w, h) = (img.width(), img.height());
    let mut out = vec![0f32; w * h];
    if w == 0 || h == 0 {
        return image_like(img, out);
    }
    let g = sobel(img);
    // Horizontally box-summed products per row, in a ring of three rows: [xx, xy, yy].
    let mut ring: Vec<[Vec<i32>; 3]> = (0..3)
        .map(|_| [vec![0; w], vec![0; w], vec![0; w]])
        .collect();
    let mut prod = [vec![0i32; w + 2], vec![0i32; w + 2], vec![0i32; w + 2]];
    let mut fill = |r: usize, slot: &mut [Vec<i32>; 3]| {
        let gx = &g.gx.data()[r * w..(r + 1) * w];
        let gy = &g.gy.data()[r * w..(r + 1) * w];
        let [pxx, pxy, pyy] = &mut prod;
        for (x, (&a, &b)) in gx.iter().zip(gy).enumerate() {
            let (a, b) = (i32::from(a), i32::from(b));
            pxx[x + 1] = a * a;
            pxy[x + 1] = a * b;
            pyy[x + 1] = b * b;
        }
        for p in prod.iter_mut() {
            p[0] = p[reflect101(-1, w) + 1];
            p[w + 1] = p[reflect101(w as isize, w) + 1];
        }
        for (s, p) in slot.iter_mut().zip(prod.iter()) {
            for (o, win) in s.iter_mut().zip(p.windows(3)) {
                *o = win[0] + win[1] + win[2];
            }
        }
    };
    let mut rows_in_ring = [usize::MAX; 3];
    for (y, dst) in out.chunks_exact_mut(w).enumerate() {
        let want = [
            reflect101(y as isize - 1, h),
            y,
            reflect101(y as isize + 1, h),
        ];
        for &r in &want {
            let slot = r % 3;
            if rows_in_ring[slot] != r {
                fill(r, &mut ring[slot]);
                rows_in_ring[slot] = r;
            }
        }
        let [a, b, c] = [&ring[want[0] % 3], &ring[want[1] % 3], &ring[want[2] % 3]];
        let sums = a[0]
            .iter()
            .zip(&b[0])
            .zip(&c[0])
            .zip(a[1].iter().zip(&b[1]).zip(&c[1]));
        let sums = sums.zip(a[2].iter().zip(&b[2]).zip(&c[2]));
        for (d, ((((xx0, xx1), xx2), ((xy0, xy1), xy2)), ((yy0, yy1), yy2))) in
            dst.iter_mut().zip(sums)
        {
            let sxx = (xx0 + xx1 + xx2) as f32 * 0.5;
            let sxy = (xy0 + xy1 + xy2) as f32;
            let syy = (yy0 + yy1 + yy2) as f32 * 0.5;
            *d = (sxx + syy) - ((sxx - syy) * (sxx - syy) + sxy * sxy).sqrt();
        }
    }
    image_like(img, out)
}

/// Detects Shi–Tomasi corners, strongest first.
pub fn shi_tomasi(img: &GrayImage, config: &ShiTomasiConfig) -> Result<Vec<Corner>, VisionError> {
    if !(config.quality_level > 0.0 && config.quality_level <= 1.0) {
        return Err(VisionError::config(
            "quality_level",
            config.quality_level,
            "must be in (0, 1]",
        ));
    }
    if !(config.min_distance_px >= 0.0 && config.min_distance_px.is_finite()) {
        return Err(VisionError::config(
            "min_distance_px",
            config.min_distance_px,
            "must be >= 0",
        ));
    }
    if config.grid_cols == 0 || config.grid_rows == 0 {
        return Err(VisionError::config(
            "grid_cols/grid_rows",
            config.grid_cols.min(config.grid_rows),
            "must be >= 1",
        ));
    }
    let eig = min_eigenvalue_map(img);
    let candidates = local_maxima(&eig, config.quality_level);
    Ok(select_spread(candidates, img.width(), img.height(), config))
}

/// 3×3 local maxima strictly inside the image with score above `quality × max`.
fn local_maxima(eig: &Image<f32>, quality: f32) -> Vec<Corner> {
    let (w, h) = (eig.width(), eig.height());
    let max = eig.data().iter().fold(0f32, |m, &v| m.max(v));
    let thresh = max * quality;
    let mut out = Vec::new();
    if w < 3 || h < 3 || max <= 0.0 {
        return out;
    }
    let d = eig.data();
    for y in 1..h - 1 {
        let (up, mid, dn) = (
            &d[(y - 1) * w..y * w],
            &d[y * w..(y + 1) * w],
            &d[(y + 1) * w..(y + 2) * w],
        );
        for x in 1..w - 1 {
            let v = mid[x];
            if v <= thresh {
                continue;
            }
            let is_max = v >= mid[x - 1]
                && v >= mid[x + 1]
                && up[x - 1..=x + 1].iter().all(|&u| v >= u)
                && dn[x - 1..=x + 1].iter().all(|&u| v >= u);
            if is_max {
                out.push(Corner {
                    x: x as f32,
                    y: y as f32,
                    score: v,
                });
            }
        }
    }
    out
}

/// Takes candidates strongest first, keeping the per-cell cap, the global cap and the minimum
/// distance (checked on a grid of `min_distance`-sized cells, as OpenCV).
fn select_spread(mut cand: Vec<Corner>, w: usize, h: usize, cfg: &ShiTomasiConfig) -> Vec<Corner> {
    // Strongest first; ties broken by position so the result is deterministic.
    cand.sort_unstable_by(|a, b| {
        b.score
            .total_cmp(&a.score)
            .then(a.y.total_cmp(&b.y))
            .then(a.x.total_cmp(&b.x))
    });
    let md = cfg.min_distance_px;
    let cell = md.max(1.0);
    let (gw, gh) = (
        (w as f32 / cell).ceil() as usize + 1,
        (h as f32 / cell).ceil() as usize + 1,
    );
    let mut taken: Vec<Vec<(f32, f32)>> = vec![Vec::new(); if md > 0.0 { gw * gh } else { 0 }];
    let mut per_cell = vec![0usize; cfg.grid_cols * cfg.grid_rows];
    let mut out = Vec::new();
    for c in cand {
        if cfg.max_corners > 0 && out.len() >= cfg.max_corners {
            break;
        }
        let bx = ((c.x as usize * cfg.grid_cols) / w.max(1)).min(cfg.grid_cols - 1);
        let by = ((c.y as usize * cfg.grid_rows) / h.max(1)).min(cfg.grid_rows - 1);
        let bucket = by * cfg.grid_cols + bx;
        if cfg.max_per_cell > 0 && per_cell[bucket] >= cfg.max_per_cell {
            continue;
        }
        if md > 0.0 {
            let (cx, cy) = ((c.x / cell) as usize, (c.y / cell) as usize);
            let near = (cy.saturating_sub(1)..=(cy + 1).min(gh - 1)).any(|yy| {
                (cx.saturating_sub(1)..=(cx + 1).min(gw - 1)).any(|xx| {
                    taken[yy * gw + xx]
                        .iter()
                        .any(|&(px, py)| (px - c.x).powi(2) + (py - c.y).powi(2) < md * md)
                })
            });
            if near {
                continue;
            }
            taken[cy * gw + cx].push((c.x, c.y));
        }
        per_cell[bucket] += 1;
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Black image with white squares: each square has four corners.
    fn squares(w: usize, h: usize, step: usize, size: usize) -> GrayImage {
        let mut img = Image::filled(w, h, 0u8);
        for y in 0..h {
            for x in 0..w {
                if x % step >= step - size && y % step >= step - size {
                    *img.get_mut(x, y).unwrap() = 255;
                }
            }
        }
        img
    }

    #[test]
    fn finds_square_corners() {
        let img = squares(100, 100, 50, 20);
        let cfg = ShiTomasiConfig {
            min_distance_px: 5.0,
            ..ShiTomasiConfig::default()
        };
        let c = shi_tomasi(&img, &cfg).unwrap();
        // four squares, four corners each (corners at 30/49 and 80/99; 99 is the border row)
        let near = |x: f32, y: f32| {
            c.iter()
                .any(|p| (p.x - x).abs() <= 1.5 && (p.y - y).abs() <= 1.5)
        };
        for &(x, y) in &[
            (30.0, 30.0),
            (49.0, 30.0),
            (30.0, 49.0),
            (49.0, 49.0),
            (80.0, 80.0),
        ] {
            assert!(near(x, y), "no corner near ({x},{y}): {c:?}");
        }
        for p in &c {
            assert!(p.score > 0.0);
        }
    }

    #[test]
    fn min_distance_and_caps_hold() {
        let img = squares(200, 200, 10, 5);
        let cfg = ShiTomasiConfig {
            min_distance_px: 7.0,
            grid_cols: 4,
            grid_rows: 4,
            max_per_cell: 3,
            ..ShiTomasiConfig::default()
        };
        let c = shi_tomasi(&img, &cfg).unwrap();
        assert!(!c.is_empty() && c.len() <= 48);
        for (i, a) in c.iter().enumerate() {
            for b in &c[i + 1..] {
                assert!((a.x - b.x).hypot(a.y - b.y) >= 7.0);
            }
        }
        let capped = shi_tomasi(
            &img,
            &ShiTomasiConfig {
                max_corners: 5,
                ..cfg
            },
        )
        .unwrap();
        assert_eq!(capped.len(), 5);
        assert!(capped.windows(2).all(|p| p[0].score >= p[1].score));
    }

    #[test]
    fn eigenvalue_map_matches_brute_force() {
        let img = Image::from_vec(9, 8, (0..72).map(|i| ((i * 97) % 251) as u8).collect()).unwrap();
        let eig = min_eigenvalue_map(&img);
        let g = sobel(&img);
        for y in 0..8isize {
            for x in 0..9isize {
                let (mut a, mut b, mut c) = (0f64, 0f64, 0f64);
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let (xx, yy) = (reflect101(x + dx, 9), reflect101(y + dy, 8));
                        let gx = f64::from(*g.gx.get(xx, yy).unwrap());
                        let gy = f64::from(*g.gy.get(xx, yy).unwrap());
                        a += gx * gx;
                        b += gx * gy;
                        c += gy * gy;
                    }
                }
                let want = (a + c) / 2.0 - (((a - c) / 2.0).powi(2) + b * b).sqrt();
                let got = f64::from(*eig.get(x as usize, y as usize).unwrap());
                assert!(
                    (got - want).abs() <= 1e-3 * want.abs().max(1.0),
                    "{got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn flat_and_bad_inputs() {
        let flat = Image::filled(20, 20, 9u8);
        assert!(shi_tomasi(&flat, &ShiTomasiConfig::default())
            .unwrap()
            .is_empty());
        let bad = ShiTomasiConfig {
            quality_level: f32::NAN,
            ..ShiTomasiConfig::default()
        };
        assert!(shi_tomasi(&flat, &bad).is_err());
    }
}
