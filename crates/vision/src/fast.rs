//! FAST-9 corners (E. Rosten and T. Drummond, "Machine learning for high-speed corner
//! detection", ECCV 2006): a pixel is a corner when 9 contiguous pixels of the 16 on a
//! radius-3 Bresenham circle are all brighter than it by more than `threshold`, or all darker.
//! Its score is the largest threshold for which that still holds (OpenCV's `cornerScore`), and
//! non-maximum suppression keeps corners whose score beats all 8 neighbours.
//!
//! Each row first goes through a branch-free test on the four compass pixels that the compiler
//! vectorises (any 9-arc contains an element of each opposite pair, so both pairs must pass);
//! only the survivors get the full 16-pixel test.

use slamkit_core::image::GrayImage;

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

/// Detects FAST-9 corners at least `border` (≥ 3) pixels from every edge, optionally with 3×3
/// non-maximum suppression. Corners come row by row, left to right.
pub fn fast9(img: &GrayImage, threshold: u8, border: usize, nonmax: bool) -> Vec<FastCorner> {
    let (w, h) = (img.width(), img.height());
    let border = border.max(3);
    if w <= 2 * border || h <= 2 * border {
        return Vec::new();
    }
    let data = img.data();
    let n = w - 2 * border;
    let mut mask = vec![false; n];
    let mut scores = if nonmax { vec![0u8; w * h] } else { Vec::new() };
    let mut corners = Vec::new();
    let offsets: [isize; 16] = CIRCLE.map(|(dx, dy)| dy * w as isize + dx);
    for y in border..h - border {
        let row = |dy: isize| {
            let r = (y as isize + dy) as usize * w;
            &data[r..r + w]
        };
        let (up, mid, dn) = (row(-3), row(0), row(3));
        prefilter(
            &mid[border..border + n],
            [
                &dn[border..],
                &up[border..],
                &mid[border + 3..],
                &mid[border - 3..],
            ],
            threshold,
            &mut mask,
        );
        for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
            let x = border + i;
            let c = y * w + x;
            let mut ring = [0u8; 16];
            for (r, &o) in ring.iter_mut().zip(&offsets) {
                *r = data[(c as isize + o) as usize];
            }
            if let Some(score) = corner_score(mid[x], &ring, threshold) {
                corners.push(FastCorner { x, y, score });
                if nonmax {
                    scores[c] = score.saturating_add(1);
                }
            }
        }
    }
    if nonmax {
        corners.retain(|k| {
            let c = k.y * w + k.x;
            let s = scores[c];
            let around = [
                c - w - 1,
                c - w,
                c - w + 1,
                c - 1,
                c + 1,
                c + w - 1,
                c + w,
                c + w + 1,
            ];
            around.iter().all(|&o| s > scores[o])
        });
    }
    corners
}

/// Row-wise compass test: `mask\[i\]` when both opposite pairs (below/above, right/left) have a
/// pixel brighter than `v + t`, or both have one darker than `v − t`.
fn prefilter(centre: &[u8], [dn, up, right, left]: [&[u8]; 4], t: u8, mask: &mut [bool]) {
    let it = centre.iter().zip(dn).zip(up).zip(right).zip(left);
    for (m, ((((&v, &p0), &p8), &p4), &p12)) in mask.iter_mut().zip(it) {
        let (hi, lo) = (v.saturating_add(t), v.saturating_sub(t));
        let bright = ((p0 > hi) | (p8 > hi)) & ((p4 > hi) | (p12 > hi));
        let dark = ((p0 < lo) | (p8 < lo)) & ((p4 < lo) | (p12 < lo));
        *m = bright | dark;
    }
}

/// Full segment test; `Some(score)` when 9 contiguous ring pixels differ by more than `t`.
fn corner_score(v: u8, ring: &[u8; 16], t: u8) -> Option<u8> {
    let (hi, lo) = (v.saturating_add(t), v.saturating_sub(t));
    let (mut bright, mut dark) = (0u32, 0u32);
    for (k, &p) in ring.iter().enumerate() {
        bright |= u32::from(p > hi) << k;
        dark |= u32::from(p < lo) << k;
    }
    if !has_arc9(bright) && !has_arc9(dark) {
        return None;
    }
    // Score: the best arc's smallest difference, minus one (strictly-greater test).
    let mut diff = [0i16; 25];
    for (d, k) in diff.iter_mut().zip((0..25).map(|k| k % 16)) {
        *d = i16::from(ring[k]) - i16::from(v);
    }
    let (mut best_b, mut best_d) = (i16::MIN, i16::MIN);
    for s in 0..16 {
        let arc = &diff[s..s + 9];
        let (mn, mx) = arc
            .iter()
            .fold((i16::MAX, i16::MIN), |(a, b), &d| (a.min(d), b.max(d)));
        best_b = best_b.max(mn);
        best_d = best_d.max(-mx);
    }
    Some((best_b.max(best_d) - 1).clamp(i16::from(t), 255) as u8)
}

/// Whether the 16-bit circular mask has 9 consecutive set bits.
#[inline]
fn has_arc9(m: u32) -> bool {
    let mut r = m | (m << 16);
    // r & (r >> 1) & ... (r >> 8): a bit survives when it starts a run of 9
    let mut acc = r;
    for _ in 0..8 {
        r >>= 1;
        acc &= r;
    }
    acc & 0xFFFF != 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_core::image::Image;

    #[test]
    fn arc_test() {
        assert!(has_arc9(0b1_1111_1111));
        assert!(has_arc9(0b1111_0000_0000_0011_1111 & 0xFFFF | 0xF000));
        assert!(!has_arc9(0b1111_1111));
        // wraps around: bits 12..15 and 0..4
        assert!(has_arc9(0xF01F));
        assert!(!has_arc9(0xF00F));
    }

    #[test]
    fn score_is_the_largest_passing_threshold() {
        let mut ring = [100u8; 16];
        for r in ring.iter_mut().take(9) {
            *r = 160;
        }
        ring[4] = 150; // weakest pixel of the arc: difference 50 from 100
        let s = corner_score(100, &ring, 20).unwrap();
        assert_eq!(s, 49);
        assert!(corner_score(100, &ring, 49).is_some());
        assert!(corner_score(100, &ring, 50).is_none());
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
