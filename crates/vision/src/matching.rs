//! Hamming matching of binary descriptors, with Lowe's ratio test (D. Lowe, IJCV 2004), a
//! mutual-best cross-check and an absolute distance threshold, as OpenCV's
//! `BFMatcher(NORM_HAMMING, crossCheck)` plus the usual filters.
//!
//! [`match_descriptors`] compares every query with every train descriptor;
//! [`match_descriptors_within`] only pairs whose pixels lie within a radius (train pixels
//! typically predicted by a motion model), found through a grid of buckets of that size, as
//! ORB-SLAM's search by projection (Mur-Artal et al., IEEE T-RO 2015). Filters apply to the
//! pairs compared, so the two agree when the radius covers the image.
//!
//! Distances are 256-bit popcounts; on x86-64 the kernel is compiled a second time with the
//! `popcnt` instruction enabled and chosen at run time when the CPU has it (the baseline x86-64
//! target does not assume it, and `count_ones` then costs a dozen instructions per word).

use serde::{Deserialize, Serialize};

use crate::error::VisionError;
use crate::orb::Descriptor;

/// Matching filters.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MatchConfig {
    /// Reject matches farther than this \[bits\].
    pub max_distance: u32,
    /// Lowe's ratio: keep when best < ratio · second best (≥ 1 disables the test).
    pub ratio: f32,
    /// Keep only mutual best matches.
    pub cross_check: bool,
}

impl Default for MatchConfig {
    fn default() -> Self {
        Self {
            max_distance: 64,
            ratio: 0.8,
            cross_check: true,
        }
    }
}

/// A match between `query\[query_idx\]` and `train\[train_idx\]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DescriptorMatch {
    /// Index into the query descriptors.
    pub query_idx: usize,
    /// Index into the train descriptors.
    pub train_idx: usize,
    /// Hamming distance \[bits\].
    pub distance: u32,
}

/// Number of differing bits.
#[inline]
pub fn hamming(a: &Descriptor, b: &Descriptor) -> u32 {
    (a[0] ^ b[0]).count_ones()
        + (a[1] ^ b[1]).count_ones()
        + (a[2] ^ b[2]).count_ones()
        + (a[3] ^ b[3]).count_ones()
}

/// Matches every query descriptor to its nearest train descriptor and filters the result;
/// matches come in query order.
pub fn match_descriptors(
    query: &[Descriptor],
    train: &[Descriptor],
    config: &MatchConfig,
) -> Vec<DescriptorMatch> {
    filter(nearest(query, train, &AllPairs(train.len())), config)
}

/// Like [`match_descriptors`], but query `i` is compared only with the train descriptors `j`
/// whose pixel `train_px\[j\]` lies within `radius_px` of `query_px\[i\]` (pixels `[x, y]`;
/// non-finite ones match nothing).
///
/// # Errors
/// [`VisionError::InvalidConfig`] when a pixel list is not as long as its descriptors or the
/// radius is not finite and positive.
pub fn match_descriptors_within(
    (query, query_px): (&[Descriptor], &[[f32; 2]]),
    (train, train_px): (&[Descriptor], &[[f32; 2]]),
    radius_px: f32,
    config: &MatchConfig,
) -> Result<Vec<DescriptorMatch>, VisionError> {
    if query_px.len() != query.len() || train_px.len() != train.len() {
        return Err(VisionError::config(
            "pixels",
            format!("{} and {}", query_px.len(), train_px.len()),
            "must be one per query and per train descriptor",
        ));
    }
    within(query_px, train_px, radius_px, |window| {
        filter(nearest(query, train, window), config)
    })
}

/// Like [`match_descriptors_within`], but the distance of query `i` and train `j` is
/// `distance(i, j)` (`None`: the pair is not compared), for descriptors that depend on the
/// pair — a feature described on the pyramid level its predicted scale change calls for, the
/// smallest distance over a few levels.
///
/// # Errors
/// [`VisionError::InvalidConfig`] when the radius is not finite and positive.
pub fn match_within_by(
    query_px: &[[f32; 2]],
    train_px: &[[f32; 2]],
    radius_px: f32,
    distance: impl Fn(usize, usize) -> Option<u32>,
    config: &MatchConfig,
) -> Result<Vec<DescriptorMatch>, VisionError> {
    within(query_px, train_px, radius_px, |window| {
        filter(
            nearest_by(query_px.len(), train_px.len(), window, distance),
            config,
        )
    })
}

/// Checks the radius and runs `search` over the pairs within it.
fn within(
    query_px: &[[f32; 2]],
    train_px: &[[f32; 2]],
    radius_px: f32,
    search: impl FnOnce(&Window<'_>) -> Vec<DescriptorMatch>,
) -> Result<Vec<DescriptorMatch>, VisionError> {
    if !(radius_px.is_finite() && radius_px > 0.0) {
        return Err(VisionError::config("radius_px", radius_px, "must be > 0"));
    }
    let grid = Buckets::new(train_px, radius_px);
    let window = Window {
        grid: &grid,
        query_px,
        train_px,
        radius_sq: radius_px * radius_px,
    };
    Ok(search(&window))
}

/// Best and second-best distance of one query and the train index of the best.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Row {
    best: u32,
    second: u32,
    best_train: usize,
}

/// The rows, and for each train descriptor the closest query `(distance, index)`.
#[derive(Debug, PartialEq)]
struct Nearest {
    rows: Vec<Row>,
    col_best: Vec<(u32, usize)>,
}

/// Which train descriptors a query is compared with.
trait Candidates {
    /// Calls `visit` with each train index query `qi` is compared with (queries come in
    /// increasing order).
    fn each(&self, qi: usize, visit: impl FnMut(usize));
}

/// Every train descriptor.
struct AllPairs(usize);

impl Candidates for AllPairs {
    #[inline(always)]
    fn each(&self, _qi: usize, visit: impl FnMut(usize)) {
        (0..self.0).for_each(visit);
    }
}

/// Train descriptors whose pixel is within the radius of the query's.
struct Window<'a> {
    grid: &'a Buckets,
    query_px: &'a [[f32; 2]],
    train_px: &'a [[f32; 2]],
    radius_sq: f32,
}

impl Candidates for Window<'_> {
    #[inline(always)]
    fn each(&self, qi: usize, mut visit: impl FnMut(usize)) {
        let Some(&[x, y]) = self.query_px.get(qi) else {
            return;
        };
        let Some((cx, cy)) = self.grid.cell_of(x, y) else {
            return;
        };
        for gy in cy.saturating_sub(1)..(cy + 2).min(self.grid.rows) {
            let lo = gy * self.grid.cols + cx.saturating_sub(1);
            let hi = gy * self.grid.cols + (cx + 2).min(self.grid.cols);
            let (Some(&start), Some(&end)) = (self.grid.start.get(lo), self.grid.start.get(hi))
            else {
                continue;
            };
            for &ti in self.grid.index.get(start..end).unwrap_or_default() {
                let Some(&[tx, ty]) = self.train_px.get(ti) else {
                    continue;
                };
                if (tx - x).powi(2) + (ty - y).powi(2) <= self.radius_sq {
                    visit(ti);
                }
            }
        }
    }
}

/// Train indices sorted into square cells of the radius's size, row by row; cells adjacent to
/// a query's cell hold every train pixel within the radius.
struct Buckets {
    origin: [f32; 2],
    cell: f32,
    cols: usize,
    rows: usize,
    /// Indices of cell `c` are `index\[start\[c\]..start\[c + 1\]\]`, increasing.
    start: Vec<usize>,
    index: Vec<usize>,
}

impl Buckets {
    /// Cells at most this many per side; larger spreads get larger cells.
    const MAX_SIDE: f32 = 4096.0;

    fn new(px: &[[f32; 2]], radius: f32) -> Self {
        let finite = px.iter().filter(|p| p[0].is_finite() && p[1].is_finite());
        let (mut lo, mut hi) = ([f32::MAX; 2], [f32::MIN; 2]);
        for p in finite {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let span = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(0.0);
        let cell = radius.max(span / Self::MAX_SIDE);
        let side = |k: usize| ((hi[k] - lo[k]).max(0.0) / cell) as usize + 1;
        let mut grid = Self {
            origin: lo,
            cell,
            cols: side(0),
            rows: side(1),
            start: Vec::new(),
            index: Vec::new(),
        };
        let cells: Vec<Option<usize>> = px
            .iter()
            .map(|&[x, y]| grid.cell_of(x, y).map(|(cx, cy)| cy * grid.cols + cx))
            .collect();
        let mut count = vec![0usize; grid.cols * grid.rows + 1];
        for c in cells.iter().flatten() {
            count[c + 1] += 1;
        }
        for c in 1..count.len() {
            count[c] += count[c - 1];
        }
        grid.start = count.clone();
        grid.index = vec![0; count.last().copied().unwrap_or(0)];
        for (i, c) in cells.iter().enumerate() {
            if let Some(c) = *c {
                grid.index[count[c]] = i;
                count[c] += 1;
            }
        }
        grid
    }

    /// The cell of a pixel, clamped to the grid; `None` when not finite.
    fn cell_of(&self, x: f32, y: f32) -> Option<(usize, usize)> {
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
        let c = |v: f32, o: f32, n: usize| (((v - o) / self.cell).max(0.0) as usize).min(n - 1);
        Some((
            c(x, self.origin[0], self.cols),
            c(y, self.origin[1], self.rows),
        ))
    }
}

/// The nearest neighbours over the candidate pairs, with the `popcnt` build of the kernel when
/// the CPU has the instruction.
fn nearest(query: &[Descriptor], train: &[Descriptor], pairs: &impl Candidates) -> Nearest {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("popcnt") {
        // SAFETY: the CPU supports popcnt, the only feature `nearest_popcnt` enables.
        #[allow(unsafe_code)]
        return unsafe { nearest_popcnt(query, train, pairs) };
    }
    nearest_portable(query, train, pairs)
}

/// [`nearest_portable`] compiled with `popcnt`.
///
/// # Safety
/// The CPU must support the `popcnt` instruction.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt")]
#[allow(unsafe_code)]
unsafe fn nearest_popcnt(
    query: &[Descriptor],
    train: &[Descriptor],
    pairs: &impl Candidates,
) -> Nearest {
    nearest_portable(query, train, pairs)
}

#[inline(always)]
fn nearest_portable(
    query: &[Descriptor],
    train: &[Descriptor],
    pairs: &impl Candidates,
) -> Nearest {
    nearest_by(query.len(), train.len(), pairs, |qi, ti| {
        Some(hamming(query.get(qi)?, train.get(ti)?))
    })
}

/// The nearest neighbours of `n_query` queries among `n_train` train items over the candidate
/// pairs, the distance of a pair given by `distance` (`None`: not compared).
#[inline(always)]
fn nearest_by(
    n_query: usize,
    n_train: usize,
    pairs: &impl Candidates,
    distance: impl Fn(usize, usize) -> Option<u32>,
) -> Nearest {
    let mut col_best = vec![(u32::MAX, usize::MAX); n_train];
    let mut rows = Vec::with_capacity(n_query);
    for qi in 0..n_query {
        let mut row = Row {
            best: u32::MAX,
            second: u32::MAX,
            best_train: usize::MAX,
        };
        pairs.each(qi, |ti| {
            let Some(cb) = col_best.get_mut(ti) else {
                return;
            };
            let Some(d) = distance(qi, ti) else {
                return;
            };
            // ties go to the lowest train index, whatever order the pairs come in
            if (d, ti) < (row.best, row.best_train) {
                row.second = row.best;
                row.best = d;
                row.best_train = ti;
            } else if d < row.second {
                row.second = d;
            }
            if d < cb.0 {
                *cb = (d, qi);
            }
        });
        rows.push(row);
    }
    Nearest { rows, col_best }
}

/// Applies the distance threshold, ratio test and cross-check to the nearest neighbours.
fn filter(nearest: Nearest, config: &MatchConfig) -> Vec<DescriptorMatch> {
    let Nearest { rows, col_best } = nearest;
    rows.into_iter()
        .enumerate()
        .filter_map(|(qi, row)| {
            let Row {
                best,
                second,
                best_train: ti,
            } = row;
            let ratio_ok = config.ratio >= 1.0
                || second == u32::MAX
                || (best as f32) < config.ratio * second as f32;
            let cross_ok = !config.cross_check || col_best.get(ti).is_some_and(|c| c.1 == qi);
            (best <= config.max_distance && ratio_ok && cross_ok).then_some(DescriptorMatch {
                query_idx: qi,
                train_idx: ti,
                distance: best,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_desc(rng: &mut ChaCha8Rng) -> Descriptor {
        [rng.gen(), rng.gen(), rng.gen(), rng.gen()]
    }

    fn flip(d: &Descriptor, bits: &[usize]) -> Descriptor {
        let mut o = *d;
        for &b in bits {
            o[b / 64] ^= 1 << (b % 64);
        }
        o
    }

    #[test]
    fn hamming_counts_bits() {
        let a = [0u64; 4];
        assert_eq!(hamming(&a, &flip(&a, &[0, 63, 64, 200, 255])), 5);
        assert_eq!(hamming(&a, &[u64::MAX; 4]), 256);
    }

    /// The run-time selected kernel (popcnt on this CPU when it has it) gives what the
    /// portable build gives, with and without a window.
    #[test]
    fn popcnt_kernel_equals_portable() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let query: Vec<Descriptor> = (0..300).map(|_| random_desc(&mut rng)).collect();
        let train: Vec<Descriptor> = (0..250).map(|_| random_desc(&mut rng)).collect();
        let all = AllPairs(train.len());
        assert_eq!(
            nearest(&query, &train, &all),
            nearest_portable(&query, &train, &all)
        );
        let (qp, tp) = (random_px(&mut rng, 300), random_px(&mut rng, 250));
        let grid = Buckets::new(&tp, 40.0);
        let window = Window {
            grid: &grid,
            query_px: &qp,
            train_px: &tp,
            radius_sq: 1600.0,
        };
        let got = nearest(&query, &train, &window);
        assert_eq!(got, nearest_portable(&query, &train, &window));
        assert!(got.rows.iter().any(|r| r.best < u32::MAX));
    }

    fn random_px(rng: &mut ChaCha8Rng, n: usize) -> Vec<[f32; 2]> {
        (0..n)
            .map(|_| [rng.gen_range(-5.0..400.0), rng.gen_range(0.0..300.0)])
            .collect()
    }

    /// The windowed matcher is the brute-force definition restricted to pairs within the
    /// radius: nearest and second nearest, cross-check and filters over those pairs only.
    #[test]
    fn window_matches_the_masked_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let train: Vec<Descriptor> = (0..400).map(|_| random_desc(&mut rng)).collect();
        // queries: noisy copies of train descriptors (near their pixel or far away) and noise
        let tp = random_px(&mut rng, 400);
        let mut query = Vec::new();
        let mut qp = Vec::new();
        for i in 0..300 {
            let bits: Vec<usize> = (0..rng.gen_range(0..40))
                .map(|_| rng.gen_range(0..256))
                .collect();
            query.push(flip(&train[i], &bits));
            let [x, y] = tp[i];
            qp.push([
                x + rng.gen_range(-45.0..45.0),
                y + rng.gen_range(-45.0..45.0),
            ]);
        }
        query.extend((0..50).map(|_| random_desc(&mut rng)));
        qp.extend(random_px(&mut rng, 50));
        qp[7] = [f32::NAN, 1.0];
        let radius = 30.0f32;
        let config = MatchConfig {
            max_distance: 90,
            ..MatchConfig::default()
        };
        let got = match_descriptors_within((&query, &qp), (&train, &tp), radius, &config).unwrap();
        let near = |q: usize, t: usize| {
            (qp[q][0] - tp[t][0]).powi(2) + (qp[q][1] - tp[t][1]).powi(2) <= radius * radius
        };
        let best_of = |q: usize| {
            let mut d: Vec<(u32, usize)> = (0..train.len())
                .filter(|&t| near(q, t))
                .map(|t| (hamming(&query[q], &train[t]), t))
                .collect();
            d.sort();
            d
        };
        let mut want = Vec::new();
        for q in 0..query.len() {
            let d = best_of(q);
            let Some(&(best, t)) = d.first() else {
                continue;
            };
            let ratio_ok = d.get(1).map_or(true, |s| (best as f32) < 0.8 * s.0 as f32);
            let mutual = (0..query.len())
                .filter(|&q2| near(q2, t))
                .map(|q2| (hamming(&query[q2], &train[t]), q2))
                .min()
                .is_some_and(|(_, q2)| q2 == q);
            if best <= 90 && ratio_ok && mutual {
                want.push(DescriptorMatch {
                    query_idx: q,
                    train_idx: t,
                    distance: best,
                });
            }
        }
        assert_eq!(got, want);
        assert!(got.len() > 60, "{}", got.len());
        // the same through a distance function; pairs it declines are not compared
        let by = |q: usize, t: usize| Some(hamming(&query[q], &train[t]));
        assert_eq!(match_within_by(&qp, &tp, radius, by, &config).unwrap(), got);
        let odd_only = |q: usize, t: usize| (t % 2 == 1).then(|| hamming(&query[q], &train[t]));
        let some = match_within_by(&qp, &tp, radius, odd_only, &config).unwrap();
        assert!(!some.is_empty() && some.iter().all(|m| m.train_idx % 2 == 1));
        assert!(match_within_by(&qp, &tp, -1.0, by, &config).is_err());
        // a radius covering everything is the brute force
        let wide = match_descriptors_within((&query, &qp), (&train, &tp), 1e4, &config).unwrap();
        let brute = match_descriptors(&query, &train, &config);
        assert_eq!(
            wide.iter().filter(|m| m.query_idx != 7).count(),
            brute.iter().filter(|m| m.query_idx != 7).count()
        );
        assert!(wide.iter().all(|m| brute.contains(m)));
    }

    #[test]
    fn window_rejects_bad_input() {
        let d = [[0u64; 4]; 2];
        let px = [[0.0f32, 0.0]; 2];
        let c = MatchConfig::default();
        assert!(match_descriptors_within((&d, &px[..1]), (&d, &px), 5.0, &c).is_err());
        assert!(match_descriptors_within((&d, &px), (&d, &px), 0.0, &c).is_err());
        assert!(match_descriptors_within((&d, &px), (&d, &px), f32::NAN, &c).is_err());
        let ok = match_descriptors_within((&d, &px), (&[], &[]), 5.0, &c).unwrap();
        assert!(ok.is_empty());
    }

    #[test]
    fn finds_noisy_copies_and_filters() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let train: Vec<Descriptor> = (0..200).map(|_| random_desc(&mut rng)).collect();
        // query i = train[(i * 7) % 200] with 10 flipped bits; plus 20 unrelated descriptors
        let mut query: Vec<Descriptor> = (0..100)
            .map(|i| {
                let bits: Vec<usize> = (0..10).map(|_| rng.gen_range(0..256)).collect();
                flip(&train[(i * 7) % 200], &bits)
            })
            .collect();
        query.extend((0..20).map(|_| random_desc(&mut rng)));
        let m = match_descriptors(&query, &train, &MatchConfig::default());
        assert_eq!(m.len(), 100, "unrelated descriptors must be rejected");
        for mm in &m {
            assert_eq!(mm.train_idx, (mm.query_idx * 7) % 200);
            assert!(mm.distance <= 10);
        }
        // brute-force check of the nearest neighbour without filters
        let all = match_descriptors(
            &query,
            &train,
            &MatchConfig {
                max_distance: 256,
                ratio: 1.0,
                cross_check: false,
            },
        );
        assert_eq!(all.len(), query.len());
        for mm in &all {
            let best = train
                .iter()
                .map(|t| hamming(&query[mm.query_idx], t))
                .min()
                .unwrap();
            assert_eq!(mm.distance, best);
        }
        assert!(match_descriptors(&[], &train, &MatchConfig::default()).is_empty());
        assert!(match_descriptors(&query, &[], &MatchConfig::default()).is_empty());
    }
}
