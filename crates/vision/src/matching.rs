//! Brute-force Hamming matching of binary descriptors (u64 popcount), with Lowe's ratio test
//! (D. Lowe, IJCV 2004), a mutual-best cross-check and an absolute distance threshold, as
//! OpenCV's `BFMatcher(NORM_HAMMING, crossCheck)` plus the usual filters.

use serde::{Deserialize, Serialize};

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
    let mut col_best = vec![(u32::MAX, usize::MAX); train.len()];
    let mut rows = Vec::with_capacity(query.len());
    for (qi, q) in query.iter().enumerate() {
        let (mut best, mut second, mut best_t) = (u32::MAX, u32::MAX, usize::MAX);
        for (ti, (t, cb)) in train.iter().zip(col_best.iter_mut()).enumerate() {
            let d = hamming(q, t);
            if d < best {
                second = best;
                best = d;
                best_t = ti;
            } else if d < second {
                second = d;
            }
            if d < cb.0 {
                *cb = (d, qi);
            }
        }
        rows.push((best, second, best_t));
    }
    rows.into_iter()
        .enumerate()
        .filter_map(|(qi, (best, second, ti))| {
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
