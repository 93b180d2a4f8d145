//! Contrast Limited Adaptive Histogram Equalisation (K. Zuiderveld, "Contrast limited adaptive
//! histogram equalization", Graphics Gems IV, 1994), reproducing OpenCV's `createCLAHE`
//! (`modules/imgproc/src/clahe.cpp`) to ±1 grey level:
//!
//! 1. the image is cut into a grid of tiles (padded by reflect-101 at the bottom/right when the
//!    size is not a multiple of the grid, with OpenCV's quirk of then padding *both* axes);
//! 2. each tile's 256-bin histogram is clipped at `max(clip_limit·tile_area/256, 1)`, the excess
//!    spread evenly over all bins and the remainder one count per `256/residual` bins;
//! 3. its cumulative histogram, scaled by `255/tile_area`, is the tile's lookup table;
//! 4. each pixel blends the tables of its four nearest tile centres bilinearly.
//!
//! Colour images are equalised on the L\* channel of 8-bit CIELAB (OpenCV's
//! `RGB → Lab → CLAHE(L) → RGB`), so hue is preserved.

use serde::{Deserialize, Serialize};
use slamkit_core::image::{GrayImage, RgbImage};

use crate::border::reflect101;
use crate::color::{image_like, lab_planes_to_rgb, rgb_to_lab_planes};
use crate::error::VisionError;
use crate::round::round_to_u8;
use crate::simd::dispatch_avx2;

/// CLAHE parameters (`cv::createCLAHE(clipLimit, tileGridSize)`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClaheConfig {
    /// Contrast limit: a histogram bin may hold at most `clip_limit` times the mean bin count
    /// (≤ 0 disables clipping, i.e. plain adaptive equalisation). OpenCV's own default is 40;
    /// slamkit's 2.0 is what the VO front end was tuned with.
    pub clip_limit: f64,
    /// Number of tiles across \[tiles\].
    pub tiles_x: usize,
    /// Number of tiles down \[tiles\].
    pub tiles_y: usize,
}

impl Default for ClaheConfig {
    fn default() -> Self {
        Self {
            clip_limit: 2.0,
            tiles_x: 8,
            tiles_y: 8,
        }
    }
}

const BINS: usize = 256;

/// A CLAHE operator with its reusable buffers.
#[derive(Debug, Clone)]
pub struct Clahe {
    config: ClaheConfig,
    luts: Vec<u8>,
}

impl Clahe {
    /// Checks the configuration.
    pub fn new(config: ClaheConfig) -> Result<Self, VisionError> {
        if config.tiles_x == 0 || config.tiles_x > 1024 {
            return Err(VisionError::config(
                "tiles_x",
                config.tiles_x,
                "must be 1..=1024",
            ));
        }
        if config.tiles_y == 0 || config.tiles_y > 1024 {
            return Err(VisionError::config(
                "tiles_y",
                config.tiles_y,
                "must be 1..=1024",
            ));
        }
        if !config.clip_limit.is_finite() {
            return Err(VisionError::config(
                "clip_limit",
                config.clip_limit,
                "must be finite",
            ));
        }
        Ok(Self {
            config,
            luts: Vec::new(),
        })
    }

    /// Equalises a grey image.
    pub fn apply_gray(&mut self, img: &GrayImage) -> GrayImage {
        let (w, h) = (img.width(), img.height());
        if w == 0 || h == 0 {
            return img.clone();
        }
        let (tx, ty) = (self.config.tiles_x, self.config.tiles_y);
        // OpenCV pads both axes as soon as one is not a multiple of the grid.
        let (ew, eh) = if w % tx == 0 && h % ty == 0 {
            (w, h)
        } else {
            (w + tx - w % tx, h + ty - h % ty)
        };
        let (tw, th) = (ew / tx, eh / ty);
        self.compute_luts(img, tw, th);
        let mut out = vec![0u8; w * h];
        interpolate(img, &self.luts, (tx, ty), (tw, th), &mut out);
        image_like(img, out)
    }

    /// Equalises the lightness of an RGB image (through 8-bit CIELAB, as OpenCV).
    pub fn apply_rgb(&mut self, img: &RgbImage) -> RgbImage {
        let (l, ab) = rgb_to_lab_planes(img);
        let l = self.apply_gray(&l);
        match lab_planes_to_rgb(&l, &ab) {
            Some(rgb) => rgb,
            None => unreachable!("CLAHE keeps the size"),
        }
    }

    /// Builds one 256-entry table per tile from the (virtually padded) image.
    fn compute_luts(&mut self, img: &GrayImage, tw: usize, th: usize) {
        let (tx, ty) = (self.config.tiles_x, self.config.tiles_y);
        let (w, h) = (img.width(), img.height());
        let area = tw * th;
        let clip = if self.config.clip_limit > 0.0 {
            Some(((self.config.clip_limit * area as f64 / BINS as f64) as u32).max(1))
        } else {
            None
        };
        let lut_scale = (BINS - 1) as f32 / area as f32;
        self.luts.clear();
        self.luts.resize(tx * ty * BINS, 0);
        let data = img.data();
        let mut hist = vec![[0u32; BINS]; tx];
        for (band, luts) in self.luts.chunks_exact_mut(tx * BINS).enumerate() {
            hist.iter_mut().for_each(|hh| hh.fill(0));
            for y in band * th..(band + 1) * th {
                let sy = reflect101(y as isize, h);
                let row = &data[sy * w..(sy + 1) * w];
                for (t, hh) in hist.iter_mut().enumerate() {
                    let (x0, x1) = (t * tw, (t + 1) * tw);
                    let inside = &row[x0.min(w)..x1.min(w)];
                    for &v in inside {
                        hh[usize::from(v)] += 1;
                    }
                    for x in x1.min(w).max(x0)..x1 {
                        hh[usize::from(row[reflect101(x as isize, w)])] += 1;
                    }
                }
            }
            for (hh, lut) in hist.iter_mut().zip(luts.chunks_exact_mut(BINS)) {
                if let Some(c) = clip {
                    clip_histogram(hh, c);
                }
                let mut sum = 0u32;
                for (l, &c) in lut.iter_mut().zip(hh.iter()) {
                    sum += c;
                    *l = round_to_u8(sum as f32 * lut_scale);
                }
            }
        }
    }
}

/// Clips bins at `limit` and redistributes the excess as OpenCV does.
fn clip_histogram(hist: &mut [u32; BINS], limit: u32) {
    let mut clipped = 0u32;
    for c in hist.iter_mut() {
        if *c > limit {
            clipped += *c - limit;
            *c = limit;
        }
    }
    let batch = clipped / BINS as u32;
    let mut residual = clipped as usize - batch as usize * BINS;
    for c in hist.iter_mut() {
        *c += batch;
    }
    if let Some(step) = BINS.checked_div(residual) {
        let step = step.max(1);
        let mut i = 0;
        while i < BINS && residual > 0 {
            hist[i] += 1;
            i += step;
            residual -= 1;
        }
    }
}

/// Per-column tile indices and weights of the bilinear blend (OpenCV's float formula).
struct ColumnTaps {
    lut1: Vec<usize>,
    lut2: Vec<usize>,
    wa: Vec<f32>,
}

fn column_taps(w: usize, tiles: usize, tile_w: usize) -> ColumnTaps {
    let inv = 1.0f32 / tile_w as f32;
    let mut t = ColumnTaps {
        lut1: Vec::with_capacity(w),
        lut2: Vec::with_capacity(w),
        wa: Vec::with_capacity(w),
    };
    for x in 0..w {
        let f = x as f32 * inv - 0.5;
        let t1 = f.floor();
        t.wa.push(f - t1);
        let t1 = t1 as isize;
        t.lut1.push(t1.max(0) as usize * BINS);
        t.lut2.push(((t1 + 1) as usize).min(tiles - 1) * BINS);
    }
    t
}

dispatch_avx2! {
    /// Blends the four nearest tiles' tables per pixel (OpenCV's float formula).
    fn interpolate(
        img: &GrayImage,
        luts: &[u8],
        tiles: (usize, usize),
        tile_size: (usize, usize),
        out: &mut [u8],
    );
    /// [`interpolate`]'s body. Per row, the four table look-ups of every pixel are gathered first
    /// (scalar loads), then the blend runs over the row in `f32` lanes, with the same operations in
    /// the same order as a per-pixel loop.
    portable interpolate_portable {
        let (tx, ty) = tiles;
        let (tw, th) = tile_size;
        let w = img.width();
        let cols = column_taps(w, tx, tw);
        let inv_th = 1.0f32 / th as f32;
        let mut taps = [vec![0u8; w], vec![0u8; w], vec![0u8; w], vec![0u8; w]];
        for (y, (src, dst)) in img
            .data()
            .chunks_exact(w)
            .zip(out.chunks_exact_mut(w))
            .enumerate()
        {
            let f = y as f32 * inv_th - 0.5;
            let t1 = f.floor();
            let ya = f - t1;
            let ya1 = 1.0 - ya;
            let t1 = t1 as isize;
            let row1 = t1.max(0) as usize * tx * BINS;
            let row2 = ((t1 + 1) as usize).min(ty - 1) * tx * BINS;
            let (p1, p2) = (&luts[row1..row1 + tx * BINS], &luts[row2..row2 + tx * BINS]);
            let [t11, t12, t21, t22] = &mut taps;
            let cols_of = cols.lut1.iter().zip(&cols.lut2);
            let gathered = t11
                .iter_mut()
                .zip(t12.iter_mut())
                .zip(t21.iter_mut().zip(t22.iter_mut()));
            for (((a, b), (c, d)), (&v, (&i1, &i2))) in gathered.zip(src.iter().zip(cols_of)) {
                let v = usize::from(v);
                let (a1, a2) = (i1 + v, i2 + v);
                (*a, *b, *c, *d) = (p1[a1], p1[a2], p2[a1], p2[a2]);
            }
            let blend = t11.iter().zip(t12.iter()).zip(t21.iter().zip(t22.iter()));
            for (d, (((&a, &b), (&c, &e)), &xa)) in dst.iter_mut().zip(blend.zip(&cols.wa)) {
                let xa1 = 1.0 - xa;
                let top = f32::from(a) * xa1 + f32::from(b) * xa;
                let bottom = f32::from(c) * xa1 + f32::from(e) * xa;
                *d = round_to_u8(top * ya1 + bottom * ya);
            }
        }
    }
}

/// One-shot CLAHE of a grey image (see [`Clahe`] to reuse buffers across frames).
pub fn clahe_gray(img: &GrayImage, config: &ClaheConfig) -> Result<GrayImage, VisionError> {
    Ok(Clahe::new(config.clone())?.apply_gray(img))
}

/// One-shot CLAHE of an RGB image on its L\* channel.
pub fn clahe_rgb(img: &RgbImage, config: &ClaheConfig) -> Result<RgbImage, VisionError> {
    Ok(Clahe::new(config.clone())?.apply_rgb(img))
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_core::image::Image;

    #[test]
    fn clipping_redistributes_like_opencv() {
        let mut h = [0u32; BINS];
        h[10] = 1000;
        h[20] = 5;
        clip_histogram(&mut h, 8);
        // excess 992 -> 3 per bin + residual 224 -> one extra every 256/224 = 1 bin
        assert_eq!(h[10], 8 + 3 + 1);
        assert_eq!(h[20], 5 + 3 + 1);
        assert_eq!(h[223], 3 + 1);
        assert_eq!(h[224], 3);
        assert_eq!(h.iter().sum::<u32>(), 1005);
    }

    /// The row-wise interpolation (portable and AVX2 builds) equals OpenCV's per-pixel blend.
    #[test]
    fn interpolation_matches_the_per_pixel_blend() {
        let (w, h) = (75, 53);
        let img = Image::from_vec(
            w,
            h,
            (0..(w * h) as u32)
                .map(|i| ((i.wrapping_mul(2_654_435_761) >> 26) as u8).wrapping_add((i % 75) as u8))
                .collect(),
        )
        .unwrap();
        for (tx, ty) in [(8, 8), (3, 5), (1, 1)] {
            let mut clahe = Clahe::new(ClaheConfig {
                tiles_x: tx,
                tiles_y: ty,
                ..ClaheConfig::default()
            })
            .unwrap();
            let (tw, th) = ((w + tx - w % tx) / tx, (h + ty - h % ty) / ty);
            clahe.compute_luts(&img, tw, th);
            let luts = &clahe.luts;
            let cols = column_taps(w, tx, tw);
            let mut want = Vec::new();
            for y in 0..h {
                let f = y as f32 * (1.0 / th as f32) - 0.5;
                let t1 = f.floor();
                let ya = f - t1;
                let t1 = t1 as isize;
                let row1 = t1.max(0) as usize * tx * BINS;
                let row2 = ((t1 + 1) as usize).min(ty - 1) * tx * BINS;
                for x in 0..w {
                    let v = usize::from(*img.get(x, y).unwrap());
                    let (a1, a2) = (cols.lut1[x] + v, cols.lut2[x] + v);
                    let xa = cols.wa[x];
                    let at = |i| f32::from(luts[i]);
                    let top = at(row1 + a1) * (1.0 - xa) + at(row1 + a2) * xa;
                    let bottom = at(row2 + a1) * (1.0 - xa) + at(row2 + a2) * xa;
                    let o = (top * (1.0 - ya) + bottom * ya).clamp(0.0, 255.0);
                    want.push(o.round_ties_even() as u8);
                }
            }
            let mut got = vec![0u8; w * h];
            interpolate(&img, luts, (tx, ty), (tw, th), &mut got);
            assert_eq!(got, want, "{tx}x{ty}");
            interpolate_portable(&img, luts, (tx, ty), (tw, th), &mut got);
            assert_eq!(got, want, "{tx}x{ty}");
        }
    }

    #[test]
    fn constant_image_maps_through_its_cdf() {
        let img = Image::filled(64, 64, 100u8);
        let out = clahe_gray(&img, &ClaheConfig::default()).unwrap();
        // tile 8x8 = 64 px, clip = max(2*64/256, 1) = 1: all excess spread evenly,
        // lut[100] = round(101 * 64/256 * 255/64)... computed by the same formula:
        let clip = 1u32;
        let mut h = [0u32; BINS];
        h[100] = 64;
        clip_histogram(&mut h, clip);
        let cdf: u32 = h[..=100].iter().sum();
        let want = round_to_u8(cdf as f32 * (255.0 / 64.0));
        assert!(out.data().iter().all(|&v| v == want), "want {want}");
    }

    #[test]
    fn bad_config_is_an_error() {
        let bad = ClaheConfig {
            tiles_x: 0,
            ..ClaheConfig::default()
        };
        assert!(Clahe::new(bad).is_err());
        let nan = ClaheConfig {
            clip_limit: f64::NAN,
            ..ClaheConfig::default()
        };
        assert!(Clahe::new(nan).is_err());
    }

    #[test]
    fn odd_sizes_and_tiny_images_work() {
        let img = Image::from_vec(13, 7, (0..91).map(|i| (i * 37 % 256) as u8).collect()).unwrap();
        let out = clahe_gray(&img, &ClaheConfig::default()).unwrap();
        assert_eq!((out.width(), out.height()), (13, 7));
        let one = Image::filled(1, 1, 5u8);
        assert_eq!(
            clahe_gray(&one, &ClaheConfig::default())
                .unwrap()
                .data()
                .len(),
            1
        );
        let rgb = Image::filled(9, 9, [200u8, 40, 40]);
        assert_eq!(
            clahe_rgb(&rgb, &ClaheConfig::default())
                .unwrap()
                .data()
                .len(),
            81
        );
    }
}
