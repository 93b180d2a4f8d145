//! A 2D pose graph and its sparse Gauss–Newton solver: the SLAM back end that corrects the
//! drift of incremental scan matching once loop closures tie new poses to old ones (Lu & Milios,
//! "Globally consistent range scan alignment", 1997; Grisetti et al., "A tutorial on graph-based
//! SLAM", 2010, whose error and Jacobians on SE(2) are used here; Hess et al. 2016 do the same
//! with submaps).
//!
//! Nodes are poses `world_from_node`; an edge holds a measured `from_from_to` with its
//! information matrix. Each Gauss–Newton step solves the block-sparse normal equations by
//! eliminating nodes one at a time in minimum-degree order (variable elimination, i.e. a sparse
//! block LDLᵀ factorisation with 3×3 blocks, [`slamkit_core::block_elimination`]; the order and
//! fill-in are worked out once per optimisation and reused by every iteration), which keeps the
//! fill-in small on the near-planar graphs a robot builds. Edges may carry a Cauchy kernel (iteratively reweighted), so a wrong loop closure
//! pulls with bounded force. The first node is held fixed.

use nalgebra::{Matrix3, Vector2, Vector3};
use slamkit_core::block_elimination::{BlockSystem, Elimination};
use slamkit_core::robust::cauchy;
use slamkit_core::Pose2;

/// A relative pose measurement between two nodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// Index of the node the measurement is expressed in.
    pub from: usize,
    /// Index of the measured node.
    pub to: usize,
    /// Measured pose of `to` in the frame of `from`.
    pub from_from_to: Pose2,
    /// Information (inverse covariance) of `(x, y, θ)` in the frame of `from` \[1/m², 1/rad²\].
    pub information: Matrix3<f64>,
    /// Scale of the Cauchy kernel on the Mahalanobis error (`None`: plain least squares).
    pub robust_scale: Option<f64>,
}

/// What an optimisation did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OptimizeSummary {
    /// Gauss–Newton iterations run.
    pub iterations: usize,
    /// Robust cost (sum of ½ρ(χ²) over edges) before the first step.
    pub initial_cost: f64,
    /// Robust cost after the last step.
    pub final_cost: f64,
}

/// Poses and the relative measurements between them.
#[derive(Debug, Clone, Default)]
pub struct PoseGraph {
    nodes: Vec<Pose2>,
    edges: Vec<Edge>,
}

impl PoseGraph {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a node at `world_from_node` and returns its index.
    pub fn add_node(&mut self, world_from_node: Pose2) -> usize {
        self.nodes.push(world_from_node);
        self.nodes.len() - 1
    }

    /// Adds an edge; returns false (and adds nothing) when a node index is out of range, the
    /// edge is a self-loop or a value is not finite.
    pub fn add_edge(&mut self, edge: Edge) -> bool {
        let finite = edge.information.iter().all(|v| v.is_finite())
            && edge
                .from_from_to
                .translation
                .vector
                .iter()
                .all(|v| v.is_finite())
            && edge.from_from_to.rotation.angle().is_finite();
        if edge.from == edge.to || edge.from.max(edge.to) >= self.nodes.len() || !finite {
            return false;
        }
        self.edges.push(edge);
        true
    }

    /// The node poses.
    pub fn nodes(&self) -> &[Pose2] {
        &self.nodes
    }

    /// The edges.
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }

    /// Runs up to `max_iterations` Gauss–Newton steps, stopping once a step moves no node by
    /// more than `tolerance` (in metres and radians).
    pub fn optimize(&mut self, max_iterations: usize, tolerance: f64) -> OptimizeSummary {
        let initial_cost = self.cost();
        let mut iterations = 0;
        let elimination = self.elimination();
        while iterations < max_iterations && self.nodes.len() > 1 {
            iterations += 1;
            let Some(step) = self.solve_step(&elimination) else {
                break;
            };
            let mut largest: f64 = 0.0;
            for (node, d) in self.nodes.iter_mut().zip(&step) {
                let (t, a) = (node.translation.vector, node.rotation.angle());
                *node = Pose2::new(t + d.xy(), a + d.z);
                largest = largest.max(d.abs().max());
            }
            if largest < tolerance {
                break;
            }
        }
        OptimizeSummary {
            iterations,
            initial_cost,
            final_cost: self.cost(),
        }
    }

    /// Robust cost of the current poses.
    pub fn cost(&self) -> f64 {
        self.edges
            .iter()
            .filter_map(|e| {
                let (a, b) = (self.nodes.get(e.from)?, self.nodes.get(e.to)?);
                let r = edge_error(e, (a, a.rotation.angle()), (b, b.rotation.angle()));
                Some(cauchy(e.robust_scale, r.dot(&(e.information * r))).0)
            })
            .sum()
    }

    /// The elimination order and fill-in of the graph's normal equations.
    fn elimination(&self) -> Elimination {
        let pairs: Vec<(usize, usize)> = self.edges.iter().map(|e| (e.from, e.to)).collect();
        Elimination::new(self.nodes.len(), &pairs)
    }

    /// Builds and solves the normal equations at the current poses; `None` when singular.
    fn solve_step(&self, elimination: &Elimination) -> Option<Vec<Vector3<f64>>> {
        let mut system = BlockSystem::<3>::new(elimination);
        // Hold the first node: a stiff prior on its increment.
        system.add_diag(0, Matrix3::identity() * 1e12, Vector3::zeros());
        // Each node's angle once per step rather than once per edge (atan2 was a third of the
        // optimisation's time).
        let angles: Vec<f64> = self.nodes.iter().map(|n| n.rotation.angle()).collect();
        for (i, e) in self.edges.iter().enumerate() {
            let (Some(a), Some(b)) = (self.nodes.get(e.from), self.nodes.get(e.to)) else {
                continue;
            };
            let (Some(&ta), Some(&tb)) = (angles.get(e.from), angles.get(e.to)) else {
                continue;
            };
            let r = edge_error(e, (a, ta), (b, tb));
            let (ja, jb) = edge_jacobians(e, a, ta, b);
            let (_, w) = cauchy(e.robust_scale, r.dot(&(e.information * r)));
            let omega = e.information * w;
            system.add_diag(
                e.from,
                ja.transpose() * omega * ja,
                ja.transpose() * omega * r,
            );
            system.add_diag(
                e.to,
                jb.transpose() * omega * jb,
                jb.transpose() * omega * r,
            );
            system.add_off(i, ja.transpose() * omega * jb);
        }
        system.solve().map(|x| x.into_iter().map(|d| -d).collect())
    }
}

/// Error of edge `e` at poses `a` (of `from`) and `b` (of `to`), each given with its angle: the
/// measured pose of `b` in `a`'s frame against the predicted one,
/// `(R_zᵀ(R_aᵀ(t_b − t_a) − t_z), θ_b − θ_a − θ_z)`.
fn edge_error(e: &Edge, (a, ta): (&Pose2, f64), (b, tb): (&Pose2, f64)) -> Vector3<f64> {
    let z = &e.from_from_to;
    let dt = a.rotation.inverse() * (b.translation.vector - a.translation.vector);
    let et = z.rotation.inverse() * (dt - z.translation.vector);
    let ea = wrap(tb - ta - z.rotation.angle());
    Vector3::new(et.x, et.y, ea)
}

/// Jacobians of [`edge_error`] with respect to `(x, y, θ)` of `a` (at angle `ta`) and of `b`.
fn edge_jacobians(e: &Edge, a: &Pose2, ta: f64, b: &Pose2) -> (Matrix3<f64>, Matrix3<f64>) {
    let rz_t = e.from_from_to.rotation.inverse().to_rotation_matrix();
    let ra_t = a.rotation.inverse().to_rotation_matrix();
    let (s, c) = ta.sin_cos();
    let dt = b.translation.vector - a.translation.vector;
    // d(R_aᵀ)/dθ · dt
    let d_ra_t = Vector2::new(-s * dt.x + c * dt.y, -c * dt.x - s * dt.y);
    let rr = rz_t.matrix() * ra_t.matrix();
    let col = rz_t.matrix() * d_ra_t;
    let ja = Matrix3::new(
        -rr[(0, 0)],
        -rr[(0, 1)],
        col.x,
        -rr[(1, 0)],
        -rr[(1, 1)],
        col.y,
        0.0,
        0.0,
        -1.0,
    );
    let jb = Matrix3::new(
        rr[(0, 0)],
        rr[(0, 1)],
        0.0,
        rr[(1, 0)],
        rr[(1, 1)],
        0.0,
        0.0,
        0.0,
        1.0,
    );
    (ja, jb)
}

/// An angle wrapped to (−π, π]: returned as it is when already there (edge errors are small,
/// so almost always; the sine–cosine–arctangent round trip it replaces was a tenth of the
/// optimisation's time), else shifted by whole turns.
fn wrap(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if a > -PI && a <= PI {
        return a;
    }
    let w = a - TAU * (a / TAU).round();
    if w <= -PI {
        w + TAU
    } else if w > PI {
        w - TAU
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A pose with its angle, as the solver passes nodes to the edge functions.
    fn at(p: &Pose2) -> (&Pose2, f64) {
        (p, p.rotation.angle())
    }

    fn edge(from: usize, to: usize, z: Pose2, robust_scale: Option<f64>) -> Edge {
        Edge {
            from,
            to,
            from_from_to: z,
            information: Matrix3::from_diagonal(&Vector3::new(100.0, 100.0, 1000.0)),
            robust_scale,
        }
    }

    /// A square loop of `n` poses per side: the true poses, and a graph of odometry edges with a
    /// heading bias (so the chain drifts) plus one exact loop-closure edge.
    fn drifting_square(n: usize) -> (Vec<Pose2>, PoseGraph) {
        let mut truth = vec![Pose2::identity()];
        for _side in 0..4 {
            for s in 0..n {
                let turn = if s == n - 1 {
                    std::f64::consts::FRAC_PI_2
                } else {
                    0.0
                };
                let last = truth[truth.len() - 1];
                truth.push(last * Pose2::new(Vector2::new(0.5, 0.0), turn));
            }
        }
        let mut graph = PoseGraph::new();
        let mut est = Pose2::identity();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        graph.add_node(est);
        for i in 1..truth.len() {
            let z = truth[i - 1].inverse() * truth[i];
            let noisy = Pose2::new(
                z.translation.vector + Vector2::new(rng.gen_range(-0.01..0.01), 0.0),
                z.rotation.angle() + 0.01,
            );
            est *= noisy;
            graph.add_node(est);
            assert!(graph.add_edge(edge(i - 1, i, noisy, None)));
        }
        let last = truth.len() - 1;
        assert!(graph.add_edge(edge(0, last, truth[0].inverse() * truth[last], None)));
        (truth, graph)
    }

    fn end_error(truth: &[Pose2], graph: &PoseGraph) -> f64 {
        let last = truth.len() - 1;
        (truth[last].translation.vector - graph.nodes()[last].translation.vector).norm()
    }

    #[test]
    fn loop_closure_removes_drift() {
        let (truth, mut graph) = drifting_square(20);
        let before = end_error(&truth, &graph);
        let summary = graph.optimize(20, 1e-9);
        let after = end_error(&truth, &graph);
        assert!(before > 1.0, "drift before {before}");
        assert!(after < 0.05, "error after {after}");
        assert!(summary.final_cost < 0.01 * summary.initial_cost);
        let first = graph.nodes()[0];
        assert!(first.translation.vector.norm() < 1e-9 && first.rotation.angle().abs() < 1e-9);
    }

    #[test]
    fn elimination_matches_a_dense_solve() {
        let (_, graph) = drifting_square(5);
        let elimination = graph.elimination();
        let sparse = graph.solve_step(&elimination).unwrap();
        let n = graph.nodes().len();
        let mut h = nalgebra::DMatrix::<f64>::zeros(3 * n, 3 * n);
        let mut g = nalgebra::DVector::<f64>::zeros(3 * n);
        for i in 0..3 {
            h[(i, i)] += 1e12;
        }
        for e in graph.edges() {
            let (a, b) = (graph.nodes()[e.from], graph.nodes()[e.to]);
            let r = edge_error(e, at(&a), at(&b));
            let (ja, jb) = edge_jacobians(e, &a, a.rotation.angle(), &b);
            let mut j = nalgebra::DMatrix::<f64>::zeros(3, 3 * n);
            j.view_mut((0, 3 * e.from), (3, 3)).copy_from(&ja);
            j.view_mut((0, 3 * e.to), (3, 3)).copy_from(&jb);
            h += j.transpose() * e.information * &j;
            g += j.transpose() * (e.information * r);
        }
        let dense = -h.lu().solve(&g).unwrap();
        for (i, s) in sparse.iter().enumerate() {
            for c in 0..3 {
                assert!((s[c] - dense[3 * i + c]).abs() < 1e-6, "node {i}");
            }
        }
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let e = edge(0, 1, Pose2::new(Vector2::new(0.3, -0.2), 0.4), None);
        let a = Pose2::new(Vector2::new(1.0, 2.0), 0.7);
        let b = Pose2::new(Vector2::new(1.5, 1.6), 1.2);
        let (ja, jb) = edge_jacobians(&e, &a, a.rotation.angle(), &b);
        let bump = |p: &Pose2, k: usize, h: f64| {
            let mut v = Vector3::new(p.translation.vector.x, p.translation.vector.y, 0.0);
            v[k] += h;
            Pose2::new(v.xy(), p.rotation.angle() + if k == 2 { h } else { 0.0 })
        };
        let h = 1e-6;
        for k in 0..3 {
            let (a_up, a_down) = (bump(&a, k, h), bump(&a, k, -h));
            let (b_up, b_down) = (bump(&b, k, h), bump(&b, k, -h));
            let da = (edge_error(&e, at(&a_up), at(&b)) - edge_error(&e, at(&a_down), at(&b)))
                / (2.0 * h);
            let db = (edge_error(&e, at(&a), at(&b_up)) - edge_error(&e, at(&a), at(&b_down)))
                / (2.0 * h);
            assert!((da - ja.column(k)).norm() < 1e-6, "ja column {k}");
            assert!((db - jb.column(k)).norm() < 1e-6, "jb column {k}");
        }
    }

    #[test]
    fn a_robust_kernel_bounds_a_wrong_loop_closure() {
        let (truth, mut graph) = drifting_square(20);
        let last = truth.len() - 1;
        let wrong = truth[10].inverse() * truth[last] * Pose2::new(Vector2::new(3.0, 0.0), 0.5);
        assert!(graph.add_edge(edge(10, last, wrong, Some(1.0))));
        graph.optimize(30, 1e-9);
        assert!(
            end_error(&truth, &graph) < 0.3,
            "{}",
            end_error(&truth, &graph)
        );
    }

    #[test]
    fn wrap_keeps_angles_in_range_and_equals_the_trig_round_trip() {
        use std::f64::consts::PI;
        for a in [0.0, 0.3, -2.9, PI, -PI, 3.5, -3.5, 7.0, -9.0, 2.0 * PI, 1e3] {
            let w = wrap(a);
            assert!(w > -PI && w <= PI, "{a} -> {w}");
            assert!(
                (w - a.sin().atan2(a.cos())).abs() < 1e-9 || (w - PI).abs() < 1e-9,
                "{a}"
            );
            assert!(((w - a) / (2.0 * PI)).fract().abs() < 1e-9 || a.abs() > 100.0);
        }
        assert_eq!(wrap(1.25), 1.25);
        assert!(wrap(f64::NAN).is_nan());
    }

    #[test]
    fn bad_edges_are_refused() {
        let mut graph = PoseGraph::new();
        graph.add_node(Pose2::identity());
        assert!(!graph.add_edge(edge(0, 0, Pose2::identity(), None)));
        assert!(!graph.add_edge(edge(0, 3, Pose2::identity(), None)));
        graph.add_node(Pose2::identity());
        let nan = Pose2::new(Vector2::new(f64::NAN, 0.0), 0.0);
        assert!(!graph.add_edge(edge(0, 1, nan, None)));
        assert_eq!(graph.optimize(5, 1e-9).iterations, 1);
    }
}
