//! Monte Carlo localisation in a saved occupancy grid (F. Dellaert, D. Fox, W. Burgard,
//! S. Thrun, "Monte Carlo localization for mobile robots", ICRA 1999; Thrun et al.,
//! *Probabilistic Robotics*, 2005, ch. 8).
//!
//! * Sensor model: the likelihood field of the map ([`slamkit_map::LikelihoodField`], table 6.3)
//!   over `beams` evenly spread beams, divided by `likelihood_gain` since neighbouring beams are
//!   not independent.
//! * Motion model: the odometry increment with Gaussian noise ([`crate::motion`]); scan-to-scan
//!   ICP odometry when the log has none.
//! * Global initialisation: particles uniform over the map's free cells and all headings. Their
//!   number makes it 90 % likely that one starts within `capture_radius_m` and
//!   `±heading_window_deg/2` of the true pose: `n = ln(0.1) / ln(1 − P)` with
//!   `P = (A/S)·(θ/360°)`, `A = π·r²`, `S` the free area (capped at `max_particles`). Once the
//!   particles gather within `converged_radius_m`, the filter keeps only `tracking_particles`
//!   (a coarse form of adaptive sample size, D. Fox, "KLD-sampling", NIPS 2001).
//! * Recovery (augmented MCL, table 8.3): short- and long-term averages `w_fast`, `w_slow` of the
//!   per-beam likelihood; at each resampling a fraction `max(0, 1 − w_fast/w_slow)` of the
//!   particles is replaced by uniform draws over the free space. When that fraction exceeds
//!   `relocalise_fraction` the robot is taken to be lost (kidnapped) and the filter restarts from
//!   a global initialisation.
//! * Resampling: low variance, only when the effective sample size drops below
//!   `resample_threshold · N`.
//!
//! Updates run after the odometry moved `update_linear_m` or turned `update_angular_rad`; the
//! pose of every scan is the estimate at the last update moved on by odometry. The estimate is
//! the weighted mean of the particles within `cluster_radius_m` of the heaviest one.

use crate::error::check_fields;
use crate::motion::{odometry_poses, MotionModelConfig, ScanOdometryConfig};
use crate::particles::{
    effective_sample_size, filter_checks, low_variance_resample, moved_enough, normalized_weights,
};
use crate::LidarError;
use nalgebra::{Point2, Vector2};
use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use slamkit_core::pose::pose2_to_pose3;
use slamkit_core::{LaserScan, Pose2, StageTimings, Trajectory};
use slamkit_map::{LikelihoodField, LikelihoodFieldConfig, Occupancy, OccupancyGrid};
use std::f64::consts::PI;
use std::sync::Arc;
use std::time::Instant;

/// Monte Carlo localisation parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MclConfig {
    /// Seed of the random generator.
    pub seed: u64,
    /// Likelihood-field sensor model.
    pub likelihood: LikelihoodFieldConfig,
    /// Beam log-likelihoods are divided by this (beams are not independent).
    pub likelihood_gain: f64,
    /// Beams scored per scan, evenly spread over the usable ones.
    pub beams: usize,
    /// Beams shorter than this are ignored \[m\].
    pub min_range_m: f64,
    /// Beams at or beyond this are ignored \[m\].
    pub max_range_m: f64,
    /// Odometry noise.
    pub motion: MotionModelConfig,
    /// Use the log's wheel odometry when every scan has it; scan-to-scan ICP otherwise.
    pub use_odometry: bool,
    /// Scan-to-scan ICP odometry for logs without wheel odometry.
    pub scan_odometry: ScanOdometryConfig,
    /// Radius within which a particle counts as near the true pose, for the global particle
    /// count \[m\].
    pub capture_radius_m: f64,
    /// Full width of the heading window a particle must fall in, for the global count \[deg\].
    pub heading_window_deg: f64,
    /// Upper limit on the global particle count.
    pub max_particles: usize,
    /// Particles kept once the filter has converged.
    pub tracking_particles: usize,
    /// The filter has converged when the particles' RMS distance to their mean is below this
    /// \[m\].
    pub converged_radius_m: f64,
    /// Particles within this distance of the heaviest one form the estimate \[m\].
    pub cluster_radius_m: f64,
    /// Run an update after the odometry moved this far \[m\].
    pub update_linear_m: f64,
    /// Run an update after the odometry turned this much \[rad\].
    pub update_angular_rad: f64,
    /// Resample when the effective sample size drops below this fraction of the particles.
    pub resample_threshold: f64,
    /// Decay rate of the long-term likelihood average (augmented MCL `α_slow`).
    pub alpha_slow: f64,
    /// Decay rate of the short-term likelihood average (augmented MCL `α_fast`).
    pub alpha_fast: f64,
    /// An injection fraction above this restarts the global initialisation.
    pub relocalise_fraction: f64,
    /// Scans with fewer usable beams are skipped.
    pub min_scan_points: usize,
}

impl Default for MclConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            likelihood: LikelihoodFieldConfig {
                sigma_hit_m: 0.2,
                ..LikelihoodFieldConfig::default()
            },
            likelihood_gain: 3.0,
            beams: 60,
            min_range_m: 0.1,
            max_range_m: 30.0,
            motion: MotionModelConfig {
                min_trans_sigma_m: 0.02,
                min_rot_sigma_rad: 1f64.to_radians(),
                ..MotionModelConfig::default()
            },
            use_odometry: true,
            scan_odometry: ScanOdometryConfig::default(),
            capture_radius_m: 0.25,
            heading_window_deg: 60.0,
            max_particles: 300_000,
            tracking_particles: 500,
            converged_radius_m: 0.3,
            cluster_radius_m: 1.0,
            update_linear_m: 0.1,
            update_angular_rad: 0.1,
            resample_threshold: 0.5,
            alpha_slow: 0.001,
            alpha_fast: 0.1,
            relocalise_fraction: 0.5,
            min_scan_points: 20,
        }
    }
}

impl MclConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), LidarError> {
        if !self.motion.is_valid() {
            return Err(LidarError::invalid_config(
                "motion",
                f64::NAN,
                "out of range",
            ));
        }
        self.scan_odometry.icp.validate()?;
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let fraction = |v: f64| (0.0..=1.0).contains(&v);
        let checks = [
            (
                "likelihood_gain",
                self.likelihood_gain,
                positive(self.likelihood_gain),
            ),
            ("beams", self.beams as f64, self.beams >= 1),
            ("min_range_m", self.min_range_m, self.min_range_m >= 0.0),
            (
                "max_range_m",
                self.max_range_m,
                self.max_range_m > self.min_range_m,
            ),
            (
                "capture_radius_m",
                self.capture_radius_m,
                positive(self.capture_radius_m),
            ),
            (
                "heading_window_deg",
                self.heading_window_deg,
                positive(self.heading_window_deg) && self.heading_window_deg <= 360.0,
            ),
            (
                "max_particles",
                self.max_particles as f64,
                (1..=10_000_000).contains(&self.max_particles),
            ),
            (
                "tracking_particles",
                self.tracking_particles as f64,
                self.tracking_particles >= 1,
            ),
            (
                "converged_radius_m",
                self.converged_radius_m,
                positive(self.converged_radius_m),
            ),
            (
                "cluster_radius_m",
                self.cluster_radius_m,
                positive(self.cluster_radius_m),
            ),
            ("alpha_slow", self.alpha_slow, fraction(self.alpha_slow)),
            ("alpha_fast", self.alpha_fast, fraction(self.alpha_fast)),
            (
                "relocalise_fraction",
                self.relocalise_fraction,
                fraction(self.relocalise_fraction),
            ),
        ];
        let shared = filter_checks(
            self.update_linear_m,
            self.update_angular_rad,
            self.resample_threshold,
        );
        check_fields(checks.into_iter().chain(shared), "out of range")
    }
}

/// Particles needed so that, with 90 % probability, one starts within `radius_m` and a
/// heading window of `window_deg` of the true pose in `free_area_m2` of free space:
/// `n = ln(0.1) / ln(1 − P)`, `P = (π r² / S)·(θ / 360°)`, with `π r² / S` capped at 1. At
/// least 1; exactly 1 when there is no free area (`S` zero, negative or NaN) to search.
pub fn global_particle_count(free_area_m2: f64, radius_m: f64, window_deg: f64) -> usize {
    if free_area_m2.is_nan() || free_area_m2 <= 0.0 {
        return 1;
    }
    let p = (PI * radius_m * radius_m / free_area_m2).min(1.0) * (window_deg / 360.0).min(1.0);
    if p.is_nan() || p <= 0.0 || p >= 1.0 {
        return 1;
    }
    (0.1f64.ln() / (1.0 - p).ln()).ceil().max(1.0) as usize
}

/// The filter's belief after an update.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MclEstimate {
    /// Estimated pose of the robot base in the map frame.
    #[serde(skip)]
    pub world_from_base: Pose2,
    /// RMS distance of the particles to their weighted mean \[m\].
    pub spread_m: f64,
    /// True when the spread is below `converged_radius_m`.
    pub converged: bool,
    /// Particles in the filter.
    pub particles: usize,
}

/// Counters over a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct MclStats {
    /// Scans given to the filter.
    pub scans_read: usize,
    /// Scans that ran a filter update.
    pub updates: usize,
    /// Scans skipped for too few usable beams.
    pub scans_skipped: usize,
    /// Free area of the map \[m²\].
    pub free_area_m2: f64,
    /// Particles of a global initialisation.
    pub global_particles: usize,
    /// Resampling steps.
    pub resamples: usize,
    /// Particles replaced by uniform draws (augmented MCL).
    pub injected: usize,
    /// Restarts from a global initialisation after the robot was found lost.
    pub relocalisations: usize,
    /// First scan at which the filter had converged, if any.
    pub first_converged_scan: Option<usize>,
    /// True when the log's wheel odometry was used.
    pub wheel_odometry: bool,
}

/// A map prepared for Monte Carlo localisation: the likelihood field of its obstacles and the
/// centres of its free cells, where a global initialisation draws its particles. Built once and
/// shared ([`Arc`]) by the filters that localise in it.
pub struct MclMap {
    field: LikelihoodField,
    free_cells: Vec<Point2<f64>>,
    resolution_m: f64,
}

impl MclMap {
    /// Prepares `map` for the sensor model `likelihood`. Fails when the model is refused or
    /// the map has no free cell.
    pub fn new(
        map: &OccupancyGrid,
        likelihood: &LikelihoodFieldConfig,
    ) -> Result<Self, LidarError> {
        let field =
            LikelihoodField::new(map, likelihood).map_err(|e| LidarError::InvalidConfig {
                field: "likelihood",
                value: e.to_string(),
                reason: "the likelihood field refused it",
            })?;
        let free_cells = free_cell_centres(map);
        if free_cells.is_empty() {
            return Err(LidarError::TooFewPoints { got: 0, min: 1 });
        }
        Ok(Self {
            field,
            free_cells,
            resolution_m: map.resolution_m(),
        })
    }

    /// An error unless the map was prepared for the sensor model `likelihood`.
    fn check_sensor_model(&self, likelihood: &LikelihoodFieldConfig) -> Result<(), LidarError> {
        if self.field.config() == likelihood {
            return Ok(());
        }
        Err(LidarError::InvalidConfig {
            field: "likelihood",
            value: format!("{likelihood:?}"),
            reason: "the map was prepared with another sensor model",
        })
    }

    /// Area of the free cells \[m²\].
    pub fn free_area_m2(&self) -> f64 {
        self.free_cells.len() as f64 * self.resolution_m * self.resolution_m
    }
}

/// Monte Carlo localisation over one map.
pub struct Mcl {
    config: MclConfig,
    map: Arc<MclMap>,
    poses: Vec<Pose2>,
    log_weights: Vec<f64>,
    rng: ChaCha8Rng,
    w_slow: Option<f64>,
    w_fast: Option<f64>,
    estimate: Option<MclEstimate>,
    stats: MclStats,
}

impl Mcl {
    /// A filter over `map`, globally initialised.
    pub fn new(map: &OccupancyGrid, config: MclConfig) -> Result<Self, LidarError> {
        config.validate()?;
        let map = MclMap::new(map, &config.likelihood)?;
        Self::on_map(Arc::new(map), config)
    }

    /// A filter over a prepared map, globally initialised. Fails when `config` is out of
    /// range or `map` was prepared with another sensor model than `config.likelihood`.
    pub fn on_map(map: Arc<MclMap>, config: MclConfig) -> Result<Self, LidarError> {
        config.validate()?;
        map.check_sensor_model(&config.likelihood)?;
        let mut mcl = Self {
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            config,
            map,
            poses: Vec::new(),
            log_weights: Vec::new(),
            w_slow: None,
            w_fast: None,
            estimate: None,
            stats: MclStats::default(),
        };
        mcl.count_global_particles();
        mcl.initialise_globally();
        Ok(mcl)
    }

    /// Sets the free area and the global particle count from the current map.
    fn count_global_particles(&mut self) {
        let free_area_m2 = self.map.free_area_m2();
        self.stats.free_area_m2 = free_area_m2;
        self.stats.global_particles = global_particle_count(
            free_area_m2,
            self.config.capture_radius_m,
            self.config.heading_window_deg,
        )
        .min(self.config.max_particles);
    }

    /// Carries the particles, their weights and the likelihood averages over to `map` (in the
    /// same frame): the next updates weigh them against it, and a restart spreads them over
    /// its free space. The multi-layer localiser moves a layer hypothesis's particles so when
    /// the drone changes height layer. Fails, leaving the filter unchanged, when `map` was
    /// prepared with another sensor model.
    pub fn move_to_map(&mut self, map: Arc<MclMap>) -> Result<(), LidarError> {
        map.check_sensor_model(&self.config.likelihood)?;
        self.map = map;
        self.count_global_particles();
        Ok(())
    }

    /// Spreads the global number of particles uniformly over the free space.
    fn initialise_globally(&mut self) {
        let n = self.stats.global_particles;
        self.poses = (0..n).map(|_| self.random_pose()).collect();
        self.log_weights = vec![0.0; n];
        self.w_slow = None;
        self.w_fast = None;
    }

    /// A pose uniform over the free cells and all headings.
    fn random_pose(&mut self) -> Pose2 {
        let i = self.rng.gen_range(0..self.map.free_cells.len());
        let half = self.map.resolution_m / 2.0;
        let offset = Vector2::new(
            self.rng.gen_range(-half..half),
            self.rng.gen_range(-half..half),
        );
        let c = self
            .map
            .free_cells
            .get(i)
            .copied()
            .unwrap_or_else(Point2::origin);
        Pose2::new(c.coords + offset, self.rng.gen_range(-PI..PI))
    }

    /// Moves every particle by a noisy copy of the odometry increment `prev_from_cur`.
    pub fn predict(&mut self, increment: &Pose2) {
        for pose in &mut self.poses {
            *pose *= self.config.motion.sample(increment, &mut self.rng);
        }
    }

    /// Weights the particles by `scan`, updates the estimate and resamples when needed.
    /// Returns `None` when the scan has too few usable beams.
    pub fn correct(&mut self, scan: &LaserScan) -> Option<MclEstimate> {
        let points = self.scan_points(scan);
        if points.len() < self.config.min_scan_points.min(self.config.beams) {
            self.stats.scans_skipped += 1;
            return None;
        }
        self.stats.updates += 1;
        let gain = self.config.likelihood_gain;
        let mut mean_beam_likelihood = 0.0;
        for (pose, w) in self.poses.iter().zip(&mut self.log_weights) {
            let l = self.map.field.score_points(&points, pose);
            mean_beam_likelihood += (l / points.len() as f64).exp();
            *w += l / gain;
        }
        mean_beam_likelihood /= self.poses.len() as f64;
        self.track_likelihood(mean_beam_likelihood);
        let weights = normalized_weights(&self.log_weights);
        let estimate = self.estimate_from(&weights);
        self.estimate = Some(estimate);
        if effective_sample_size(&weights)
            < self.config.resample_threshold * self.poses.len() as f64
        {
            self.resample(&weights, estimate.converged);
        }
        Some(estimate)
    }

    /// Updates `w_slow` and `w_fast` (table 8.3, lines 10–11).
    fn track_likelihood(&mut self, w_avg: f64) {
        let c = &self.config;
        self.w_slow = Some(
            self.w_slow
                .map_or(w_avg, |w| w + c.alpha_slow * (w_avg - w)),
        );
        self.w_fast = Some(
            self.w_fast
                .map_or(w_avg, |w| w + c.alpha_fast * (w_avg - w)),
        );
    }

    /// Resamples to the tracking size once converged (else keeps the count), replacing a
    /// fraction by uniform draws, or restarting globally when lost.
    fn resample(&mut self, weights: &[f64], converged: bool) {
        self.stats.resamples += 1;
        let inject = match (self.w_fast, self.w_slow) {
            (Some(fast), Some(slow)) if slow > 0.0 => (1.0 - fast / slow).max(0.0),
            _ => 0.0,
        };
        if inject > self.config.relocalise_fraction {
            self.stats.relocalisations += 1;
            self.initialise_globally();
            return;
        }
        let count = if converged {
            self.config.tracking_particles.min(self.poses.len())
        } else {
            self.poses.len()
        };
        let injected = (inject * count as f64).round() as usize;
        let picks = low_variance_resample(weights, count - injected, &mut self.rng);
        let mut poses: Vec<Pose2> = picks
            .iter()
            .filter_map(|&i| self.poses.get(i).copied())
            .collect();
        for _ in 0..injected {
            let pose = self.random_pose();
            poses.push(pose);
        }
        self.stats.injected += injected;
        self.log_weights = vec![0.0; poses.len()];
        self.poses = poses;
    }

    /// Weighted mean of the particles near the heaviest, and the spread of all particles.
    fn estimate_from(&self, weights: &[f64]) -> MclEstimate {
        let best = weights
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .and_then(|(i, _)| self.poses.get(i).copied())
            .unwrap_or_else(Pose2::identity);
        let centre = best.translation.vector;
        let (mut sum_w, mut xy, mut cs) = (0.0, Vector2::zeros(), Vector2::zeros());
        for (pose, &w) in self.poses.iter().zip(weights) {
            if (pose.translation.vector - centre).norm() <= self.config.cluster_radius_m {
                let a = pose.rotation.angle();
                sum_w += w;
                xy += pose.translation.vector * w;
                cs += Vector2::new(a.cos(), a.sin()) * w;
            }
        }
        let mean = if sum_w > 0.0 { xy / sum_w } else { centre };
        let spread_m = weighted_spread_m(&self.poses, weights);
        MclEstimate {
            world_from_base: Pose2::new(mean, cs.y.atan2(cs.x)),
            spread_m,
            converged: spread_m < self.config.converged_radius_m,
            particles: self.poses.len(),
        }
    }

    /// Up to `beams` usable end points of `scan`, evenly spread, in the base frame.
    fn scan_points(&self, scan: &LaserScan) -> Vec<Point2<f64>> {
        let usable =
            crate::cloud::scan_points(scan, self.config.min_range_m, self.config.max_range_m);
        let stride = usable.len().div_ceil(self.config.beams).max(1);
        usable.into_iter().step_by(stride).collect()
    }

    /// RMS distance of the particles as they are now to their weighted mean \[m\]: after a
    /// resampling (uniform weights) the spread of the resampled cloud, unlike
    /// [`MclEstimate::spread_m`], which is taken before it.
    pub fn spread_m(&self) -> f64 {
        weighted_spread_m(&self.poses, &normalized_weights(&self.log_weights))
    }

    /// The latest estimate, once an update has run.
    pub fn estimate(&self) -> Option<MclEstimate> {
        self.estimate
    }

    /// The particles' poses.
    pub fn particles(&self) -> &[Pose2] {
        &self.poses
    }

    /// Counters so far.
    pub fn stats(&self) -> &MclStats {
        &self.stats
    }
}

/// RMS distance of `poses` to their mean, both weighted by the normalised `weights` \[m\].
fn weighted_spread_m(poses: &[Pose2], weights: &[f64]) -> f64 {
    let mean = poses
        .iter()
        .zip(weights)
        .fold(Vector2::zeros(), |acc, (p, w)| {
            acc + p.translation.vector * *w
        });
    poses
        .iter()
        .zip(weights)
        .map(|(p, w)| w * (p.translation.vector - mean).norm_squared())
        .sum::<f64>()
        .sqrt()
}

/// Centres of the grid's free cells.
fn free_cell_centres(map: &OccupancyGrid) -> Vec<Point2<f64>> {
    let Some(bounds) = map.known_bounds() else {
        return Vec::new();
    };
    let mut cells = Vec::new();
    for y in bounds.min.y..=bounds.max.y {
        for x in bounds.min.x..=bounds.max.x {
            let cell = slamkit_map::CellIndex { x, y };
            if map.occupancy(cell) == Some(Occupancy::Free) {
                cells.push(map.cell_center_m(cell));
            }
        }
    }
    cells
}

/// Everything a localisation run produces.
#[derive(Debug, Clone)]
pub struct MclOutput {
    /// One pose per scan, in file order, with the scans' timestamps.
    pub trajectory: Trajectory,
    /// The same poses as planar `world_from_base`.
    pub poses: Vec<Pose2>,
    /// The filter's belief at each scan (the last update's, with the pose moved by odometry).
    pub estimates: Vec<Option<MclEstimate>>,
    /// Counters.
    pub stats: MclStats,
    /// Per-stage timings: `odometry` once, `update` (predict and correct) per update.
    pub timings: StageTimings,
}

/// Localises every scan of `scans` in `map`, starting from a global initialisation, calling
/// `on_scan` after each.
pub fn run_mcl(
    scans: &[LaserScan],
    map: &OccupancyGrid,
    config: &MclConfig,
    mut on_scan: impl FnMut(usize),
) -> Result<MclOutput, LidarError> {
    let mut mcl = Mcl::new(map, config.clone())?;
    let mut timings = StageTimings::default();
    let started = Instant::now();
    let (odometry, _, wheel) = odometry_poses(scans, config.use_odometry, &config.scan_odometry);
    timings.record_since("odometry", started);
    mcl.stats.wheel_odometry = wheel;
    let mut last: Option<(Pose2, Pose2)> = None; // (odometry, estimate) at the last update
    let mut poses = Vec::with_capacity(scans.len());
    let mut estimates = Vec::with_capacity(scans.len());
    for (i, (scan, odom)) in scans.iter().zip(&odometry).enumerate() {
        mcl.stats.scans_read += 1;
        let increment = last.map_or(Pose2::identity(), |(o, _)| o.inverse() * odom);
        let moved = moved_enough(
            &increment,
            config.update_linear_m,
            config.update_angular_rad,
        );
        if last.is_none() || moved {
            let started = Instant::now();
            mcl.predict(&increment);
            if let Some(e) = mcl.correct(scan) {
                last = Some((*odom, e.world_from_base));
                if e.converged && mcl.stats.first_converged_scan.is_none() {
                    mcl.stats.first_converged_scan = Some(i);
                }
            } else if let Some((_, pose)) = last {
                // The particles moved: keep the reference odometry in step with them.
                last = Some((*odom, pose * increment));
            }
            timings.record_since("update", started);
        }
        let pose = last.map_or(Pose2::identity(), |(o, p)| p * (o.inverse() * odom));
        poses.push(pose);
        estimates.push(mcl.estimate().map(|e| MclEstimate {
            world_from_base: pose,
            ..e
        }));
        on_scan(i);
    }
    let mut trajectory = Trajectory::new();
    for (scan, pose) in scans.iter().zip(&poses) {
        trajectory.push(scan.timestamp, pose2_to_pose3(pose));
    }
    Ok(MclOutput {
        trajectory,
        poses,
        estimates,
        stats: mcl.stats,
        timings,
    })
}

#[cfg(test)]
mod tests;
