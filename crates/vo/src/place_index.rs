//! An online place index over binary descriptors, built from the keyframes the robot sees (no
//! vocabulary file): a Hamming-distance binary search tree after Schlegel and Grisetti, "HBST:
//! A Hamming distance embedding binary search tree for feature-based visual place
//! recognition", RA-L 2018.
//!
//! Every descriptor of every keyframe is stored in a leaf. A leaf holding more than
//! `max_leaf_size` descriptors splits on the bit whose mean over its descriptors is closest to
//! ½ (the paper's balanced split, bits already used on the path excluded), so the tree stays
//! shallow whatever the robot sees. A query descriptor descends by its own bits to one leaf and
//! is compared with the descriptors there only: near descriptors agree on most bits, so they
//! mostly share the path (the paper's "Hamming distance embedding"); the few that differ on a
//! split bit are missed, the price of logarithmic search. Each query descriptor votes once for
//! every keyframe with a descriptor within `max_distance` bits in its leaf; keyframes are
//! ranked by votes.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};
use slamkit_vision::matching::hamming;
use slamkit_vision::Descriptor;

use crate::VoError;

/// Bits of an ORB descriptor.
const BITS: usize = 256;

/// Settings of the place index.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlaceIndexConfig {
    /// A leaf holding more descriptors splits (HBST's `N_max`; the paper uses 50–100).
    pub max_leaf_size: usize,
    /// Deepest split; leaves there grow without bound.
    pub max_depth: usize,
    /// A stored descriptor this close to a query one is a vote for its keyframe \[bits\].
    pub max_distance: u32,
}

impl Default for PlaceIndexConfig {
    fn default() -> Self {
        Self {
            max_leaf_size: 100,
            max_depth: 24,
            max_distance: 40,
        }
    }
}

impl PlaceIndexConfig {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`VoError::InvalidConfig`] for a leaf size of 0, a depth beyond 256 bits or a distance
    /// beyond 256 bits.
    pub fn validate(&self) -> Result<(), VoError> {
        if self.max_leaf_size == 0 {
            return Err(VoError::config(
                "place_index.max_leaf_size",
                0,
                "must be > 0",
            ));
        }
        if self.max_depth > BITS {
            return Err(VoError::config(
                "place_index.max_depth",
                self.max_depth,
                "must be <= 256",
            ));
        }
        if self.max_distance as usize > BITS {
            return Err(VoError::config(
                "place_index.max_distance",
                self.max_distance,
                "must be <= 256",
            ));
        }
        Ok(())
    }
}

/// A keyframe found by [`PlaceIndex::query`], with the query descriptors that voted for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlaceMatch {
    /// The keyframe's id, as given to [`PlaceIndex::insert`].
    pub keyframe: usize,
    /// Query descriptors with a near descriptor of the keyframe in their leaf.
    pub votes: usize,
}

#[derive(Debug, Clone)]
enum Node {
    Leaf(Vec<(Descriptor, usize)>),
    Split { bit: usize, children: [usize; 2] },
}

/// The index: a binary tree over descriptor bits, leaves holding `(descriptor, keyframe)`.
///
/// ```
/// use slamkit_vo::place_index::{PlaceIndex, PlaceIndexConfig};
///
/// let mut index = PlaceIndex::new(PlaceIndexConfig::default())?;
/// // two keyframes with unrelated descriptors (a simple hash spreads the bits)
/// let descriptor = |i: u64| {
///     let h = |k: u64| (i * 4 + k + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15).rotate_left(17);
///     [h(0), h(1), h(2), h(3)]
/// };
/// index.insert(0, &(0..300).map(descriptor).collect::<Vec<_>>());
/// index.insert(1, &(1000..1300).map(descriptor).collect::<Vec<_>>());
/// // a view of keyframe 1's place: most of its descriptors again
/// let best = index.query(&(1000..1200).map(descriptor).collect::<Vec<_>>());
/// assert_eq!(best[0].keyframe, 1);
/// assert!(best[0].votes >= 150);
/// # Ok::<(), slamkit_vo::VoError>(())
/// ```
#[derive(Debug, Clone)]
pub struct PlaceIndex {
    config: PlaceIndexConfig,
    nodes: Vec<Node>,
    descriptors: usize,
}

impl PlaceIndex {
    /// An empty index.
    ///
    /// # Errors
    /// As [`PlaceIndexConfig::validate`].
    pub fn new(config: PlaceIndexConfig) -> Result<Self, VoError> {
        config.validate()?;
        Ok(Self {
            config,
            nodes: vec![Node::Leaf(Vec::new())],
            descriptors: 0,
        })
    }

    /// Descriptors stored.
    pub fn len(&self) -> usize {
        self.descriptors
    }

    /// True before the first descriptor.
    pub fn is_empty(&self) -> bool {
        self.descriptors == 0
    }

    /// The leaf `d` descends to, and the bits split on along the way.
    fn descend(&self, d: &Descriptor) -> (usize, Vec<usize>) {
        let mut node = 0;
        let mut path = Vec::new();
        while let Some(Node::Split { bit, children }) = self.nodes.get(node) {
            path.push(*bit);
            node = children[usize::from(bit_of(d, *bit))];
        }
        (node, path)
    }

    /// Stores the descriptors of `keyframe`.
    pub fn insert(&mut self, keyframe: usize, descriptors: &[Descriptor]) {
        for d in descriptors {
            let (leaf, path) = self.descend(d);
            if let Some(Node::Leaf(entries)) = self.nodes.get_mut(leaf) {
                entries.push((*d, keyframe));
                self.descriptors += 1;
                if entries.len() > self.config.max_leaf_size && path.len() < self.config.max_depth {
                    self.split(leaf, &path);
                }
            }
        }
    }

    /// Splits leaf `leaf` on its most balanced bit not in `path` (none when every free bit
    /// is constant over it: the descriptors are then all equal on them and stay together).
    fn split(&mut self, leaf: usize, path: &[usize]) {
        let Some(Node::Leaf(entries)) = self.nodes.get(leaf) else {
            return;
        };
        let mut ones = [0usize; BITS];
        for (d, _) in entries {
            for (b, count) in ones.iter_mut().enumerate() {
                *count += usize::from(bit_of(d, b));
            }
        }
        let n = entries.len();
        let best = (0..BITS)
            .filter(|b| !path.contains(b))
            .filter(|&b| ones[b] > 0 && ones[b] < n)
            .min_by_key(|&b| (2 * ones[b]).abs_diff(n));
        let Some(bit) = best else {
            return;
        };
        let (one, zero): (Vec<_>, Vec<_>) = entries.iter().partition(|(d, _)| bit_of(d, bit));
        let first = self.nodes.len();
        self.nodes.push(Node::Leaf(zero));
        self.nodes.push(Node::Leaf(one));
        if let Some(node) = self.nodes.get_mut(leaf) {
            *node = Node::Split {
                bit,
                children: [first, first + 1],
            };
        }
    }

    /// Keyframes with descriptors near those of `descriptors`, most votes first (ties by
    /// keyframe id).
    pub fn query(&self, descriptors: &[Descriptor]) -> Vec<PlaceMatch> {
        let mut votes: HashMap<usize, usize> = HashMap::new();
        let mut voted: Vec<usize> = Vec::new();
        for d in descriptors {
            let (leaf, _) = self.descend(d);
            let Some(Node::Leaf(entries)) = self.nodes.get(leaf) else {
                continue;
            };
            voted.clear();
            for (stored, keyframe) in entries {
                if hamming(d, stored) <= self.config.max_distance && !voted.contains(keyframe) {
                    voted.push(*keyframe);
                    *votes.entry(*keyframe).or_default() += 1;
                }
            }
        }
        let mut ranked: Vec<PlaceMatch> = votes
            .into_iter()
            .map(|(keyframe, votes)| PlaceMatch { keyframe, votes })
            .collect();
        ranked.sort_unstable_by(|a, b| b.votes.cmp(&a.votes).then(a.keyframe.cmp(&b.keyframe)));
        ranked
    }
}

/// Bit `b` (0..256) of `d`.
fn bit_of(d: &Descriptor, b: usize) -> bool {
    d.get(b / 64).is_some_and(|w| (w >> (b % 64)) & 1 == 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_descriptors(rng: &mut ChaCha8Rng, n: usize) -> Vec<Descriptor> {
        (0..n).map(|_| rng.gen()).collect()
    }

    /// `d` with `flips` random bits flipped.
    fn noisy(rng: &mut ChaCha8Rng, d: &Descriptor, flips: usize) -> Descriptor {
        let mut out = *d;
        for _ in 0..flips {
            let b = rng.gen_range(0..BITS);
            out[b / 64] ^= 1 << (b % 64);
        }
        out
    }

    #[test]
    fn a_revisited_place_wins_the_vote_among_many_and_an_unseen_one_gets_almost_none() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut index = PlaceIndex::new(PlaceIndexConfig::default()).unwrap();
        let places: Vec<Vec<Descriptor>> =
            (0..60).map(|_| random_descriptors(&mut rng, 400)).collect();
        for (k, p) in places.iter().enumerate() {
            index.insert(k, p);
        }
        assert_eq!(index.len(), 60 * 400);
        // place 23 seen again: 300 of its descriptors with 8 of 256 bits changed
        let query: Vec<Descriptor> = places[23][..300]
            .iter()
            .map(|d| noisy(&mut rng, d, 8))
            .collect();
        let ranked = index.query(&query);
        assert_eq!(ranked[0].keyframe, 23);
        // most still descend to their leaf (the tree is about 8 levels deep)
        assert!(ranked[0].votes > 150, "{:?}", ranked[0]);
        let second = ranked.get(1).map_or(0, |m| m.votes);
        assert!(second < 10, "runner-up {second}");
        // a place never seen: random descriptors are ~128 bits from everything stored
        let unseen = index.query(&random_descriptors(&mut rng, 300));
        assert!(unseen.iter().all(|m| m.votes < 5), "{unseen:?}");
    }

    #[test]
    fn leaves_split_on_balanced_bits_so_the_tree_stays_shallow() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let config = PlaceIndexConfig {
            max_leaf_size: 50,
            ..PlaceIndexConfig::default()
        };
        let mut index = PlaceIndex::new(config).unwrap();
        index.insert(0, &random_descriptors(&mut rng, 10_000));
        let depth = |d: &Descriptor| index.descend(d).1.len();
        let deepest = random_descriptors(&mut rng, 200).iter().map(depth).max();
        // 10 000 / 50 = 200 leaves: log2 200 ≈ 7.6 for a balanced tree
        assert!(
            deepest.is_some_and(|d| (7..=11).contains(&d)),
            "{deepest:?}"
        );
        // identical descriptors cannot be split: they stay in one leaf, no endless splitting
        let mut same = PlaceIndex::new(PlaceIndexConfig::default()).unwrap();
        same.insert(1, &vec![[5, 6, 7, 8]; 500]);
        assert_eq!(same.nodes.len(), 1);
        assert_eq!(same.query(&[[5, 6, 7, 8]])[0].votes, 1);
    }

    #[test]
    fn bad_settings_are_rejected() {
        for config in [
            PlaceIndexConfig {
                max_leaf_size: 0,
                ..PlaceIndexConfig::default()
            },
            PlaceIndexConfig {
                max_distance: 300,
                ..PlaceIndexConfig::default()
            },
        ] {
            assert!(PlaceIndex::new(config).is_err());
        }
    }
}
