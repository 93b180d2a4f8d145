//! 2D iterative closest point: point-to-point (Besl & McKay 1992) and point-to-line (Chen &
//! Medioni 1992; Censi, "An ICP variant using a point-to-line metric", ICRA 2008).
//!
//! Each iteration pairs every source point with its nearest target point within a distance
//! threshold (k-d tree or uniform grid, see [`crate::nn`]), drops the points with none, weights
//! the rest with a robust kernel (iteratively reweighted least squares; Zhang 1997 for the
//! M-estimators) and takes one Gauss–Newton or Levenberg–Marquardt step on the pose. Like MRPT's
//! `CICP`, the threshold starts wide and, each time the pose stops moving, is multiplied by a
//! factor below one until it reaches its minimum: wide thresholds pull in a poor guess, narrow
//! ones give a precise, outlier-free finish.
//!
//! Most iterations move the points by far less than the gap between their nearest and their
//! second-nearest target point, so each point keeps its last answer while that gap proves it
//! unchanged (the correspondence cache below): the pairs are exactly those a fresh search
//! gives, at a fraction of the searches.
//!
//! The pose increment is applied on the left, in the target frame:
//! `target_from_source ← exp(δ) · target_from_source`, so for a transformed point `q` the
//! Jacobian of `q` with respect to `δ = (δx, δy, δθ)` is `\[I | (−q_y, q_x)ᵀ\]`.

use crate::nn::NearestNeighbours;
use crate::LidarError;
use nalgebra::{Matrix3, Point2, Vector2, Vector3};
use serde::{Deserialize, Serialize};
use slamkit_core::Pose2;

/// The error ICP minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IcpMetric {
    /// Euclidean distance between paired points.
    PointToPoint,
    /// Distance from the source point to the line through the target point along its normal;
    /// pairs whose target has no normal fall back to point-to-point.
    PointToLine,
}

/// Robust M-estimator applied to residuals; `kernel_scale_m` is its scale `k`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RobustKernel {
    /// Plain least squares.
    None,
    /// Quadratic below `k`, linear above.
    Huber,
    /// `k²/2 · ln(1 + (r/k)²)`: heavy outliers keep a small weight.
    Cauchy,
    /// Tukey's biweight: residuals beyond `k` get zero weight.
    Tukey,
}

/// How each pose step is computed from the normal equations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IcpSolver {
    /// Undamped Gauss–Newton: fast, but fails on degenerate geometry.
    GaussNewton,
    /// Levenberg–Marquardt (Marquardt 1963 damping `λ·diag(H)`): a step is kept only if it
    /// lowers the robust cost, so a long corridor cannot throw the pose far along its axis.
    LevenbergMarquardt,
}

/// ICP parameters. Defaults follow MRPT's `icp-slam_demo_LM.ini` where it has an equivalent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IcpConfig {
    /// Error metric.
    pub metric: IcpMetric,
    /// Robust kernel on residuals.
    pub kernel: RobustKernel,
    /// Scale of the robust kernel at the smallest correspondence threshold \[m\]; while the
    /// threshold is wider the scale grows in proportion, so the kernel never rejects the pairs
    /// the threshold admits.
    pub kernel_scale_m: f64,
    /// Step computation.
    pub solver: IcpSolver,
    /// Upper limit on iterations over all thresholds (MRPT `maxIterations`).
    pub max_iterations: u32,
    /// Upper limit on iterations at one threshold: correspondences that flip between two
    /// neighbours can keep the pose dithering, and must not keep a wide threshold forever.
    pub max_iterations_per_threshold: u32,
    /// Initial correspondence distance threshold \[m\] (MRPT `thresholdDist`).
    pub max_correspondence_dist_m: f64,
    /// Smallest the threshold may shrink to \[m\] (MRPT `smallestThresholdDist`); it is also the
    /// distance within which a point counts as matched in the goodness score.
    pub min_correspondence_dist_m: f64,
    /// Factor applied to the threshold each time the pose converges (MRPT `ALFA`), in (0, 1].
    pub dist_shrink_factor: f64,
    /// A step with translation below this counts as converged \[m\].
    pub min_step_trans_m: f64,
    /// A step with rotation below this counts as converged \[rad\].
    pub min_step_rot_rad: f64,
    /// Fewer correspondences than this is an error.
    pub min_correspondences: usize,
}

impl Default for IcpConfig {
    fn default() -> Self {
        Self {
            metric: IcpMetric::PointToLine,
            kernel: RobustKernel::Cauchy,
            kernel_scale_m: 0.05,
            solver: IcpSolver::LevenbergMarquardt,
            max_iterations: 100,
            max_iterations_per_threshold: 10,
            max_correspondence_dist_m: 0.3,
            min_correspondence_dist_m: 0.05,
            dist_shrink_factor: 0.8,
            min_step_trans_m: 1e-5,
            min_step_rot_rad: 1e-5,
            min_correspondences: 10,
        }
    }
}

impl IcpConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), LidarError> {
        let positive = |field, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(LidarError::invalid_config(
                    field,
                    value,
                    "must be finite and > 0",
                ))
            }
        };
        positive("kernel_scale_m", self.kernel_scale_m)?;
        positive("max_correspondence_dist_m", self.max_correspondence_dist_m)?;
        positive("min_correspondence_dist_m", self.min_correspondence_dist_m)?;
        positive("min_step_trans_m", self.min_step_trans_m)?;
        positive("min_step_rot_rad", self.min_step_rot_rad)?;
        if !(self.dist_shrink_factor > 0.0 && self.dist_shrink_factor <= 1.0) {
            return Err(LidarError::invalid_config(
                "dist_shrink_factor",
                self.dist_shrink_factor,
                "must be in (0, 1]",
            ));
        }
        if self.max_iterations_per_threshold == 0 {
            return Err(LidarError::invalid_config(
                "max_iterations_per_threshold",
                0.0,
                "must be >= 1",
            ));
        }
        if self.min_correspondences < 3 {
            return Err(LidarError::invalid_config(
                "min_correspondences",
                self.min_correspondences as f64,
                "must be >= 3",
            ));
        }
        Ok(())
    }
}

/// Outcome of one alignment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpResult {
    /// The estimated pose of the source in the target frame.
    pub target_from_source: Pose2,
    /// Fraction of source points whose nearest target point is within the final threshold.
    pub goodness: f64,
    /// Iterations run.
    pub iterations: u32,
    /// True when the pose stopped moving at the smallest threshold before an iteration limit.
    pub converged: bool,
    /// Correspondences used in the last iteration.
    pub correspondences: usize,
    /// Root mean square residual of the last iteration's correspondences \[m\].
    pub rms_residual_m: f64,
}

/// One source–target pair.
#[derive(Debug, Clone, Copy)]
struct Pair {
    source: Point2<f64>,
    target: Point2<f64>,
    normal: Option<Vector2<f64>>,
}

/// Aligns `source` points to `target`, starting from `initial` (`target_from_source`).
pub fn align<T: NearestNeighbours + ?Sized>(
    source: &[Point2<f64>],
    target: &T,
    initial: &Pose2,
    config: &IcpConfig,
) -> Result<IcpResult, LidarError> {
    config.validate()?;
    if source.len() < config.min_correspondences {
        return Err(LidarError::TooFewPoints {
            got: source.len(),
            min: config.min_correspondences,
        });
    }
    let mut pose = *initial;
    let mut max_dist = config
        .max_correspondence_dist_m
        .max(config.min_correspondence_dist_m);
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut at_threshold = 0;
    let mut converged = false;
    let mut pairs = Vec::with_capacity(source.len());
    let mut cache = Correspondences::new(source.len());
    while iterations < config.max_iterations {
        iterations += 1;
        at_threshold += 1;
        pair_up(
            source,
            target,
            &pose,
            max_dist,
            config.metric,
            &mut pairs,
            &mut cache,
        );
        if pairs.len() < config.min_correspondences {
            return Err(LidarError::TooFewCorrespondences {
                got: pairs.len(),
                min: config.min_correspondences,
            });
        }
        let kernel = Kernel {
            kind: config.kernel,
            scale_m: config.kernel_scale_m * max_dist / config.min_correspondence_dist_m,
        };
        let step = match config.solver {
            IcpSolver::GaussNewton => gauss_newton_step(&pairs, &pose, kernel)?,
            IcpSolver::LevenbergMarquardt => lm_step(&pairs, &pose, kernel, &mut lambda),
        };
        pose = exp_step(&step) * pose;
        let small =
            step.xy().norm() < config.min_step_trans_m && step.z.abs() < config.min_step_rot_rad;
        if small || at_threshold >= config.max_iterations_per_threshold {
            if max_dist <= config.min_correspondence_dist_m {
                converged = small;
                break;
            }
            max_dist = (max_dist * config.dist_shrink_factor).max(config.min_correspondence_dist_m);
            at_threshold = 0;
        }
    }
    let (sum_sq, n) = pairs.iter().fold((0.0, 0usize), |(s, n), p| {
        let r = residuals(p, &pose);
        (s + r.norm_squared(), n + 1)
    });
    Ok(IcpResult {
        target_from_source: pose,
        goodness: matched_fraction(source, target, &pose, max_dist, &mut cache),
        iterations,
        converged,
        correspondences: pairs.len(),
        rms_residual_m: (sum_sq / n.max(1) as f64).sqrt(),
    })
}

/// Fraction of `source` points that, moved by `target_from_source`, have a target point within
/// `max_dist_m`.
pub fn goodness<T: NearestNeighbours + ?Sized>(
    source: &[Point2<f64>],
    target: &T,
    target_from_source: &Pose2,
    max_dist_m: f64,
) -> f64 {
    fraction_matched(source, target_from_source, |_, q| {
        target.nearest_within(q, max_dist_m).is_some()
    })
}

/// [`goodness`] through the correspondence cache (the same value).
fn matched_fraction<T: NearestNeighbours + ?Sized>(
    source: &[Point2<f64>],
    target: &T,
    target_from_source: &Pose2,
    max_dist_m: f64,
    cache: &mut Correspondences,
) -> f64 {
    fraction_matched(source, target_from_source, |i, q| {
        cache.nearest(i, q, target, max_dist_m).is_some()
    })
}

/// Fraction of `source` points for which `has_match(index, point moved by target_from_source)`
/// holds (0 for no points): [`goodness`] with or without the correspondence cache.
fn fraction_matched(
    source: &[Point2<f64>],
    target_from_source: &Pose2,
    mut has_match: impl FnMut(usize, &Point2<f64>) -> bool,
) -> f64 {
    if source.is_empty() {
        return 0.0;
    }
    let matched = (0..)
        .zip(source)
        .filter(|(i, p)| has_match(*i, &(target_from_source * *p)))
        .count();
    matched as f64 / source.len() as f64
}

/// Pairs each source point with its nearest target point within `max_dist_m`.
fn pair_up<T: NearestNeighbours + ?Sized>(
    source: &[Point2<f64>],
    target: &T,
    pose: &Pose2,
    max_dist_m: f64,
    metric: IcpMetric,
    pairs: &mut Vec<Pair>,
    cache: &mut Correspondences,
) {
    pairs.clear();
    pairs.extend((0..).zip(source).filter_map(|(i, p)| {
        let nearest = cache.nearest(i, &(pose * p), target, max_dist_m)?;
        Some(Pair {
            source: *p,
            target: *target.point(nearest)?,
            normal: match metric {
                IcpMetric::PointToLine => target.normal(nearest),
                IcpMetric::PointToPoint => None,
            },
        })
    }));
}

/// Safety margin of the correspondence cache's reuse test against rounding in the distances
/// (far above it: coordinates of kilometres have rounding errors near 10⁻¹³ m) \[m\].
const REUSE_GUARD_M: f64 = 1e-9;

/// The last nearest-neighbour query of each source point, reused while the point has moved too
/// little for the answer to change. A query at `q` returned the nearest target point `j` (or
/// none) and a clearance `c`: every other target point is at least `c` from `q`
/// ([`NearestNeighbours::nearest_within_clear`]). At `q'`, `m = |q' − q|` away, the others are
/// at least `c − m` away; when that exceeds `|q' − t_j|`, `t_j` is still the strict nearest
/// (or, with no `j`, when it exceeds the radius, nothing is within it), so the answer for any
/// radius is known without a query: exactly the pairs a fresh search gives. As ICP converges,
/// steps shrink below a millimetre and most points keep their pair.
struct Correspondences {
    /// Per source point, its last query.
    last: Vec<Option<Query>>,
}

/// One nearest-neighbour query and its answer.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Query {
    /// Where the point was.
    at: Point2<f64>,
    /// The nearest target point within the radius.
    nearest: Option<usize>,
    /// Every other target point is at least this far from `at` \[m\].
    clear_m: f64,
}

impl Correspondences {
    fn new(points: usize) -> Self {
        Self {
            last: vec![None; points],
        }
    }

    /// The nearest target point within `max_dist_m` of `q`, source point `i` moved there.
    fn nearest<T: NearestNeighbours + ?Sized>(
        &mut self,
        i: usize,
        q: &Point2<f64>,
        target: &T,
        max_dist_m: f64,
    ) -> Option<usize> {
        let Some(slot) = self.last.get_mut(i) else {
            return target.nearest_within(q, max_dist_m).map(|n| n.index);
        };
        if let Some(Query {
            at,
            nearest,
            clear_m,
        }) = *slot
        {
            // Every other target point is farther than this from `q`.
            let others = clear_m - (q - at).norm() - REUSE_GUARD_M;
            match nearest.and_then(|j| Some((j, target.point(j)?))) {
                Some((j, p)) => {
                    let d2 = (p - q).norm_squared();
                    if d2 < others * others && others > 0.0 {
                        // Same test as the search: within the radius, squared.
                        return (d2 <= max_dist_m * max_dist_m).then_some(j);
                    }
                }
                None if nearest.is_none() && max_dist_m < others => return None,
                None => {}
            }
        }
        let (found, clear_m) = target.nearest_within_clear(q, max_dist_m);
        let nearest = found.map(|n| n.index);
        *slot = Some(Query {
            at: *q,
            nearest,
            clear_m,
        });
        nearest
    }
}

/// Residual of a pair at `pose`: `(n·(q − m), 0)` with a normal, `q − m` without.
fn residuals(pair: &Pair, pose: &Pose2) -> Vector2<f64> {
    let d = pose * pair.source - pair.target;
    match pair.normal {
        Some(n) => Vector2::new(n.dot(&d), 0.0),
        None => d,
    }
}

/// A robust kernel with its current scale.
#[derive(Debug, Clone, Copy)]
struct Kernel {
    kind: RobustKernel,
    scale_m: f64,
}

/// Robust cost of all pairs at `pose`.
fn cost(pairs: &[Pair], pose: &Pose2, kernel: Kernel) -> f64 {
    let mut sum = CostSum::new(kernel);
    for p in pairs {
        sum.add(residuals(p, pose).norm_squared());
    }
    sum.total()
}

/// Running sum of `ρ` over residuals. The Cauchy cost `k²/2 · Σ ln(1 + rᵢ²/k²)` is taken as
/// `k²/2 · ln Π(1 + rᵢ²/k²)`: one logarithm per run of factors instead of one per residual (the
/// logarithm was a tenth of ICP-SLAM's time). The product is folded into the sum before it
/// could overflow, so the total equals the sum of logarithms up to rounding.
struct CostSum {
    kernel: Kernel,
    sum: f64,
    product: f64,
}

/// The Cauchy product is folded into the sum once it passes this; a larger factor goes into the
/// sum alone, so the product never exceeds its square, far from overflow.
const FOLD_PRODUCT: f64 = 1e150;

impl CostSum {
    fn new(kernel: Kernel) -> Self {
        Self {
            kernel,
            sum: 0.0,
            product: 1.0,
        }
    }

    /// Adds the cost of a residual of squared size `r2`.
    fn add(&mut self, r2: f64) {
        let k = self.kernel.scale_m;
        match self.kernel.kind {
            RobustKernel::Cauchy => {
                let factor = 1.0 + r2 / (k * k);
                if factor > FOLD_PRODUCT {
                    self.sum += 0.5 * k * k * factor.ln();
                    return;
                }
                self.product *= factor;
                if self.product > FOLD_PRODUCT {
                    self.sum += 0.5 * k * k * self.product.ln();
                    self.product = 1.0;
                }
            }
            kind => self.sum += rho(kind, k, r2.sqrt()),
        }
    }

    fn total(&self) -> f64 {
        match self.kernel.kind {
            RobustKernel::Cauchy => {
                let k = self.kernel.scale_m;
                self.sum + 0.5 * k * k * self.product.ln()
            }
            _ => self.sum,
        }
    }
}

/// Normal equations `(H, g)` of the robust least-squares problem at `pose` (IRLS weights), and
/// the robust cost there (the same sum as [`cost`], taken in the same pass).
fn normal_equations(
    pairs: &[Pair],
    pose: &Pose2,
    kernel: Kernel,
) -> (Matrix3<f64>, Vector3<f64>, f64) {
    let mut h = Matrix3::zeros();
    let mut g = Vector3::zeros();
    let mut cost = CostSum::new(kernel);
    for pair in pairs {
        let q = pose * pair.source;
        let d = q - pair.target;
        // One Jacobian row per residual: one along the normal, else one per axis.
        let (r2, (j, r), second) = match pair.normal {
            Some(n) => {
                let r = n.dot(&d);
                let j = Vector3::new(n.x, n.y, n.y * q.x - n.x * q.y);
                (r * r, (j, r), None)
            }
            None => (
                d.norm_squared(),
                (Vector3::new(1.0, 0.0, -q.y), d.x),
                Some((Vector3::new(0.0, 1.0, q.x), d.y)),
            ),
        };
        cost.add(r2);
        let w = weight(kernel.kind, kernel.scale_m, r2);
        for (j, r) in std::iter::once((j, r)).chain(second) {
            let wj = w * j;
            h += wj * j.transpose();
            g += wj * r;
        }
    }
    (h, g, cost.total())
}

fn gauss_newton_step(
    pairs: &[Pair],
    pose: &Pose2,
    kernel: Kernel,
) -> Result<Vector3<f64>, LidarError> {
    let (h, g, _) = normal_equations(pairs, pose, kernel);
    let eig = h.symmetric_eigen().eigenvalues;
    let (lo, hi) = (eig.min(), eig.max());
    if hi.is_nan() || hi <= 0.0 || lo / hi < 1e-10 {
        return Err(LidarError::Degenerate);
    }
    h.cholesky()
        .map(|c| -c.solve(&g))
        .ok_or(LidarError::Degenerate)
}

/// One Levenberg–Marquardt step: tries growing damping until the robust cost drops; returns a
/// zero step when no damping helps (the pose is at a minimum for these pairs).
fn lm_step(pairs: &[Pair], pose: &Pose2, kernel: Kernel, lambda: &mut f64) -> Vector3<f64> {
    let (h, g, current) = normal_equations(pairs, pose, kernel);
    let diag = Matrix3::from_diagonal(&h.diagonal().map(|d| d.max(1e-9)));
    for _ in 0..10 {
        let damped = h + *lambda * diag;
        if let Some(chol) = damped.cholesky() {
            let step = -chol.solve(&g);
            if cost(pairs, &(exp_step(&step) * pose), kernel) <= current {
                *lambda = (*lambda * 0.1).max(1e-9);
                return step;
            }
        }
        *lambda *= 10.0;
    }
    Vector3::zeros()
}

/// The rigid motion of a small step `(δx, δy, δθ)`.
fn exp_step(step: &Vector3<f64>) -> Pose2 {
    Pose2::new(step.xy(), step.z)
}

/// Robust cost `ρ(r)` of a residual of size `r` >= 0 (Cauchy's is summed by [`CostSum`]).
fn rho(kernel: RobustKernel, k: f64, r: f64) -> f64 {
    match kernel {
        RobustKernel::None => 0.5 * r * r,
        RobustKernel::Huber if r <= k => 0.5 * r * r,
        RobustKernel::Huber => k * (r - 0.5 * k),
        RobustKernel::Cauchy => 0.5 * k * k * (1.0 + (r / k).powi(2)).ln(),
        RobustKernel::Tukey if r < k => k * k / 6.0 * (1.0 - (1.0 - (r / k).powi(2)).powi(3)),
        RobustKernel::Tukey => k * k / 6.0,
    }
}

/// IRLS weight `ρ'(r)/r` of a residual of squared size `r2` >= 0.
fn weight(kernel: RobustKernel, k: f64, r2: f64) -> f64 {
    let k2 = k * k;
    match kernel {
        RobustKernel::None => 1.0,
        RobustKernel::Huber if r2 <= k2 => 1.0,
        RobustKernel::Huber => k / r2.sqrt(),
        RobustKernel::Cauchy => 1.0 / (1.0 + r2 / k2),
        RobustKernel::Tukey if r2 < k2 => (1.0 - r2 / k2).powi(2),
        RobustKernel::Tukey => 0.0,
    }
}

#[cfg(test)]
mod tests;
