//! FAST-9 corners (E. Rosten and T. Drummond, "Machine learning for high-speed corner
//! detection", ECCV 2006): a pixel is a corner when 9 contiguous pixels of the 16 on a
//! radius-3 Bresenham circle are all brighter than it by more than `threshold`, or all darker.
//! Its score is the largest threshold for which that still holds (OpenCV's `cornerScore`), and
//! non-maximum suppression keeps corners whose score beats all 8 neighbours.
//!
//! Rows are processed in chunks of 32 pixels with lane-wise (vectorised) arithmetic, as OpenCV's
//! SIMD FAST: any 9-arc contains a pixel of each of the 8 opposite pairs, so the four compass
//! pixels first, then all 8 pairs, reject most chunks; then the full segment test
//! counts, per lane, the run of consecutive brighter (darker) circle pixels over 25 steps
//! around the circle. Only corners get a score, from sliding minima over the circle.

use slamkit_core::image::GrayImage;

use crate::simd::dispatch_avx2;
/// Circle offsets (dx, dy), clockwise from straight below, as OpenCV's `offsets16`.
const CIRCLE: [(isize, isize); 16] = [
    (0, 3),
    (1, 3),
    (2, 2),
    (3, 1),
    (3, 0),
    (3, -1),
    (2, -2),
    (1, -3),
    (0, -3),
    (-1, -3),
    (-2, -2),
    (-3, -1),
    (-3, 0),
    (-3, 1),
    (-2, 2),
    (-1, 3),
];

/// A FAST corner at integer pixel position with its score (≥ the detection threshold).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FastCorner {
    /// Column \[px\].
    pub x: usize,
    /// Row \[px\].
    pub y: usize,
    /// Largest threshold at which this is still a corner.
    pub score: u8,
}

dispatch_avx2! {
    /// Detects FAST-9 corners at least `border` (≥ 3) pixels from every edge, optionally with
    /// 3×3 non-maximum suppression. Corners come row by row, left to right.
    pub fn fast9(img: &GrayImage, threshold: u8, border: usize, nonmax: bool) -> Vec<FastCorner>;
    portable fast9_portable {
        let (w, h) = (img.width(), img.height());
        let border = border.max(3);
        if w <= 2 * border || h <= 2 * border {
            return Vec::new();
        }
        let mut rows = RowDetector::new(img, border, threshold);
        let mut corners = Vec::new();
        if !nonmax {
            for y in border..h - border {
                rows.detect(y, &mut corners, &mut []);
            }
            return corners;
        }
        // Scores (+1, 0 = no corner) of the last three rows, row y in slot y mod 3: a row's corners
        // are suppressed once the row below it is scored.
        let mut scores = vec![0u8; 3 * w];
        let (mut above, mut current) = (Vec::new(), Vec::new());
        for y in border..=h - border {
            let slot = (y % 3) * w;
            scores[slot..slot + w].fill(0);
            if y < h - border {
                rows.detect(y, &mut current, &mut scores[slot..slot + w]);
            }
            let row = |dy: usize| {
                let s = ((y + 3 - dy) % 3) * w;
                &scores[s..s + w]
            };
            let (up, mid, dn) = (row(2), row(1), row(0));
            corners.extend(above.drain(..).filter(|k: &FastCorner| {
                let (x, s) = (k.x, mid[k.x]);
                let beaten = |r: &[u8]| r[x - 1] >= s || r[x] >= s || r[x + 1] >= s;
                !(beaten(up) || beaten(dn) || mid[x - 1] >= s || mid[x + 1] >= s)
            }));
            std::mem::swap(&mut above, &mut current);
        }
        corners
    }
}

/// Pixels tested together.
const LANES: usize = 32;
type Lanes = [u8; LANES];
const ZERO: Lanes = [0; LANES];

/// Per-row FAST-9 of one image, with its circle offsets and a zero-padded copy for the chunks
/// that would run past the image.
struct RowDetector<'a> {
    data: &'a [u8],
    w: usize,
    border: usize,
    threshold: u8,
    offsets: [isize; 16],
    tail: [Lanes; 17],
}

impl<'a> RowDetector<'a> {
    #[inline(always)]
    fn new(img: &'a GrayImage, border: usize, threshold: u8) -> Self {
        let w = img.width();
        Self {
            data: img.data(),
            w,
            border,
            threshold,
            offsets: CIRCLE.map(|(dx, dy)| dy * w as isize + dx),
            tail: [[0u8; LANES]; 17],
        }
    }

    /// Appends the corners of row `y` to `out`; when `scores` is a row long, also writes each
    /// corner's score + 1 there.
    #[inline(always)]
    fn detect(&mut self, y: usize, out: &mut Vec<FastCorner>, scores: &mut [u8]) {
        let (w, border) = (self.w, self.border);
        // the farthest circle pixel is 3 rows and 3 columns away
        let reach = 3 * w + 3 + LANES;
        for x0 in (border..w - border).step_by(LANES) {
            let c0 = y * w + x0;
            let mut starts = [c0; 17];
            for (s, &o) in starts.iter_mut().zip(&self.offsets) {
                *s = c0.wrapping_add_signed(o);
            }
            let mut chunks = [&ZERO; 17];
            if c0 + reach <= self.data.len() {
                for (c, &s) in chunks.iter_mut().zip(&starts) {
                    *c = as_lanes(&self.data[s..]);
                }
            } else {
                for (t, &s) in self.tail.iter_mut().zip(&starts) {
                    *t = load(self.data, s);
                }
                for (c, t) in chunks.iter_mut().zip(&self.tail) {
                    *c = t;
                }
            }
            let (ring, centre) = chunks.split_at(16);
            let (Ok(ring), [centre]) = (<&[&Lanes; 16]>::try_from(ring), centre) else {
                continue;
            };
            let mut found = segment_test(centre, ring, self.threshold);
            let lanes = (w - border - x0).min(LANES);
            if lanes < LANES {
                found &= (1u32 << lanes) - 1;
            }
            while found != 0 {
                let lane = found.trailing_zeros() as usize;
                found &= found - 1;
                let mut circle = [0u8; 16];
                for (c, r) in circle.iter_mut().zip(ring) {
                    *c = r[lane];
                }
                let score = corner_score(centre[lane], &circle, self.threshold);
                out.push(FastCorner {
                    x: x0 + lane,
                    y,
                    score,
                });
                if let Some(s) = scores.get_mut(x0 + lane) {
                    *s = score.saturating_add(1);
                }
            }
        }
    }
}

/// The first `LANES` pixels of `s` (which the caller makes at least that long).
#[inline(always)]
fn as_lanes(s: &[u8]) -> &Lanes {
    s.get(..LANES)
        .and_then(|s| <&Lanes>::try_from(s).ok())
        .unwrap_or(&ZERO)
}

/// `LANES` pixels from `start`; lanes past the end of the image are 0 (and masked by the caller).
#[inline(always)]
fn load(data: &[u8], start: usize) -> Lanes {
    let mut out = [0u8; LANES];
    if let Some(s) = data.get(start..start + LANES) {
        out.copy_from_slice(s);
    } else if let Some(s) = data.get(start..) {
        out[..s.len()].copy_from_slice(s);
    }
    out
}

/// Bit `i` set when lane `i` of `m` is true.
#[inline(always)]
fn bits(m: &[bool; LANES]) -> u32 {
    m.iter()
        .enumerate()
        .fold(0, |acc, (i, &b)| acc | (u32::from(b) << i))
}

/// Lane-wise segment test: bit `i` set when 9 contiguous circle pixels of lane `i` are all
/// brighter than `centre + t`, or all darker than `centre − t`.
#[inline(always)]
fn segment_test(centre: &Lanes, ring: &[&Lanes; 16], t: u8) -> u32 {
    let hi = centre.map(|v| v.saturating_add(t));
    let lo = centre.map(|v| v.saturating_sub(t));
    // Any 9-arc holds one pixel of every opposite pair (k, k + 8): the compass pairs first
    // (which reject most chunks), then the other six.
    let mut pass = [false; LANES];
    for (i, p) in pass.iter_mut().enumerate() {
        let b = |k: usize| (ring[k][i] > hi[i]) | (ring[k + 8][i] > hi[i]);
        let d = |k: usize| (ring[k][i] < lo[i]) | (ring[k + 8][i] < lo[i]);
        *p = (b(0) & b(4)) | (d(0) & d(4));
    }
    if bits(&pass) == 0 {
        return 0;
    }
    for (i, p) in pass.iter_mut().enumerate() {
        let b = |k: usize| (ring[k][i] > hi[i]) | (ring[k + 8][i] > hi[i]);
        let d = |k: usize| (ring[k][i] < lo[i]) | (ring[k + 8][i] < lo[i]);
        let bright = b(0) & b(1) & b(2) & b(3) & b(4) & b(5) & b(6) & b(7);
        let dark = d(0) & d(1) & d(2) & d(3) & d(4) & d(5) & d(6) & d(7);
        *p = bright | dark;
    }
    if bits(&pass) == 0 {
        return 0;
    }
    // run lengths of brighter (darker) pixels, 0xFF/0x00 masks, over 25 steps around the circle
    let (mut run_b, mut run_d, mut max_b, mut max_d) =
        ([0u8; LANES], [0u8; LANES], [0u8; LANES], [0u8; LANES]);
    for k in 0..25 {
        let r = &ring[k % 16];
        for i in 0..LANES {
            let b = u8::from(r[i] > hi[i]).wrapping_neg();
            let d = u8::from(r[i] < lo[i]).wrapping_neg();
            run_b[i] = (run_b[i] + 1) & b;
            run_d[i] = (run_d[i] + 1) & d;
            max_b[i] = max_b[i].max(run_b[i]);
            max_d[i] = max_d[i].max(run_d[i]);
        }
    }
    let mut corner = [false; LANES];
    for (c, (&b, &d)) in corner.iter_mut().zip(max_b.iter().zip(&max_d)) {
        *c = b >= 9 || d >= 9;
    }
    bits(&corner)
}

/// Score of a corner: the largest threshold at which it still passes, i.e. over all 9-arcs the
/// best smallest difference to the centre (brighter or darker) minus one (the test is strict),
/// at least `t`. Arc minima come from sliding minima of widths 2, 4, 8, 9.
#[inline(always)]
fn corner_score(v: u8, ring: &[u8; 16], t: u8) -> u8 {
    // d[k] = ring[k mod 16] − v and its negation, over 25 positions (arcs that wrap around)
    let (mut pos, mut neg) = ([0i16; 25], [0i16; 25]);
    for (k, (p, n)) in pos.iter_mut().zip(neg.iter_mut()).enumerate() {
        *p = i16::from(ring[k % 16]) - i16::from(v);
        *n = -*p;
    }
    let best = |d: &[i16; 25]| -> i16 {
        let mut m2 = [0i16; 24];
        for (i, m) in m2.iter_mut().enumerate() {
            *m = d[i].min(d[i + 1]);
        }
        let mut m4 = [0i16; 22];
        for (i, m) in m4.iter_mut().enumerate() {
            *m = m2[i].min(m2[i + 2]);
        }
        let mut m9 = [0i16; 16];
        for (i, m) in m9.iter_mut().enumerate() {
            *m = m4[i].min(m4[i + 4]).min(d[i + 8]);
        }
        m9.iter().fold(i16::MIN, |a, &b| a.max(b))
    };
    (best(&pos).max(best(&neg)) - 1).clamp(i16::from(t), 255) as u8
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use slamkit_core::image::Image;

    /// Whether the 16-bit circular mask has 9 consecutive set bits.
    fn has_arc9(m: u32) -> bool {
        (0..16).any(|s| (0..9).all(|k| m >> ((s + k) % 16) & 1 == 1))
    }

    /// FAST-9 by the definition, one pixel at a time: the reference for the chunked kernel.
    fn fast9_reference(img: &GrayImage, t: u8, border: usize, nonmax: bool) -> Vec<FastCorner> {
        let (w, h) = (img.width() as isize, img.height() as isize);
        let b = border.max(3) as isize;
        let at = |x: isize, y: isize| *img.get(x as usize, y as usize).unwrap();
        let mut found = Vec::new();
        for y in b..h - b {
            for x in b..w - b {
                let v = at(x, y);
                let ring = CIRCLE.map(|(dx, dy)| at(x + dx, y + dy));
                let mask = |f: &dyn Fn(u8) -> bool| {
                    (0..16).fold(0u32, |m, k| m | u32::from(f(ring[k])) << k)
                };
                let bright = mask(&|p| i16::from(p) > i16::from(v) + i16::from(t));
                let dark = mask(&|p| i16::from(p) < i16::from(v) - i16::from(t));
                if !has_arc9(bright) && !has_arc9(dark) {
                    continue;
                }
                // the largest threshold that still passes
                let score = (t..=254)
                    .take_while(|&s| {
                        let bb = mask(&|p| i16::from(p) > i16::from(v) + i16::from(s));
                        let dd = mask(&|p| i16::from(p) < i16::from(v) - i16::from(s));
                        has_arc9(bb) || has_arc9(dd)
                    })
                    .last()
                    .unwrap_or(t);
                found.push((x, y, score));
            }
        }
        let score_at = |x: isize, y: isize| {
            found
                .iter()
                .find(|c| c.0 == x && c.1 == y)
                .map_or(0, |c| i16::from(c.2) + 1)
        };
        found
            .iter()
            .filter(|&&(x, y, s)| {
                !nonmax
                    || (-1..=1).all(|dy| {
                        (-1..=1).all(|dx| {
                            (dx == 0 && dy == 0) || i16::from(s) + 1 > score_at(x + dx, y + dy)
                        })
                    })
            })
            .map(|&(x, y, score)| FastCorner {
                x: x as usize,
                y: y as usize,
                score,
            })
            .collect()
    }

    fn texture(w: usize, h: usize, seed: u64) -> GrayImage {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let noise = Image::from_vec(w, h, (0..w * h).map(|_| rng.gen()).collect()).unwrap();
        crate::filter::gaussian_blur(&noise, 3, 0.8).unwrap()
    }

    /// The chunked kernel, with and without AVX2, equals the per-pixel definition on textured
    /// images of widths that are and are not multiples of the chunk, including rows shorter
    /// than one chunk.
    #[test]
    fn chunked_test_matches_the_definition() {
        for (i, &(w, h, t, border, nonmax)) in [
            (64, 20, 20u8, 3usize, true),
            (77, 23, 10, 3, false),
            (77, 23, 10, 3, true),
            (45, 40, 25, 7, true),
            (20, 12, 5, 3, true),
            (140, 80, 30, 31, false),
        ]
        .iter()
        .enumerate()
        {
            let img = texture(w, h, i as u64);
            let want = fast9_reference(&img, t, border, nonmax);
            assert!(!want.is_empty(), "case {i} has no corner");
            assert_eq!(fast9(&img, t, border, nonmax), want, "case {i}");
            assert_eq!(fast9_portable(&img, t, border, nonmax), want, "case {i}");
        }
    }

    #[test]
    fn score_is_the_largest_passing_threshold() {
        let mut ring = [100u8; 16];
        for r in ring.iter_mut().take(9) {
            *r = 160;
        }
        ring[4] = 150; // weakest pixel of the arc: difference 50 from 100
        assert_eq!(corner_score(100, &ring, 20), 49);
        // a darker arc that wraps around the start of the circle, weakest difference 30
        let mut ring = [100u8; 16];
        for k in [12, 13, 14, 15, 0, 1, 2, 3, 4] {
            ring[k] = 60;
        }
        ring[0] = 70;
        assert_eq!(corner_score(100, &ring, 5), 29);
        // never below the detection threshold
        assert_eq!(corner_score(100, &ring, 35), 35);
    }

    /// A bright square on dark ground: FAST fires at its four corners.
    #[test]
    fn detects_square_corners_with_nms() {
        let mut img = Image::filled(40, 40, 20u8);
        for y in 10..30 {
            for x in 10..30 {
                *img.get_mut(x, y).unwrap() = 200;
            }
        }
        // blur so that scores differ and each corner has a single strongest pixel
        let img = crate::filter::gaussian_blur(&img, 5, 1.0).unwrap();
        let all = fast9(&img, 30, 3, false);
        let sup = fast9(&img, 30, 3, true);
        assert!(sup.len() < all.len() && !sup.is_empty(), "{all:?} {sup:?}");
        for &(cx, cy) in &[(10, 10), (29, 10), (10, 29), (29, 29)] {
            assert!(
                sup.iter()
                    .any(|k| k.x.abs_diff(cx) <= 1 && k.y.abs_diff(cy) <= 1),
                "no corner at ({cx},{cy}): {sup:?}"
            );
        }
        // edges and flat regions are not corners
        assert!(sup
            .iter()
            .all(|k| (k.x <= 11 || k.x >= 28) && (k.y <= 11 || k.y >= 28)));
        assert!(fast9(&Image::filled(5, 5, 0u8), 10, 3, true).is_empty());
    }
}
