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
//! Confidence in \[0, 1\] plays the role of a stereo camera's confidence map (the ZED's): the best
//! ZNCC score, scaled down when another disparity outside ±1 px of the best scores nearly as
//! well (ambiguous, repetitive texture). Points below `min_confidence` get no disparity.

use serde::{Deserialize, Serialize};
use slamkit_core::image::GrayImage;

use crate::error::VisionError;

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

/// Window rows are padded with zeros to a multiple of this many columns, so that the dot
/// product runs in whole 8-lane `i16 × i16 → i32` steps (SSE2 `pmaddwd`) without a scalar tail.
const LANES: usize = 8;

/// A rectified pair prepared for matching: the right image widened to `i16` and its integral
/// images.
#[derive(Debug, Clone)]
pub struct StereoPair<'a> {
    left: &'a GrayImage,
    right: &'a GrayImage,
    /// The right image as `i16`, followed by `LANES` zeros so that a padded window row never
    /// leaves the buffer.
    right16: Vec<i16>,
    /// `(width + 1) × (height + 1)` integral of the right image.
    sum: Vec<u64>,
    /// Integral of the squared right image.
    sum_sq: Vec<u64>,
}

impl<'a> StereoPair<'a> {
    /// Prepares `left`/`right` (rectified, same size) for matching.
    ///
    /// # Errors
    /// [`VisionError::SizeMismatch`] when the images differ in size.
    pub fn new(left: &'a GrayImage, right: &'a GrayImage) -> Result<Self, VisionError> {
        if (left.width(), left.height()) != (right.width(), right.height()) {
            return Err(VisionError::SizeMismatch {
                a_width: left.width(),
                a_height: left.height(),
                b_width: right.width(),
                b_height: right.height(),
            });
        }
        let (w, h) = (right.width(), right.height());
        let stride = w + 1;
        let mut sum = vec![0u64; stride * (h + 1)];
        let mut sum_sq = vec![0u64; stride * (h + 1)];
        for (y, row) in right.data().chunks_exact(w.max(1)).enumerate().take(h) {
            let (mut s, mut s2) = (0u64, 0u64);
            for (x, &v) in row.iter().enumerate() {
                s += u64::from(v);
                s2 += u64::from(v) * u64::from(v);
                let i = (y + 1) * stride + x + 1;
                sum[i] = sum[i - stride] + s;
                sum_sq[i] = sum_sq[i - stride] + s2;
            }
        }
        let mut right16: Vec<i16> = right.data().iter().map(|&v| i16::from(v)).collect();
        right16.resize(right16.len() + LANES, 0);
        Ok(Self {
            left,
            right,
            right16,
            sum,
            sum_sq,
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
        let mut scores = Vec::with_capacity(config.max_disparity_px + 1);
        let side = 2 * config.half_window_px + 1;
        let mut patch = Patch {
            values: Vec::with_capacity(side * side.next_multiple_of(LANES)),
            sum: 0,
            norm: 0.0,
        };
        Ok(points
            .iter()
            .map(|&p| self.match_point(p, config, &mut patch, &mut scores))
            .collect())
    }

    fn match_point(
        &self,
        (x, y): (f32, f32),
        config: &StereoConfig,
        patch: &mut Patch,
        scores: &mut Vec<f32>,
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
        left_patch(self.left, xi, yi, r, patch, config.min_texture)?;
        // candidate right column xr = xi − d must keep its window inside: xr ≥ r
        let d_max = config.max_disparity_px.min(xi - r);
        if d_max < config.min_disparity_px {
            return None;
        }
        scores.clear();
        for d in config.min_disparity_px..=d_max {
            scores.push(self.zncc(patch, xi - d, yi, r));
        }
        let (best, &s1) = scores
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))?;
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

    /// ZNCC of the left `patch` with the right window centred at (`xr`, `y`).
    fn zncc(&self, patch: &Patch, xr: usize, y: usize, r: usize) -> f32 {
        let side = 2 * r + 1;
        let n = (side * side) as f32;
        let stride = self.right.width() + 1;
        let (x0, y0, x1, y1) = (xr - r, y - r, xr + r + 1, y + r + 1);
        let rect = |s: &[u64]| {
            s[y1 * stride + x1] + s[y0 * stride + x0] - s[y0 * stride + x1] - s[y1 * stride + x0]
        };
        let sum = rect(&self.sum) as f32;
        let var = rect(&self.sum_sq) as f32 - sum * sum / n;
        if var <= 1e-3 {
            return -1.0;
        }
        let w = self.right.width();
        let padded = side.next_multiple_of(LANES);
        // integer dot product over zero-padded rows (exact), in eight i32 lanes reduced once per
        // window
        let mut acc = [0i32; LANES];
        for (row, prow) in (y0..y1).zip(patch.values.chunks_exact(padded)) {
            let start = row * w + x0;
            let Some(rrow) = self.right16.get(start..start + padded) else {
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
        let dot: i32 = acc.iter().sum();
        // Σ (l − l̄)(r − r̄) = Σ l′r − (Σ l′)(Σ r)/n for l′ = l − any constant
        let cov = f64::from(dot) - f64::from(patch.sum) * f64::from(sum) / f64::from(n);
        (cov / f64::from(patch.norm * var.sqrt())) as f32
    }
}

/// A left window: grey levels minus their rounded mean (each row followed by zeros up to a
/// multiple of `LANES` columns), their sum and the window's centred norm `sqrt(Σ (l − l̄)²)`.
struct Patch {
    values: Vec<i16>,
    sum: i32,
    norm: f32,
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
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random-texture left image, smoothed horizontally so that sub-pixel shifts are defined,
    /// and the right image shifted left by `disparity` px (linear interpolation).
    fn pair(disparity: f32) -> (GrayImage, GrayImage) {
        let (w, h) = (160, 60);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let raw: Vec<f32> = (0..w * h).map(|_| rng.gen_range(0.0..255.0)).collect();
        let smooth = |x: f32, y: usize| {
            let x0 = x.floor().clamp(0.0, (w - 2) as f32);
            let t = x - x0;
            let x0 = x0 as usize;
            let at = |xx: usize| {
                (raw[y * w + xx.saturating_sub(1)]
                    + 2.0 * raw[y * w + xx]
                    + raw[y * w + (xx + 1).min(w - 1)])
                    / 4.0
            };
            at(x0) * (1.0 - t) + at(x0 + 1) * t
        };
        let left = (0..w * h)
            .map(|i| smooth((i % w) as f32, i / w) as u8)
            .collect();
        let right = (0..w * h)
            .map(|i| smooth((i % w) as f32 + disparity, i / w) as u8)
            .collect();
        (
            GrayImage::from_vec(w, h, left).unwrap(),
            GrayImage::from_vec(w, h, right).unwrap(),
        )
    }

    #[test]
    fn recovers_sub_pixel_disparity() {
        for truth in [7.0f32, 12.25, 20.5] {
            let (l, r) = pair(truth);
            let pairing = StereoPair::new(&l, &r).unwrap();
            // sub-pixel positions: the disparity must not follow the rounding of x
            let pts: Vec<(f32, f32)> = (0..10)
                .map(|i| (60.4 + 8.0 * i as f32 - 0.1 * i as f32, 30.0))
                .collect();
            let got = pairing
                .match_points(&pts, &StereoConfig::default())
                .unwrap();
            for m in &got {
                let m = m.expect("textured point matched");
                assert!(
                    (m.disparity_px - truth).abs() < 0.3,
                    "{} vs {truth}",
                    m.disparity_px
                );
                assert!(m.confidence > 0.8, "{}", m.confidence);
            }
        }
    }

    /// The padded integer ZNCC equals the textbook formula in f64.
    #[test]
    fn zncc_matches_the_definition() {
        let (l, r) = pair(9.5);
        let pairing = StereoPair::new(&l, &r).unwrap();
        let rad = 9;
        let mut patch = Patch {
            values: Vec::new(),
            sum: 0,
            norm: 0.0,
        };
        let window = |img: &GrayImage, x: usize, y: usize| -> Vec<f64> {
            (y - rad..=y + rad)
                .flat_map(|yy| (x - rad..=x + rad).map(move |xx| (xx, yy)))
                .map(|(xx, yy)| f64::from(*img.get(xx, yy).unwrap()))
                .collect()
        };
        for (x, y, d) in [(60, 30, 9), (70, 20, 3), (150, 50, 40), (40, 9, 30)] {
            left_patch(&l, x, y, rad, &mut patch, 0.0).unwrap();
            let got = pairing.zncc(&patch, x - d, y, rad);
            let (a, b) = (window(&l, x, y), window(&r, x - d, y));
            let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
            let (ma, mb) = (mean(&a), mean(&b));
            let cov: f64 = a.iter().zip(&b).map(|(p, q)| (p - ma) * (q - mb)).sum();
            let var = |v: &[f64], m: f64| v.iter().map(|p| (p - m).powi(2)).sum::<f64>();
            let want = cov / (var(&a, ma) * var(&b, mb)).sqrt();
            assert!((f64::from(got) - want).abs() < 1e-3, "{got} vs {want}");
        }
    }

    #[test]
    fn flat_and_repetitive_windows_get_no_disparity() {
        let flat = GrayImage::filled(80, 40, 100u8);
        let pairing = StereoPair::new(&flat, &flat).unwrap();
        let got = pairing
            .match_points(&[(40.0, 20.0)], &StereoConfig::default())
            .unwrap();
        assert_eq!(got, vec![None]);
        // vertical stripes of period 4 px: every fourth disparity fits equally well
        let stripes = GrayImage::from_vec(
            80,
            40,
            (0..3200)
                .map(|i| if i % 4 < 2 { 40 } else { 200 })
                .collect(),
        )
        .unwrap();
        let pairing = StereoPair::new(&stripes, &stripes).unwrap();
        let got = pairing
            .match_points(&[(60.0, 20.0)], &StereoConfig::default())
            .unwrap();
        assert_eq!(got, vec![None]);
    }

    #[test]
    fn bad_input_is_an_error_or_none() {
        let a = GrayImage::filled(80, 40, 0u8);
        let b = GrayImage::filled(81, 40, 0u8);
        assert!(StereoPair::new(&a, &b).is_err());
        let pairing = StereoPair::new(&a, &a).unwrap();
        let bad = StereoConfig {
            min_disparity_px: 10,
            max_disparity_px: 5,
            ..Default::default()
        };
        assert!(pairing.match_points(&[(40.0, 20.0)], &bad).is_err());
        let got = pairing
            .match_points(
                &[(f32::NAN, 1.0), (-5.0, 3.0), (2.0, 20.0)],
                &StereoConfig::default(),
            )
            .unwrap();
        assert_eq!(got, vec![None, None, None]);
    }
}
