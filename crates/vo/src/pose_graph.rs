//! An SE(3) pose graph and its Levenberg–Marquardt optimiser: the back end loop closure uses to
//! correct keyframe poses (Kümmerle et al., "g2o", ICRA 2011; Grisetti et al., "A tutorial on
//! graph-based SLAM", 2010; Dellaert & Kaess, "Factor graphs for robot perception", 2017).
//!
//! Nodes are poses `world_from_node`; an edge holds a measured `from_from_to = Z` with a 6×6
//! information matrix `Ω` over `(translation, rotation)`. Its error is the SE(3) logarithm of
//! the relative-pose error, `e = log(Z⁻¹ T_from⁻¹ T_to)` ([`slamkit_core::se3`]), and the cost is
//! `½ Σ ρ(eᵀ Ω e)` with `ρ` the identity or a Cauchy kernel: the same cost as GTSAM's
//! `BetweenFactor<Pose3>` with Gaussian noise of the same information (GTSAM's Pose3 chart is
//! the exponential map: `localCoordinates = Logmap`). Poses are updated on the right,
//! `T ← T exp(δ)`, and the Jacobians are exact: `∂e/∂δ_to = J_r⁻¹(e)`,
//! `∂e/∂δ_from = −J_r⁻¹(e) Ad(T_to⁻¹ T_from)`.
//!
//! Each iteration solves the damped normal equations `(H + λD) δ = −g`, `D` the diagonal of `H`
//! (Marquardt's scaling, so the damping does not depend on units), by sparse block LDLᵀ
//! elimination in minimum-degree order ([`slamkit_core::block_elimination`], 6×6 blocks; the
//! symbolic part is done once per optimisation). The damping follows Nielsen's rule (Madsen,
//! Nielsen & Tingleff, "Methods for non-linear least squares problems", 2004, §3.2; Ceres and
//! g2o use it too): `λ` starts at `τ`, shrinks by `max(⅓, 1 − (2ϱ − 1)³)` after a step with gain
//! ratio `ϱ > 0`
//! and grows by `ν` (doubling each time) after a rejected one. Edges may carry a Cauchy kernel
//! (iteratively reweighted), so a wrong loop closure pulls with bounded force. Fixed nodes (the
//! first one by default, to hold the gauge) do not move.

use crate::VoError;
use nalgebra::{Matrix6, Vector6};
use serde::{Deserialize, Serialize};
use slamkit_core::block_elimination::{BlockSystem, Elimination};
use slamkit_core::robust::cauchy;
use slamkit_core::{se3, Pose3};
use slamkit_io::g2o::G2oGraph;

/// A relative pose measurement between two nodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// Index of the node the measurement is expressed in.
    pub from: usize,
    /// Index of the measured node.
    pub to: usize,
    /// Measured pose of `to` in the frame of `from`.
    pub from_from_to: Pose3,
    /// Information (inverse covariance) of the error `(ρ, φ)`: translation, then rotation.
    pub information: Matrix6<f64>,
    /// Scale of the Cauchy kernel on the Mahalanobis error (`None`: plain least squares).
    pub robust_scale: Option<f64>,
}

/// Settings of the Levenberg–Marquardt optimiser.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LmConfig {
    /// Upper limit on iterations (linearisations).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction of it.
    pub relative_tolerance: f64,
    /// Stop when an accepted step lowers the cost by less than this.
    pub absolute_tolerance: f64,
    /// Initial damping `τ`, relative to the diagonal of `H`.
    pub initial_damping: f64,
    /// Give up an iteration after this many rejected steps in a row.
    pub max_rejections: usize,
}

impl Default for LmConfig {
    /// 100 iterations; tolerances 1e-5 relative and absolute (GTSAM's defaults); τ = 1e-5
    /// (g2o's default τ, here with Marquardt's scaling); 10 rejections.
    fn default() -> Self {
        Self {
            max_iterations: 100,
            relative_tolerance: 1e-5,
            absolute_tolerance: 1e-5,
            initial_damping: 1e-5,
            max_rejections: 10,
        }
    }
}

/// What an optimisation did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OptimizeSummary {
    /// Iterations run (linearisations, each ending in an accepted step or giving up).
    pub iterations: usize,
    /// Steps rejected by the gain ratio, over all iterations.
    pub rejected_steps: usize,
    /// Robust cost (`½ Σ ρ(eᵀΩe)`) before the first step.
    pub initial_cost: f64,
    /// Robust cost after the last step.
    pub final_cost: f64,
}

/// Poses and the relative measurements between them.
#[derive(Debug, Clone, Default)]
pub struct PoseGraph {
    nodes: Vec<Pose3>,
    fixed: Vec<bool>,
    edges: Vec<Edge>,
}

impl PoseGraph {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a node at `world_from_node` and returns its index. The first node is held fixed
    /// unless [`PoseGraph::set_fixed`] says otherwise.
    pub fn add_node(&mut self, world_from_node: Pose3) -> usize {
        self.fixed.push(self.nodes.is_empty());
        self.nodes.push(world_from_node);
        self.nodes.len() - 1
    }

    /// Holds node `i` fixed (or frees it); false when there is no such node.
    pub fn set_fixed(&mut self, i: usize, fixed: bool) -> bool {
        self.fixed.get_mut(i).map(|f| *f = fixed).is_some()
    }

    /// Adds an edge after checking it: both nodes exist and differ, the values are finite,
    /// the information matrix is symmetric positive definite and the kernel scale positive.
    pub fn add_edge(&mut self, edge: Edge) -> Result<(), VoError> {
        let bad = |reason| {
            Err(VoError::InvalidEdge {
                from: edge.from,
                to: edge.to,
                reason,
            })
        };
        if edge.from == edge.to || edge.from.max(edge.to) >= self.nodes.len() {
            return bad("a node is missing or the edge is a self-loop");
        }
        let z = &edge.from_from_to;
        if !(z.translation.vector.iter().chain(z.rotation.coords.iter()))
            .chain(edge.information.iter())
            .all(|v| v.is_finite())
        {
            return bad("a value is not finite");
        }
        if (edge.information - edge.information.transpose()).amax() > 1e-9 * edge.information.amax()
            || nalgebra::Cholesky::new(edge.information).is_none()
        {
            return bad("the information matrix is not symmetric positive definite");
        }
        if edge
            .robust_scale
            .is_some_and(|k| !(k.is_finite() && k > 0.0))
        {
            return bad("the kernel scale is not finite and positive");
        }
        self.edges.push(edge);
        Ok(())
    }

    /// The graph a g2o file holds ([`slamkit_io::g2o`]): its vertices in file order, its
    /// edges without a kernel, its `FIX` vertices held (the first vertex when there are none).
    pub fn from_g2o(g2o: &G2oGraph) -> Result<Self, VoError> {
        let mut graph = Self::new();
        for v in &g2o.vertices {
            graph.add_node(v.world_from_vertex);
        }
        if !g2o.fixed.is_empty() {
            graph.set_fixed(0, false);
            for &i in &g2o.fixed {
                graph.set_fixed(i, true);
            }
        }
        for e in &g2o.edges {
            graph.add_edge(Edge {
                from: e.from,
                to: e.to,
                from_from_to: e.from_from_to,
                information: e.information,
                robust_scale: None,
            })?;
        }
        Ok(graph)
    }

    /// The node poses.
    pub fn nodes(&self) -> &[Pose3] {
        &self.nodes
    }

    /// The edges.
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }

    /// Robust cost `½ Σ ρ(eᵀΩe)` of the current poses.
    pub fn cost(&self) -> f64 {
        cost_at(&self.nodes, &self.edges)
    }

    /// Runs Levenberg–Marquardt until a tolerance of `config` is met or the iterations run
    /// out.
    ///
    /// ```
    /// use nalgebra::{Matrix6, Translation3, UnitQuaternion};
    /// use slamkit_core::Pose3;
    /// use slamkit_vo::pose_graph::{Edge, LmConfig, PoseGraph};
    ///
    /// let step = Pose3::from_parts(Translation3::new(1.0, 0.0, 0.0), UnitQuaternion::identity());
    /// let mut graph = PoseGraph::new();
    /// graph.add_node(Pose3::identity());
    /// graph.add_node(Pose3::translation(0.7, 0.2, 0.0)); // a poor initial guess
    /// let edge = Edge {
    ///     from: 0,
    ///     to: 1,
    ///     from_from_to: step,
    ///     information: Matrix6::identity(),
    ///     robust_scale: None,
    /// };
    /// graph.add_edge(edge).unwrap();
    /// let summary = graph.optimize(&LmConfig::default());
    /// assert!(summary.final_cost < 1e-12 && summary.initial_cost > 0.0);
    /// assert!((graph.nodes()[1].translation.vector - step.translation.vector).norm() < 1e-6);
    /// ```
    pub fn optimize(&mut self, config: &LmConfig) -> OptimizeSummary {
        let pairs: Vec<(usize, usize)> = self.edges.iter().map(|e| (e.from, e.to)).collect();
        let elimination = Elimination::new(self.nodes.len(), &pairs);
        let initial_cost = self.cost();
        let mut summary = OptimizeSummary {
            iterations: 0,
            rejected_steps: 0,
            initial_cost,
            final_cost: initial_cost,
        };
        let mut cost = initial_cost;
        let mut lambda: Option<f64> = None;
        let mut nu = 2.0;
        while summary.iterations < config.max_iterations && cost > 0.0 {
            summary.iterations += 1;
            let system = self.linearize(&elimination);
            let mut l = *lambda.get_or_insert(config.initial_damping);
            let mut accepted = None;
            for _ in 0..config.max_rejections.max(1) {
                let Some((step, predicted)) = system.damped_step(l) else {
                    break;
                };
                let moved: Vec<Pose3> = self
                    .nodes
                    .iter()
                    .zip(&step)
                    .map(|(t, d)| t * se3::exp(d))
                    .collect();
                let new_cost = cost_at(&moved, &self.edges);
                let gain_ratio = (cost - new_cost) / predicted;
                if predicted > 0.0 && gain_ratio > 0.0 && new_cost.is_finite() {
                    l *= (1.0 - (2.0 * gain_ratio - 1.0).powi(3)).max(1.0 / 3.0);
                    nu = 2.0;
                    accepted = Some((moved, new_cost));
                    break;
                }
                summary.rejected_steps += 1;
                l *= nu;
                nu *= 2.0;
            }
            lambda = Some(l);
            let Some((moved, new_cost)) = accepted else {
                break;
            };
            self.nodes = moved;
            let decrease = cost - new_cost;
            cost = new_cost;
            if decrease < config.absolute_tolerance
                || decrease < config.relative_tolerance * (cost + decrease)
            {
                break;
            }
        }
        summary.final_cost = cost;
        summary
    }

    /// The normal equations (robustly reweighted) at the current poses.
    fn linearize<'a>(&self, elimination: &'a Elimination) -> Linearization<'a> {
        let mut system = BlockSystem::<6>::new(elimination);
        for (i, e) in self.edges.iter().enumerate() {
            let (Some(a), Some(b)) = (self.nodes.get(e.from), self.nodes.get(e.to)) else {
                continue;
            };
            let (r, ja, jb) = edge_error_and_jacobians(&e.from_from_to, a, b);
            let (_, w) = cauchy(e.robust_scale, r.dot(&(e.information * r)));
            let omega = e.information * w;
            let fixed = |n: usize| self.fixed.get(n).copied().unwrap_or(true);
            let (fa, fb) = (fixed(e.from), fixed(e.to));
            let (ja_t_omega, jb_t_omega) = (ja.transpose() * omega, jb.transpose() * omega);
            if !fa {
                system.add_diag(e.from, ja_t_omega * ja, ja_t_omega * r);
            }
            if !fb {
                system.add_diag(e.to, jb_t_omega * jb, jb_t_omega * r);
            }
            if !fa && !fb {
                system.add_off(i, ja_t_omega * jb);
            }
        }
        // A fixed node's block is the identity with a zero right-hand side: its step is zero.
        let fixed = self.fixed.clone();
        system.add_to_diagonals(|i, _| {
            if fixed.get(i).copied().unwrap_or(true) {
                Matrix6::identity()
            } else {
                Matrix6::zeros()
            }
        });
        Linearization { system, fixed }
    }
}

/// The normal equations `H δ = −g` at one linearisation point.
struct Linearization<'a> {
    system: BlockSystem<'a, 6>,
    fixed: Vec<bool>,
}

impl Linearization<'_> {
    /// The step for damping `lambda` and the cost decrease the quadratic model predicts for it,
    /// `½ δᵀ(λDδ − g)`; `None` when the damped system is singular.
    fn damped_step(&self, lambda: f64) -> Option<(Vec<Vector6<f64>>, f64)> {
        let mut damped = self.system.clone();
        let fixed = &self.fixed;
        damped.add_to_diagonals(|i, d| {
            if fixed.get(i).copied().unwrap_or(true) {
                Matrix6::zeros()
            } else {
                Matrix6::from_diagonal(&(damping_diagonal(d) * lambda))
            }
        });
        let step: Vec<Vector6<f64>> = damped.solve()?.into_iter().map(|d| -d).collect();
        let predicted = step
            .iter()
            .enumerate()
            .filter_map(|(i, d)| {
                let scaled = damping_diagonal(self.system.diagonal(i)?).component_mul(d);
                Some(0.5 * d.dot(&(scaled * lambda - self.system.rhs(i)?)))
            })
            .sum();
        Some((step, predicted))
    }
}

/// Marquardt's damping scale `D` of a diagonal block of `H`: its diagonal, clamped to
/// \[1e-6, 1e32\] as Ceres does so that an unobserved direction still gets damped.
fn damping_diagonal(block: &Matrix6<f64>) -> Vector6<f64> {
    block.diagonal().map(|v| v.clamp(1e-6, 1e32))
}

/// The error `e = log(Z⁻¹ A⁻¹ B)` of a measurement `Z` of pose `b` in the frame of pose `a`,
/// with its Jacobians with respect to right perturbations of `a` and of `b`.
fn edge_error_and_jacobians(
    z: &Pose3,
    a: &Pose3,
    b: &Pose3,
) -> (Vector6<f64>, Matrix6<f64>, Matrix6<f64>) {
    let b_from_a = b.inverse() * a;
    let r = se3::log(&(z.inverse() * b_from_a.inverse()));
    let jb = se3::right_jacobian_inv(&r);
    let ja = -jb * se3::adjoint(&b_from_a);
    (r, ja, jb)
}

/// Robust cost of `edges` at poses `nodes`.
fn cost_at(nodes: &[Pose3], edges: &[Edge]) -> f64 {
    edges
        .iter()
        .filter_map(|e| {
            let (a, b) = (nodes.get(e.from)?, nodes.get(e.to)?);
            let r = se3::log(&(e.from_from_to.inverse() * a.inverse() * b));
            Some(cauchy(e.robust_scale, r.dot(&(e.information * r))).0)
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn pose(x: f64, y: f64, z: f64, rx: f64, ry: f64, rz: f64) -> Pose3 {
        Pose3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_scaled_axis(Vector3::new(rx, ry, rz)),
        )
    }

    fn edge(from: usize, to: usize, z: Pose3, robust_scale: Option<f64>) -> Edge {
        Edge {
            from,
            to,
            from_from_to: z,
            information: Matrix6::from_diagonal(&Vector6::new(100.0, 100.0, 100.0, 1e3, 1e3, 1e3)),
            robust_scale,
        }
    }

    /// A climbing loop of `n` poses (a helix turn), the truth; and a graph of odometry edges
    /// with the given noise (translation m, rotation rad) plus a loop closure from the last
    /// pose to the first, initialised by chaining the odometry.
    fn helix(n: usize, noise: f64, seed: u64) -> (Vec<Pose3>, PoseGraph) {
        let truth: Vec<Pose3> = (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                pose(
                    5.0 * a.cos(),
                    5.0 * a.sin(),
                    0.1 * i as f64,
                    0.1 * a.sin(),
                    0.05,
                    a,
                )
            })
            .collect();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut jitter = || {
            let v = Vector6::from_fn(|_, _| rng.gen_range(-1.0..1.0)) * noise;
            se3::exp(&v)
        };
        let mut graph = PoseGraph::new();
        graph.add_node(truth[0]);
        for i in 1..n {
            let z = truth[i - 1].inverse() * truth[i] * jitter();
            let guess = graph.nodes()[i - 1] * z;
            graph.add_node(guess);
            graph.add_edge(edge(i - 1, i, z, None)).unwrap();
        }
        let z = truth[n - 1].inverse() * truth[0] * jitter();
        graph.add_edge(edge(n - 1, 0, z, None)).unwrap();
        (truth, graph)
    }

    fn largest_error(truth: &[Pose3], graph: &PoseGraph) -> f64 {
        truth
            .iter()
            .zip(graph.nodes())
            .map(|(t, g)| se3::log(&(t.inverse() * g)).norm())
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_noise_free_loop_converges_to_zero_cost() {
        let (truth, mut graph) = helix(40, 0.0, 1);
        // Start far from the truth: bend every pose but the fixed first one.
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for node in graph.nodes.iter_mut().skip(1) {
            let d = Vector6::from_fn(|_, _| rng.gen_range(-0.3..0.3));
            *node *= se3::exp(&d);
        }
        let summary = graph.optimize(&LmConfig {
            relative_tolerance: 0.0,
            absolute_tolerance: 1e-20,
            ..LmConfig::default()
        });
        assert!(summary.initial_cost > 1e3, "{summary:?}");
        assert!(summary.final_cost < 1e-18, "{summary:?}");
        assert!(
            largest_error(&truth, &graph) < 1e-9,
            "{}",
            largest_error(&truth, &graph)
        );
        assert_eq!(graph.nodes()[0], truth[0], "the first node is held");
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let z = pose(0.3, -0.2, 0.1, 0.2, -0.1, 0.4);
        let a = pose(1.0, 2.0, -0.5, 0.3, 0.2, 0.7);
        let b = pose(1.5, 1.6, -0.2, 0.1, 0.5, 1.2);
        let (r, ja, jb) = edge_error_and_jacobians(&z, &a, &b);
        assert!(
            r.norm() > 0.3,
            "a large error tests the exact Jacobians: {r}"
        );
        let h = 1e-6;
        for k in 0..6 {
            let mut d = Vector6::zeros();
            d[k] = h;
            let (up, down) = (se3::exp(&d), se3::exp(&(-d)));
            let err = |a: &Pose3, b: &Pose3| edge_error_and_jacobians(&z, a, b).0;
            let da = (err(&(a * up), &b) - err(&(a * down), &b)) / (2.0 * h);
            let db = (err(&a, &(b * up)) - err(&a, &(b * down))) / (2.0 * h);
            assert!((da - ja.column(k)).norm() < 1e-7, "ja column {k}: {da}");
            assert!((db - jb.column(k)).norm() < 1e-7, "jb column {k}: {db}");
        }
    }

    #[test]
    fn noisy_loop_closes_and_lowers_the_cost() {
        let (truth, mut graph) = helix(60, 0.01, 3);
        let before = largest_error(&truth, &graph);
        let summary = graph.optimize(&LmConfig::default());
        let after = largest_error(&truth, &graph);
        assert!(after < 0.5 * before, "{before} -> {after}");
        assert!(
            summary.final_cost < 0.1 * summary.initial_cost,
            "{summary:?}"
        );
        assert!(
            summary.iterations >= 2 && summary.iterations < 20,
            "{summary:?}"
        );
    }

    #[test]
    fn a_robust_kernel_bounds_a_wrong_loop_closure() {
        let run = |robust_scale| {
            let (truth, mut graph) = helix(60, 0.005, 4);
            graph.optimize(&LmConfig::default());
            let wrong = truth[30].inverse() * truth[5] * pose(3.0, -2.0, 1.0, 0.5, 0.2, -0.4);
            graph.add_edge(edge(30, 5, wrong, robust_scale)).unwrap();
            graph.optimize(&LmConfig::default());
            largest_error(&truth, &graph)
        };
        let (plain, robust) = (run(None), run(Some(1.0)));
        assert!(robust < 0.1, "with a Cauchy kernel: {robust}");
        assert!(plain > 5.0 * robust, "plain {plain}, robust {robust}");
    }

    #[test]
    fn fixed_nodes_hold_and_free_nodes_move() {
        let (truth, mut graph) = helix(20, 0.01, 5);
        assert!(graph.set_fixed(10, true) && !graph.set_fixed(99, true));
        let held = graph.nodes()[10];
        graph.optimize(&LmConfig::default());
        assert_eq!(graph.nodes()[10], held);
        assert_eq!(graph.nodes()[0], truth[0]);
        assert_ne!(graph.nodes()[5], truth[5]);
    }

    #[test]
    fn a_g2o_graph_keeps_its_fixed_vertices() {
        let info = "1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1";
        let text = format!(
            "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n\
             EDGE_SE3:QUAT 0 1 2 0 0 0 0 0 1 {info}\nFIX 1\n"
        );
        let mut graph = PoseGraph::from_g2o(&slamkit_io::g2o::parse_g2o(&text).unwrap()).unwrap();
        assert_eq!(graph.cost(), 0.5);
        graph.optimize(&LmConfig::default());
        // Vertex 1 is held, so vertex 0 moves to x = −1.
        assert!((graph.nodes()[0].translation.x + 1.0).abs() < 1e-9);
        assert_eq!(graph.nodes()[1].translation.x, 1.0);
    }

    #[test]
    fn bad_edges_are_refused() {
        let mut graph = PoseGraph::new();
        graph.add_node(Pose3::identity());
        graph.add_node(Pose3::identity());
        let ok = edge(0, 1, Pose3::identity(), None);
        let mut not_pd = ok;
        not_pd.information[(5, 5)] = -1.0;
        let mut asymmetric = ok;
        asymmetric.information[(0, 1)] = 5.0;
        let mut nan = ok;
        nan.from_from_to.translation.x = f64::NAN;
        let cases = [
            (edge(0, 0, Pose3::identity(), None), "self-loop"),
            (edge(0, 2, Pose3::identity(), None), "missing"),
            (nan, "not finite"),
            (not_pd, "positive definite"),
            (asymmetric, "positive definite"),
            (edge(0, 1, Pose3::identity(), Some(-1.0)), "kernel scale"),
        ];
        for (e, why) in cases {
            let err = graph.add_edge(e).unwrap_err().to_string();
            assert!(err.contains(why), "{err}");
        }
        assert!(graph.edges().is_empty());
        graph.add_edge(ok).unwrap();
        assert_eq!(graph.optimize(&LmConfig::default()).final_cost, 0.0);
    }
}
