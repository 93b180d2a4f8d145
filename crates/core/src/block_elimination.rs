//! Sparse block LDLᵀ elimination of the normal equations of a pose graph, for any block size.
//!
//! A pose graph's Gauss–Newton (or Levenberg–Marquardt) system `H x = g` has one `D × D` block
//! per node on the diagonal and one per edge off it. Eliminating nodes one at a time (variable
//! elimination, the block form of a sparse Cholesky / LDLᵀ factorisation) costs little when the
//! order keeps the fill-in small; minimum degree first (Tinney & Walker 1967; George & Liu,
//! "The evolution of the minimum degree ordering algorithm", 1989) does that well on the
//! near-planar graphs robots build. The order, and for each step the blocks it reads and
//! updates (fill-in included), depend only on the graph's structure, so [`Elimination`] works
//! them out once (the symbolic factorisation) and every iteration's [`BlockSystem`] runs the same
//! arithmetic on flat block arrays without any map look-up. `D = 3` serves the planar graph of
//! `slamkit-lidar`, `D = 6` the SE(3) graph of `slamkit-vo`.
//!
//! ```
//! use nalgebra::{Matrix2, Vector2};
//! use slamkit_core::block_elimination::{BlockSystem, Elimination};
//!
//! // Two nodes joined by one edge: [[2, -1], [-1, 2]] x = [1, 0] in 2×2 blocks (scaled I).
//! let elimination = Elimination::new(2, &[(0, 1)]);
//! let mut system = BlockSystem::<2>::new(&elimination);
//! system.add_diag(0, Matrix2::identity() * 2.0, Vector2::new(1.0, 1.0));
//! system.add_diag(1, Matrix2::identity() * 2.0, Vector2::zeros());
//! system.add_off(0, -Matrix2::identity());
//! let x = system.solve().unwrap();
//! assert!((x[0] - Vector2::repeat(2.0 / 3.0)).norm() < 1e-12);
//! assert!((x[1] - Vector2::repeat(1.0 / 3.0)).norm() < 1e-12);
//! ```

use nalgebra::{SMatrix, SVector};
use std::collections::{BTreeMap, BTreeSet};

/// The elimination of the block-sparse normal equations of a fixed graph, worked out once per
/// optimisation (a symbolic factorisation): the order, minimum degree first, and for each step
/// the blocks it reads and the blocks it updates, fill-in included.
#[derive(Debug, Clone)]
pub struct Elimination {
    /// Number of nodes.
    nodes: usize,
    /// Number of off-diagonal blocks (ordered pairs, fill-in included).
    blocks: usize,
    /// Blocks `(from, to)` and `(to, from)` of each edge.
    edge_blocks: Vec<(usize, usize)>,
    steps: Vec<Step>,
}

/// Elimination of one node.
#[derive(Debug, Clone)]
struct Step {
    node: usize,
    /// The node's remaining neighbours in ascending order, with the block `(node, neighbour)`.
    row: Vec<(usize, usize)>,
    /// For neighbours `a` (outer) and `b` (inner) of `row`: the block `(a, b)` the step updates
    /// (unused where `a == b`, which updates `a`'s diagonal block).
    updates: Vec<usize>,
}

impl Elimination {
    /// The elimination of a graph of `nodes` nodes whose edges join the pairs `edges`
    /// (`(from, to)`, in the order the edges are later added with [`BlockSystem::add_off`]).
    /// Pairs naming a node out of range couple nothing.
    pub fn new(nodes: usize, edges: &[(usize, usize)]) -> Self {
        // rows[i][j] = index of block (i, j).
        let mut rows: Vec<BTreeMap<usize, usize>> = vec![BTreeMap::new(); nodes];
        let mut blocks = 0;
        let mut block = |rows: &mut Vec<BTreeMap<usize, usize>>, i: usize, j: usize| {
            rows.get_mut(i)
                .map(|row| {
                    *row.entry(j).or_insert_with(|| {
                        blocks += 1;
                        blocks - 1
                    })
                })
                .unwrap_or(usize::MAX)
        };
        let edge_blocks = edges
            .iter()
            .map(|&(from, to)| {
                if from.max(to) >= nodes {
                    return (usize::MAX, usize::MAX);
                }
                (block(&mut rows, from, to), block(&mut rows, to, from))
            })
            .collect();
        let mut queue: BTreeSet<(usize, usize)> =
            rows.iter().enumerate().map(|(i, r)| (r.len(), i)).collect();
        let mut steps = Vec::with_capacity(nodes);
        while let Some((_, k)) = queue.pop_first() {
            let row: Vec<(usize, usize)> = rows
                .get_mut(k)
                .map(std::mem::take)
                .unwrap_or_default()
                .into_iter()
                .collect();
            let mut updates = Vec::with_capacity(row.len() * row.len());
            for &(a, _) in &row {
                let old_degree = rows.get(a).map_or(0, BTreeMap::len);
                if let Some(r) = rows.get_mut(a) {
                    r.remove(&k);
                }
                for &(b, _) in &row {
                    updates.push(if a == b {
                        usize::MAX
                    } else {
                        block(&mut rows, a, b)
                    });
                }
                let new_degree = rows.get(a).map_or(0, BTreeMap::len);
                if queue.remove(&(old_degree, a)) {
                    queue.insert((new_degree, a));
                }
            }
            steps.push(Step {
                node: k,
                row,
                updates,
            });
        }
        Self {
            nodes,
            blocks,
            edge_blocks,
            steps,
        }
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.nodes
    }

    /// Number of off-diagonal blocks the factorisation holds (both directions, fill-in
    /// included): a measure of its memory and work.
    pub fn off_diagonal_blocks(&self) -> usize {
        self.blocks
    }
}

/// Symmetric block-sparse normal equations `H x = g` with `D × D` blocks, laid out by an
/// [`Elimination`]. Cloning one keeps the linearisation, so a Levenberg–Marquardt loop can try
/// several dampings ([`BlockSystem::add_to_diagonals`]) on copies.
#[derive(Debug, Clone)]
pub struct BlockSystem<'a, const D: usize> {
    elimination: &'a Elimination,
    diag: Vec<SMatrix<f64, D, D>>,
    rhs: Vec<SVector<f64, D>>,
    /// Off-diagonal blocks `H_ij`, `i ≠ j`, stored in both directions.
    off: Vec<SMatrix<f64, D, D>>,
}

impl<'a, const D: usize> BlockSystem<'a, D> {
    /// An all-zero system laid out by `elimination`.
    pub fn new(elimination: &'a Elimination) -> Self {
        Self {
            elimination,
            diag: vec![SMatrix::zeros(); elimination.nodes],
            rhs: vec![SVector::zeros(); elimination.nodes],
            off: vec![SMatrix::zeros(); elimination.blocks],
        }
    }

    /// Adds `h` to the diagonal block of node `i` and `g` to its right-hand side (nothing when
    /// `i` is out of range).
    pub fn add_diag(&mut self, i: usize, h: SMatrix<f64, D, D>, g: SVector<f64, D>) {
        if let (Some(d), Some(r)) = (self.diag.get_mut(i), self.rhs.get_mut(i)) {
            *d += h;
            *r += g;
        }
    }

    /// Adds `h_ij` to the off-diagonal block `(from, to)` of edge number `edge` (as given to
    /// [`Elimination::new`]) and its transpose to `(to, from)`.
    pub fn add_off(&mut self, edge: usize, h_ij: SMatrix<f64, D, D>) {
        let Some(&(ij, ji)) = self.elimination.edge_blocks.get(edge) else {
            return;
        };
        if let Some(b) = self.off.get_mut(ij) {
            *b += h_ij;
        }
        if let Some(b) = self.off.get_mut(ji) {
            *b += h_ij.transpose();
        }
    }

    /// Adds `f(i, diagonal block of i)` to every diagonal block: Levenberg–Marquardt damping.
    pub fn add_to_diagonals(
        &mut self,
        f: impl Fn(usize, &SMatrix<f64, D, D>) -> SMatrix<f64, D, D>,
    ) {
        for (i, d) in self.diag.iter_mut().enumerate() {
            *d += f(i, d);
        }
    }

    /// The diagonal block of node `i`.
    pub fn diagonal(&self, i: usize) -> Option<&SMatrix<f64, D, D>> {
        self.diag.get(i)
    }

    /// The right-hand side of node `i`.
    pub fn rhs(&self, i: usize) -> Option<&SVector<f64, D>> {
        self.rhs.get(i)
    }

    /// Solves by block elimination in the precomputed order, then back substitution; `None`
    /// when a pivot block is singular or the solution not finite.
    pub fn solve(mut self) -> Option<Vec<SVector<f64, D>>> {
        let steps = &self.elimination.steps;
        // Per step: D⁻¹ and the rhs at elimination.
        let mut eliminated = Vec::with_capacity(steps.len());
        for step in steps {
            let d_inv = self.diag.get(step.node)?.try_inverse()?;
            let g_k = *self.rhs.get(step.node)?;
            let m = step.row.len();
            for (ai, &(a, ka)) in step.row.iter().enumerate() {
                let h_ak_dinv = self.off.get(ka)?.transpose() * d_inv;
                for (bi, &(b, kb)) in step.row.iter().enumerate() {
                    let update = h_ak_dinv * self.off.get(kb)?;
                    let target = if a == b {
                        self.diag.get_mut(a)?
                    } else {
                        self.off.get_mut(*step.updates.get(ai * m + bi)?)?
                    };
                    *target -= update;
                }
                *self.rhs.get_mut(a)? -= h_ak_dinv * g_k;
            }
            eliminated.push((d_inv, g_k));
        }
        let mut x = vec![SVector::zeros(); self.elimination.nodes];
        for (step, (d_inv, g_k)) in steps.iter().zip(eliminated).rev() {
            let mut coupled = g_k;
            for &(j, kj) in &step.row {
                coupled -= self.off.get(kj)? * x.get(j).copied().unwrap_or_else(SVector::zeros);
            }
            *x.get_mut(step.node)? = d_inv * coupled;
        }
        x.iter()
            .all(|v| v.iter().all(|c| c.is_finite()))
            .then_some(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector, Matrix6, Vector6};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use std::ops::AddAssign;

    /// A random graph (a chain plus random chords) and a positive definite system on it, solved
    /// sparsely and densely: the two solutions agree.
    #[test]
    fn elimination_matches_a_dense_solve() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let n = 40;
        let mut edges: Vec<(usize, usize)> = (1..n).map(|i| (i - 1, i)).collect();
        for _ in 0..30 {
            let (a, b) = (rng.gen_range(0..n), rng.gen_range(0..n));
            if a != b {
                edges.push((a, b));
            }
        }
        let elimination = Elimination::new(n, &edges);
        let mut system = BlockSystem::<6>::new(&elimination);
        let mut h = DMatrix::<f64>::zeros(6 * n, 6 * n);
        let mut g = DVector::<f64>::zeros(6 * n);
        for i in 0..n {
            let gi = Vector6::from_fn(|_, _| rng.gen_range(-1.0..1.0));
            let hi = Matrix6::identity() * 0.1;
            system.add_diag(i, hi, gi);
            h.view_mut((6 * i, 6 * i), (6, 6)).add_assign(&hi);
            g.rows_mut(6 * i, 6).add_assign(&gi);
        }
        for (k, &(a, b)) in edges.iter().enumerate() {
            // An edge adds JᵀJ with J = [A  B]: positive semi-definite.
            let ja = Matrix6::from_fn(|_, _| rng.gen_range(-1.0..1.0));
            let jb = Matrix6::from_fn(|_, _| rng.gen_range(-1.0..1.0));
            system.add_diag(a, ja.transpose() * ja, Vector6::zeros());
            system.add_diag(b, jb.transpose() * jb, Vector6::zeros());
            system.add_off(k, ja.transpose() * jb);
            h.view_mut((6 * a, 6 * a), (6, 6))
                .add_assign(&(ja.transpose() * ja));
            h.view_mut((6 * b, 6 * b), (6, 6))
                .add_assign(&(jb.transpose() * jb));
            h.view_mut((6 * a, 6 * b), (6, 6))
                .add_assign(&(ja.transpose() * jb));
            h.view_mut((6 * b, 6 * a), (6, 6))
                .add_assign(&(jb.transpose() * ja));
        }
        let sparse = system.solve().unwrap();
        let dense = h.cholesky().unwrap().solve(&g);
        for (i, s) in sparse.iter().enumerate() {
            for c in 0..6 {
                assert!((s[c] - dense[6 * i + c]).abs() < 1e-8, "node {i}");
            }
        }
        // Every edge's pair of blocks (the chain's at least), plus any fill-in.
        assert!(elimination.off_diagonal_blocks() >= 2 * (n - 1));
    }

    #[test]
    fn a_singular_system_gives_none() {
        let elimination = Elimination::new(2, &[(0, 1)]);
        let system = BlockSystem::<3>::new(&elimination);
        assert!(system.solve().is_none());
    }

    #[test]
    fn out_of_range_pairs_couple_nothing() {
        let elimination = Elimination::new(2, &[(0, 5)]);
        assert_eq!(elimination.off_diagonal_blocks(), 0);
        let mut system = BlockSystem::<1>::new(&elimination);
        system.add_off(0, nalgebra::Matrix1::new(1.0));
        system.add_diag(0, nalgebra::Matrix1::new(2.0), nalgebra::Vector1::new(4.0));
        system.add_diag(1, nalgebra::Matrix1::new(1.0), nalgebra::Vector1::new(1.0));
        assert_eq!(system.rhs(1).map(|r| r[0]), Some(1.0));
        let x = system.solve().unwrap();
        assert_eq!((x[0][0], x[1][0]), (2.0, 1.0));
    }
}
