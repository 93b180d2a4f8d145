//! Which pairs of scans get a ground-truth relation, as in the Freiburg 2D SLAM benchmark
//! (Kümmerle et al., "On measuring the accuracy of SLAM algorithms", Autonomous Robots 27(4),
//! 2009): scans about `spacing_s` apart along the whole run, which score local accuracy, and a
//! few random far-apart pairs, which score global consistency.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Index pairs `(i, j)`, `i < j`, into `times` (sorted): from every scan one `spacing_s` later
/// (stepping by that spacing), then `far_pairs` random pairs at least ten spacings apart.
pub fn relation_pairs(
    times: &[f64],
    spacing_s: f64,
    far_pairs: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<(usize, usize)> {
    let mut pairs = Vec::new();
    if times.len() < 2 || spacing_s.is_nan() || spacing_s <= 0.0 {
        return pairs;
    }
    let mut i = 0;
    while let Some(j) = next_after(times, i, spacing_s) {
        pairs.push((i, j));
        i = j;
    }
    let far_s = 10.0 * spacing_s;
    let Some(last) = times.last().copied() else {
        return pairs;
    };
    let candidates = times.partition_point(|t| *t <= last - far_s);
    for _ in 0..far_pairs {
        if candidates == 0 {
            break;
        }
        let i = rng.gen_range(0..candidates);
        let first = times.partition_point(|t| *t < times[i] + far_s);
        let j = rng.gen_range(first.max(i + 1)..times.len());
        pairs.push((i, j));
    }
    pairs
}

/// The first index whose time is at least `spacing_s` after that of `i`.
fn next_after(times: &[f64], i: usize, spacing_s: f64) -> Option<usize> {
    let t = times.get(i)? + spacing_s - 1e-9;
    let j = times.partition_point(|x| *x < t);
    (j < times.len()).then_some(j)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn near_pairs_one_second_apart_and_far_pairs_far() {
        let times: Vec<f64> = (0..1000).map(|k| f64::from(k) / 10.0).collect();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let pairs = relation_pairs(&times, 1.0, 20, &mut rng);
        let (near, far) = pairs.split_at(pairs.len() - 20);
        assert_eq!(near.len(), 99);
        assert!(near.iter().all(|&(i, j)| j == i + 10));
        assert!(far
            .iter()
            .all(|&(i, j)| times[j] - times[i] >= 10.0 - 1e-9 && j < 1000));
        assert!(relation_pairs(&times[..50], 1.0, 5, &mut rng).len() == 4);
        assert!(relation_pairs(&[], 1.0, 5, &mut rng).is_empty());
    }
}
