//! Pairwise consistency maximisation (PCM; Mangelson, Dominic, Eustice and Vasudevan, "Pairwise
//! Consistent Measurement Set Maximization for Robust Multi-robot Map Merging", ICRA 2018).
//!
//! Each verified closure between maps A and B says where B's frame lies in A's:
//! `A_from_B = A_from_a · a_from_b · (B_from_b)⁻¹`. Two true closures say nearly the same
//! thing; how nearly depends on how far apart they are, since each map's own error between the
//! two places enters. Two closures are consistent when their frames move each closure's query
//! keyframe to within `tolerance_m + drift_per_m · d` of each other and turn by no more than
//! `tolerance_rad + drift_rad_per_m · d`, where `d` is the distance between the two closures in
//! A plus that in B. Wrong closures put B anywhere and agree with few others; the true ones
//! form one large set of mutually consistent closures, a maximum clique of the consistency
//! graph, found exactly by Bron–Kerbosch with Tomita's pivot (Tomita, Tanaka and Takahashi,
//! 2006) and a size bound. A pair of maps is joined only when that clique holds at least
//! `min_consistent` closures and no second consistent set outside it comes close in size
//! (`ambiguity_ratio`).

use super::{ClosureStatus, InterClosure};
use crate::SlamError;
use serde::{Deserialize, Serialize};
use slamkit_core::Pose2;
use slamkit_lidar::point_map::Keyframe;
use std::collections::BTreeMap;

/// Consistency check settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PcmConfig {
    /// Disagreement allowed between two closures at the same place \[m\]...
    pub tolerance_m: f64,
    /// ...growing by this much per metre between them (the maps' own drift).
    pub drift_per_m: f64,
    /// Rotation disagreement allowed at the same place \[rad\]...
    pub tolerance_rad: f64,
    /// ...growing by this much per metre between them \[rad/m\].
    pub drift_rad_per_m: f64,
    /// Fewest mutually consistent closures that join two maps (>= 1; 1 trusts any single
    /// closure, which a merge never should).
    pub min_consistent: usize,
    /// The pair stays apart when, beside the largest consistent set, the closures outside it
    /// hold another set of at least `min_consistent` closures and at least this fraction of
    /// its size: two places that look alike (a room and its mirror image, two identical
    /// offices) give two consistent stories, and the evidence does not tell which is true.
    pub ambiguity_ratio: f64,
}

impl Default for PcmConfig {
    fn default() -> Self {
        Self {
            tolerance_m: 0.3,
            drift_per_m: 0.02,
            tolerance_rad: 3f64.to_radians(),
            drift_rad_per_m: 0.2f64.to_radians(),
            min_consistent: 3,
            ambiguity_ratio: 0.5,
        }
    }
}

impl PcmConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), SlamError> {
        let ok = self.tolerance_m >= 0.0
            && self.drift_per_m >= 0.0
            && self.tolerance_rad >= 0.0
            && self.drift_rad_per_m >= 0.0
            && self.min_consistent >= 1
            && self.ambiguity_ratio >= 0.0;
        if ok {
            Ok(())
        } else {
            Err(SlamError::Config(format!(
                "merge pcm: a field is out of range in {self:?}"
            )))
        }
    }
}

/// Two maps joined by a consistent set of closures.
#[derive(Debug, Clone, PartialEq)]
pub struct PairLink {
    /// The lower-numbered map of the pair.
    pub from_map: usize,
    /// The higher-numbered map of the pair.
    pub to_map: usize,
    /// `from_world_from_to_world`: where `to_map`'s frame lies in `from_map`'s,
    /// by the best closure of the set (highest product of the two goodnesses).
    pub from_from_to_frame: Pose2,
    /// Indices of the closures of the set.
    pub closures: Vec<usize>,
}

/// Runs the consistency check on every pair of maps (`keyframes[m]`: map `m`'s keyframes):
/// sets the status of each verified closure that passed the free-space check (accepted, too few consistent, inconsistent) and
/// returns the pairs joined.
pub fn select(
    keyframes: &[Vec<Keyframe>],
    closures: &mut [InterClosure],
    config: &PcmConfig,
) -> Vec<PairLink> {
    let mut by_pair: BTreeMap<(usize, usize), Vec<usize>> = BTreeMap::new();
    for (i, c) in closures.iter().enumerate() {
        let checked = !matches!(
            c.status,
            ClosureStatus::FailedVerification | ClosureStatus::FreeSpaceConflict
        );
        if checked {
            // both search directions of a pair of maps meet in one set
            let pair = (c.from_map.min(c.to_map), c.from_map.max(c.to_map));
            by_pair.entry(pair).or_default().push(i);
        }
    }
    let mut links = Vec::new();
    for ((from_map, to_map), members) in by_pair {
        let located: Vec<Located> = members
            .iter()
            .filter_map(|&i| Located::new(keyframes, &closures[i]))
            .collect();
        let adjacency = consistency_graph(&located, config);
        let weights: Vec<f64> = located.iter().map(|l| l.weight).collect();
        let best = max_clique(&adjacency, &weights);
        let runner_up = runner_up_size(&adjacency, &weights, &best);
        let clique: Vec<usize> = best.into_iter().map(|k| members[k]).collect();
        let ambiguous = runner_up >= config.min_consistent
            && runner_up as f64 >= config.ambiguity_ratio * clique.len() as f64;
        let status = if clique.len() < config.min_consistent {
            ClosureStatus::TooFewConsistent
        } else if ambiguous {
            ClosureStatus::Ambiguous
        } else {
            ClosureStatus::Accepted
        };
        for &i in &clique {
            closures[i].status = status;
        }
        let joined = status == ClosureStatus::Accepted;
        if !joined {
            continue;
        }
        let best = clique
            .iter()
            .filter_map(|&i| Located::new(keyframes, &closures[i]))
            .max_by(|a, b| a.weight.total_cmp(&b.weight));
        if let Some(best) = best {
            links.push(PairLink {
                from_map,
                to_map,
                from_from_to_frame: best.frame,
                closures: clique,
            });
        }
    }
    links
}

/// Size of the largest consistent set among the closures outside `best`.
fn runner_up_size(adjacency: &[Vec<bool>], weights: &[f64], best: &[usize]) -> usize {
    let rest: Vec<usize> = (0..adjacency.len()).filter(|i| !best.contains(i)).collect();
    let sub: Vec<Vec<bool>> = rest
        .iter()
        .map(|&i| rest.iter().map(|&j| adjacency[i][j]).collect())
        .collect();
    let sub_weights: Vec<f64> = rest.iter().map(|&i| weights[i]).collect();
    max_clique(&sub, &sub_weights).len()
}

/// A closure with what the check needs: the frame it implies, where it is in both maps, all
/// oriented from the lower-numbered map of its pair to the higher (a closure found by searching
/// the later map's query in the earlier map and one found the other way round say the same
/// thing in the same terms).
#[derive(Debug, Clone, Copy)]
struct Located {
    frame: Pose2,
    from_position: nalgebra::Vector2<f64>,
    to_position: nalgebra::Vector2<f64>,
    weight: f64,
}

impl Located {
    fn new(keyframes: &[Vec<Keyframe>], c: &InterClosure) -> Option<Self> {
        let from = keyframes
            .get(c.from_map)?
            .get(c.from_keyframe)?
            .world_from_base;
        let to = keyframes.get(c.to_map)?.get(c.to_keyframe)?.world_from_base;
        let frame = from * c.from_from_to * to.inverse();
        let weight = c.goodness * c.reverse_goodness.unwrap_or(0.0);
        Some(if c.from_map <= c.to_map {
            Self {
                frame,
                from_position: from.translation.vector,
                to_position: to.translation.vector,
                weight,
            }
        } else {
            Self {
                frame: frame.inverse(),
                from_position: to.translation.vector,
                to_position: from.translation.vector,
                weight,
            }
        })
    }
}

/// Whether closures `a` and `b` put the querying map at the same place (see the module
/// documentation).
fn consistent(a: &Located, b: &Located, config: &PcmConfig) -> bool {
    let d = (a.from_position - b.from_position).norm() + (a.to_position - b.to_position).norm();
    let tol_m = config.tolerance_m + config.drift_per_m * d;
    let tol_rad = config.tolerance_rad + config.drift_rad_per_m * d;
    let turn = (a.frame.rotation.inverse() * b.frame.rotation)
        .angle()
        .abs();
    let apart = |p: nalgebra::Vector2<f64>| {
        let p = nalgebra::Point2::from(p);
        (a.frame * p - b.frame * p).norm()
    };
    turn <= tol_rad && apart(a.to_position) <= tol_m && apart(b.to_position) <= tol_m
}

fn consistency_graph(located: &[Located], config: &PcmConfig) -> Vec<Vec<bool>> {
    let n = located.len();
    let mut adjacency = vec![vec![false; n]; n];
    for i in 0..n {
        for j in i + 1..n {
            let ok = consistent(&located[i], &located[j], config);
            adjacency[i][j] = ok;
            adjacency[j][i] = ok;
        }
    }
    adjacency
}

/// A maximum clique of the graph `adjacency` (symmetric, no self-loops), and among those of
/// the largest size the one of the highest total `weights`; empty for an empty graph.
///
/// ```
/// use slamkit_slam::merge::pcm::max_clique;
/// // a triangle 0-1-2 and an edge 3-4
/// let mut adj = vec![vec![false; 5]; 5];
/// for (a, b) in [(0, 1), (1, 2), (0, 2), (3, 4)] {
///     adj[a][b] = true;
///     adj[b][a] = true;
/// }
/// let mut clique = max_clique(&adj, &[1.0; 5]);
/// clique.sort();
/// assert_eq!(clique, [0, 1, 2]);
/// ```
pub fn max_clique(adjacency: &[Vec<bool>], weights: &[f64]) -> Vec<usize> {
    let mut search = CliqueSearch {
        adjacency,
        weights,
        best: Vec::new(),
        best_weight: f64::NEG_INFINITY,
    };
    let mut current = Vec::new();
    search.expand(&mut current, (0..adjacency.len()).collect(), Vec::new());
    search.best
}

struct CliqueSearch<'a> {
    adjacency: &'a [Vec<bool>],
    weights: &'a [f64],
    best: Vec<usize>,
    best_weight: f64,
}

impl CliqueSearch<'_> {
    fn linked(&self, a: usize, b: usize) -> bool {
        self.adjacency
            .get(a)
            .and_then(|row| row.get(b))
            .copied()
            .unwrap_or(false)
    }

    /// Bron–Kerbosch: `current` is a clique, `candidates` extend it, `excluded` were tried.
    fn expand(
        &mut self,
        current: &mut Vec<usize>,
        mut candidates: Vec<usize>,
        mut excluded: Vec<usize>,
    ) {
        if candidates.is_empty() {
            if excluded.is_empty() {
                let weight: f64 = current
                    .iter()
                    .map(|&v| self.weights.get(v).copied().unwrap_or(0.0))
                    .sum();
                let better = current.len() > self.best.len()
                    || (current.len() == self.best.len() && weight > self.best_weight);
                if better {
                    self.best = current.clone();
                    self.best_weight = weight;
                }
            }
            return;
        }
        // Bound: even taking every candidate cannot reach the best size.
        if current.len() + candidates.len() < self.best.len() {
            return;
        }
        // Tomita's pivot: the vertex with the most candidate neighbours; its neighbours are
        // reached through the other branches.
        let pivot = candidates
            .iter()
            .chain(&excluded)
            .copied()
            .max_by_key(|&u| candidates.iter().filter(|&&v| self.linked(u, v)).count());
        let branch: Vec<usize> = candidates
            .iter()
            .copied()
            .filter(|&v| pivot.map_or(true, |u| !self.linked(u, v)))
            .collect();
        for v in branch {
            current.push(v);
            let next_candidates = candidates
                .iter()
                .copied()
                .filter(|&w| self.linked(v, w))
                .collect();
            let next_excluded = excluded
                .iter()
                .copied()
                .filter(|&w| self.linked(v, w))
                .collect();
            self.expand(current, next_candidates, next_excluded);
            current.pop();
            candidates.retain(|&w| w != v);
            excluded.push(v);
        }
    }
}
