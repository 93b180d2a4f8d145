//! GMapping's improved proposal: each particle's scan is matched against that particle's own
//! map, and the new pose is drawn from a Gaussian fitted around the match (G. Grisetti,
//! C. Stachniss, W. Burgard, "Improved techniques for grid mapping with Rao-Blackwellized
//! particle filters", IEEE T-RO 23(1), 2007, section IV, eqs. 9–11 and 19).
//!
//! The observation likelihood is a local likelihood field read straight off the particle's grid,
//! as GMapping's `ScanMatcher::score`: for each beam end point the nearest occupied cell within
//! `kernel_cells` is found, requiring the cell one step back along the beam (at the same offset)
//! not to be occupied, so a wall is matched from the side the laser saw it. The distance `d`
//! is measured to the mean of the end points that fell in that cell ([`super::hit_means`],
//! GMapping's `cell.mean()`), not to the cell centre, so the match is not tied to the cell
//! lattice. It scores `ln(z_hit·N(d; 0, σ²) + z_rand/z_max)` (Thrun et al., *Probabilistic Robotics*,
//! table 6.3); a beam finding no obstacle scores as `d = (kernel_cells + 1)·resolution`.
//! No field is precomputed: particle maps change every step, and only the cells under the beam
//! ends are ever read.
//!
//! The match is a hill climb from a draw of the motion model (GMapping's `drawFromMotion`, then
//! `optimize`; the draw keeps the particles spread where the scan does not fix the pose): moves of one
//! step in ±x, ±y, ±θ are taken while they raise the score, then the steps are halved. Around the
//! best pose `x*`, 3 × 3 × 3 poses `xⱼ` are scored by `p(z | m, xⱼ)·p(xⱼ | x, u)`; their weighted
//! mean and covariance give the Gaussian the new pose is drawn from, and their sum `η` is the
//! particle's weight factor (eq. 19). A failed match (too few beams near an obstacle) falls back
//! to sampling the motion model, weighted by the likelihood at the sample.

use super::hit_means::{locate, HitMeans, MeanReader};
use crate::motion::{pose_difference, MotionModelConfig};
use nalgebra::{Matrix3, Point2, Vector2, Vector3};
use rand::Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use slamkit_core::pose::wrap_angle;
use slamkit_core::{LaserScan, Pose2};
use slamkit_map::likelihood_field::SquaredDistanceTable;
use slamkit_map::occupancy_grid::log_odds_from_probability;
use slamkit_map::{CellIndex, LikelihoodFieldConfig, OccupancyGrid};

/// Scan matching and proposal parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ProposalConfig {
    /// Search radius for the nearest occupied cell around a beam end, in cells (GMapping
    /// `kernelSize`).
    pub kernel_cells: u32,
    /// Standard deviation of a beam end around its obstacle \[m\].
    pub sigma_m: f64,
    /// Weight of the Gaussian hit component \[0..1\].
    pub z_hit: f64,
    /// Weight of the uniform random-reading component \[0..1\].
    pub z_rand: f64,
    /// Maximum range over which random readings are uniform \[m\].
    pub z_max_m: f64,
    /// Cells more likely occupied than this are obstacles \[0..1\].
    pub occupied_probability: f64,
    /// Initial translation step of the hill climb \[m\] (GMapping `lstep`).
    pub linear_step_m: f64,
    /// Initial rotation step of the hill climb \[rad\] (GMapping `astep`).
    pub angular_step_rad: f64,
    /// Times the steps are halved (GMapping `iterations`).
    pub refinements: u32,
    /// Spacing of the 3 × 3 × 3 poses sampled around the match, translation \[m\].
    pub sample_linear_m: f64,
    /// Spacing of the poses sampled around the match, rotation \[rad\].
    pub sample_angular_rad: f64,
    /// Log-likelihoods are divided by this before they weight particles, since neighbouring
    /// beams are not independent (GMapping `obsSigmaGain`).
    pub likelihood_gain: f64,
    /// A match is accepted when at least this fraction of beams ends near an obstacle \[0..1\].
    pub min_match_fraction: f64,
    /// Measure beam ends against the mean of the end points recorded in each occupied cell
    /// (GMapping's `cell.mean()`, [`super::hit_means`]) instead of the cell centre.
    pub mean_hit_points: bool,
    /// Hill-climb on the tempered scan log-likelihood plus the motion model's log-density
    /// around the odometry's prediction (the target of the improved proposal, Grisetti et al.
    /// eq. 9) instead of on the scan likelihood alone (GMapping's `optimize`, which assumes the
    /// scan far more peaked than the odometry). For odometry more precise than the scan match
    /// (a drone's scan-matching odometry with a gyro heading, matched against one map of many
    /// heights) a climb on the scan alone walks off into the map's biases.
    pub climb_with_motion_prior: bool,
}

impl Default for ProposalConfig {
    fn default() -> Self {
        Self {
            kernel_cells: 2,
            sigma_m: 0.05,
            z_hit: 0.95,
            z_rand: 0.05,
            z_max_m: 30.0,
            occupied_probability: 0.6,
            linear_step_m: 0.05,
            angular_step_rad: 0.05,
            refinements: 5,
            sample_linear_m: 0.02,
            sample_angular_rad: 0.01,
            likelihood_gain: 3.0,
            min_match_fraction: 0.3,
            mean_hit_points: false,
            climb_with_motion_prior: false,
        }
    }
}

impl ProposalConfig {
    /// True when every value is in range.
    pub fn is_valid(&self) -> bool {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        positive(self.sigma_m)
            && positive(self.z_rand)
            && positive(self.z_max_m)
            && self.z_hit.is_finite()
            && self.z_hit >= 0.0
            && self.occupied_probability > 0.0
            && self.occupied_probability < 1.0
            && positive(self.linear_step_m)
            && positive(self.angular_step_rad)
            && positive(self.sample_linear_m)
            && positive(self.sample_angular_rad)
            && positive(self.likelihood_gain)
            && (0.0..=1.0).contains(&self.min_match_fraction)
            && self.kernel_cells <= 8
    }
}

/// A scan's beam ends, and the points one cell back along each beam, in the base frame.
#[derive(Debug, Clone, Default)]
pub struct PreparedScan {
    hits: Vec<Point2<f64>>,
    backs: Vec<Point2<f64>>,
}

impl PreparedScan {
    /// Every `stride`-th beam of `scan` that hit something within `[min_range_m, max_range_m)`;
    /// the back points lie `back_m` closer to the laser.
    pub fn new(
        scan: &LaserScan,
        min_range_m: f64,
        max_range_m: f64,
        stride: usize,
        back_m: f64,
    ) -> Self {
        let mut prepared = Self::default();
        for (i, &r) in scan.ranges_m.iter().enumerate().step_by(stride.max(1)) {
            if !(scan.is_hit(i) && r >= min_range_m && r < max_range_m) {
                continue;
            }
            let (s, c) = scan.beam_angle_rad(i).sin_cos();
            let back = (r - back_m).max(0.0);
            prepared
                .hits
                .push(scan.base_from_laser * Point2::new(r * c, r * s));
            prepared
                .backs
                .push(scan.base_from_laser * Point2::new(back * c, back * s));
        }
        prepared
    }

    /// Number of beams kept.
    pub fn len(&self) -> usize {
        self.hits.len()
    }

    /// True when no beam was kept.
    pub fn is_empty(&self) -> bool {
        self.hits.is_empty()
    }
}

/// Result of scoring a scan at one pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Score {
    /// Sum of the beams' log-likelihoods.
    pub log_likelihood: f64,
    /// Beams that found an obstacle within the kernel.
    pub matched: usize,
}

/// Widest kernel row: `kernel_cells` is at most 8.
const MAX_ROW: usize = 17;

/// Scores scans against one grid; see the module documentation.
pub struct GridScorer<'a> {
    grid: &'a OccupancyGrid,
    means: Option<&'a HitMeans>,
    occupied_log_odds: f32,
    kernel: i32,
    table: SquaredDistanceTable,
    miss: f64,
    origin_m: Vector2<f64>,
    inv_resolution: f64,
    resolution_m2: f64,
}

impl<'a> GridScorer<'a> {
    /// A scorer over `grid`, whose cells' mean hit points are `means` (a cell without a
    /// recorded mean is scored at its centre); `None` scores every cell at its centre without
    /// looking anything up.
    pub fn new(
        grid: &'a OccupancyGrid,
        means: Option<&'a HitMeans>,
        config: &ProposalConfig,
    ) -> Self {
        let kernel = config.kernel_cells.min(8) as i32;
        let model = LikelihoodFieldConfig {
            sigma_hit_m: config.sigma_m,
            z_hit: config.z_hit,
            z_rand: config.z_rand,
            z_max_m: config.z_max_m,
            max_distance_m: f64::from(kernel + 1) * grid.resolution_m(),
            obstacle_min_probability: config.occupied_probability,
        };
        let resolution_m = grid.resolution_m();
        Self {
            grid,
            means,
            occupied_log_odds: log_odds_from_probability(config.occupied_probability),
            kernel,
            miss: model.log_likelihood(model.max_distance_m),
            table: SquaredDistanceTable::new(&model),
            origin_m: grid.origin_m().coords,
            inv_resolution: 1.0 / resolution_m,
            resolution_m2: resolution_m * resolution_m,
        }
    }

    fn occupied(&self, x: i32, y: i32) -> bool {
        self.grid
            .log_odds(CellIndex { x, y })
            .is_some_and(|l| l > self.occupied_log_odds)
    }

    /// Cell holding world point `p`, and `p`'s offset from that cell's centre in cells.
    #[inline]
    fn cell(&self, p: &Point2<f64>) -> Option<(i32, i32, f64, f64)> {
        locate(&self.origin_m, self.inv_resolution, p)
    }

    /// Log-odds of the `len` cells from `(x, y)` along +x, read as one tile row when they lie in
    /// one tile (nearly always), cell by cell otherwise.
    #[inline]
    fn row(&self, x: i32, y: i32, out: &mut [f32]) {
        match self.grid.log_odds_row(CellIndex { x, y }, out.len()) {
            Some(cells) => out.copy_from_slice(cells),
            None => {
                for (o, cx) in out.iter_mut().zip(x..) {
                    *o = self.grid.log_odds(CellIndex { x: cx, y }).unwrap_or(0.0);
                }
            }
        }
    }

    /// Squared distance \[m²\] from `hit` to the nearest mean hit point of an occupied cell
    /// within the kernel whose partner cell around `back` is not occupied.
    fn nearest_squared(
        &self,
        hit: Point2<f64>,
        back: Point2<f64>,
        means: &mut Option<MeanReader<'_>>,
    ) -> Option<f64> {
        let (hx, hy, fx, fy) = self.cell(&hit)?;
        let (bx, by, _, _) = self.cell(&back)?;
        let k = self.kernel;
        let mut cells = [0.0f32; MAX_ROW];
        let cells = cells.get_mut(..(2 * k + 1) as usize)?;
        let mut best = f64::INFINITY;
        for dy in -k..=k {
            self.row(hx - k, hy + dy, cells);
            for (dx, &l) in (-k..).zip(cells.iter()) {
                if l <= self.occupied_log_odds || self.occupied(bx + dx, by + dy) {
                    continue;
                }
                let (mx, my) = means
                    .as_mut()
                    .map_or((0.0, 0.0), |m| m.offset(hx + dx, hy + dy));
                let (ex, ey) = (f64::from(dx) + mx - fx, f64::from(dy) + my - fy);
                best = best.min(ex * ex + ey * ey);
            }
        }
        best.is_finite().then_some(best * self.resolution_m2)
    }

    /// Log-likelihood of `scan` with the robot base at `world_from_base`.
    pub fn score(&self, scan: &PreparedScan, world_from_base: &Pose2) -> Score {
        let mut total = Score {
            log_likelihood: 0.0,
            matched: 0,
        };
        let mut means = self.means.map(HitMeans::reader);
        for (hit, back) in scan.hits.iter().zip(&scan.backs) {
            match self.nearest_squared(world_from_base * hit, world_from_base * back, &mut means) {
                Some(d2) => {
                    total.matched += 1;
                    total.log_likelihood += self.table.log_likelihood(d2);
                }
                None => total.log_likelihood += self.miss,
            }
        }
        total
    }

    /// Hill climb from `start` (GMapping's `optimize`) on the scan's log-likelihood, or, with a
    /// `prior`, on the log-likelihood divided by `config.likelihood_gain` plus the prior's
    /// log-density; returns the best pose and its score.
    pub fn climb(
        &self,
        scan: &PreparedScan,
        start: &Pose2,
        config: &ProposalConfig,
        prior: Option<&MotionPrior>,
    ) -> (Pose2, Score) {
        let objective = |pose: &Pose2, s: &Score| match prior {
            Some(p) => s.log_likelihood / config.likelihood_gain + p.log_density(pose),
            None => s.log_likelihood,
        };
        let mut best = *start;
        let mut best_score = self.score(scan, &best);
        let mut best_value = objective(&best, &best_score);
        let (mut step_m, mut step_rad) = (config.linear_step_m, config.angular_step_rad);
        for _ in 0..=config.refinements {
            // Each pass either improves the score or ends; the cap guards against plateaus.
            for _ in 0..50 {
                let mut improved = false;
                for (dx, dy, da) in [
                    (step_m, 0.0, 0.0),
                    (-step_m, 0.0, 0.0),
                    (0.0, step_m, 0.0),
                    (0.0, -step_m, 0.0),
                    (0.0, 0.0, step_rad),
                    (0.0, 0.0, -step_rad),
                ] {
                    let candidate = shifted(&best, dx, dy, da);
                    let s = self.score(scan, &candidate);
                    let value = objective(&candidate, &s);
                    if value > best_value {
                        (best, best_score, best_value, improved) = (candidate, s, value, true);
                    }
                }
                if !improved {
                    break;
                }
            }
            step_m /= 2.0;
            step_rad /= 2.0;
        }
        (best, best_score)
    }
}

/// `pose` moved by `(dx, dy)` in the world frame and turned by `da`.
fn shifted(pose: &Pose2, dx: f64, dy: f64, da: f64) -> Pose2 {
    let t = pose.translation.vector;
    Pose2::new(Vector2::new(t.x + dx, t.y + dy), pose.rotation.angle() + da)
}

/// The odometry's prediction of a particle's pose and the motion model's information
/// (inverse covariance) about it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionPrior {
    /// The particle's previous pose moved by the odometry increment.
    pub predicted: Pose2,
    /// Inverse covariance of the motion noise, in the frame of `predicted`.
    pub information: Matrix3<f64>,
}

impl MotionPrior {
    /// Log of the motion model's density at `pose`, up to a constant: `-½ eᵀ I e` for `e` the
    /// difference of `pose` from the prediction.
    pub fn log_density(&self, pose: &Pose2) -> f64 {
        let e = pose_difference(&self.predicted, pose);
        -0.5 * e.dot(&(self.information * e))
    }
}

/// A particle's new pose and the log of its weight factor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proposal {
    /// The sampled pose of the robot base.
    pub world_from_base: Pose2,
    /// Log of the importance weight factor `η` (tempered by `likelihood_gain`).
    pub log_weight: f64,
    /// True when the scan matched the map; false when the motion model was sampled instead.
    pub matched: bool,
}

/// Draws a particle's new pose with the improved proposal; see the module documentation.
/// `previous` is the particle's pose at the last update and `increment` the odometry since.
pub fn propose(
    scorer: &GridScorer<'_>,
    scan: &PreparedScan,
    previous: &Pose2,
    increment: &Pose2,
    motion: &MotionModelConfig,
    config: &ProposalConfig,
    rng: &mut impl Rng,
) -> Proposal {
    let prior = MotionPrior {
        predicted: previous * increment,
        information: motion.information(increment),
    };
    // The climb starts from a draw of the motion model, as GMapping's code does (`drawFromMotion`
    // before `optimize`): where the scan constrains the pose only weakly (a corridor) particles
    // keep the motion model's spread instead of all landing on one match.
    let start = previous * motion.sample(increment, rng);
    let climb_prior = config.climb_with_motion_prior.then_some(&prior);
    let (matched_pose, score) = scorer.climb(scan, &start, config, climb_prior);
    let needed = (config.min_match_fraction * scan.len() as f64).ceil() as usize;
    let gain = config.likelihood_gain;
    if score.matched < needed.max(1) {
        let pose = start;
        return Proposal {
            world_from_base: pose,
            log_weight: scorer.score(scan, &pose).log_likelihood / gain,
            matched: false,
        };
    }
    let (sl, sa) = (config.sample_linear_m, config.sample_angular_rad);
    let mut samples: Vec<(Vector3<f64>, f64)> = Vec::with_capacity(27);
    for i in -1..=1 {
        for j in -1..=1 {
            for k in -1..=1 {
                let (dx, dy, da) = (f64::from(i) * sl, f64::from(j) * sl, f64::from(k) * sa);
                let pose = shifted(&matched_pose, dx, dy, da);
                let log_motion = prior.log_density(&pose);
                let log_obs = scorer.score(scan, &pose).log_likelihood / gain;
                samples.push((Vector3::new(dx, dy, da), log_obs + log_motion));
            }
        }
    }
    let max = samples
        .iter()
        .map(|s| s.1)
        .fold(f64::NEG_INFINITY, f64::max);
    let weights: Vec<f64> = samples.iter().map(|s| (s.1 - max).exp()).collect();
    let sum: f64 = weights.iter().sum();
    let mean = samples
        .iter()
        .zip(&weights)
        .fold(Vector3::zeros(), |acc, (s, w)| acc + s.0 * *w)
        / sum;
    let floor = Vector3::new(0.1 * sl, 0.1 * sl, 0.1 * sa);
    let covariance = samples
        .iter()
        .zip(&weights)
        .fold(Matrix3::zeros(), |acc, (s, w)| {
            let d = s.0 - mean;
            acc + d * d.transpose() * *w
        })
        / sum
        + Matrix3::from_diagonal(&floor.component_mul(&floor));
    let offset = draw_gaussian(&mean, &covariance, rng);
    Proposal {
        world_from_base: shifted(&matched_pose, offset.x, offset.y, wrap_angle(offset.z)),
        log_weight: max + sum.ln(),
        matched: true,
    }
}

/// A draw from `N(mean, covariance)`; the mean when the covariance is not positive definite.
fn draw_gaussian(
    mean: &Vector3<f64>,
    covariance: &Matrix3<f64>,
    rng: &mut impl Rng,
) -> Vector3<f64> {
    let mut normal = || rng.sample::<f64, _>(StandardNormal);
    let z = Vector3::new(normal(), normal(), normal());
    match covariance.cholesky() {
        Some(c) => mean + c.l() * z,
        None => *mean,
    }
}
