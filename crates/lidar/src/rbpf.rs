//! Rao-Blackwellised particle-filter SLAM in the style of GMapping (G. Grisetti, C. Stachniss,
//! W. Burgard, "Improved techniques for grid mapping with Rao-Blackwellized particle filters",
//! IEEE T-RO 23(1), 2007; K. Murphy, "Bayesian map learning in dynamic environments", NIPS 1999).
//!
//! Each particle is a robot trajectory with its own occupancy grid. The grids share unchanged
//! 64 × 64 tiles (copy-on-write, `slamkit_map`'s tiles), so resampling copies only a tile index
//! and memory grows with the tiles particles actually changed, not with particles × map size.
//!
//! The filter runs an update whenever the odometry has moved or turned far enough since the last
//! one (GMapping `linearUpdate`, `angularUpdate`): every particle draws its new pose from the
//! improved proposal ([`proposal`]: scan matching against its own map, then sampling around the
//! match), multiplies its weight by the proposal's normaliser, and inserts the scan into its map.
//! Particles are resampled only when the effective sample size falls below
//! `resample_threshold · N` ([`crate::particles`]). Odometry comes from the log's wheel odometry,
//! or from scan-to-scan ICP when the log has none ([`crate::motion`]).
//!
//! On re-entering mapped ground, particles whose map and trajectory agree with the scan gain
//! weight and the others die out. Since every particle's matcher drifts metres over a long loop
//! and resampling leaves them one lineage, half of them also search their own past for the scan
//! every second update and, when it matches, move there before the proposal
//! ([`relocalise`](mod@relocalise)); the weights then choose between the moved and the unmoved
//! particles. Those weights favour the unmoved particles (both are scored against a map whose
//! ground around the robot is the recent, drifted pass), so which seeds close a loop is left to
//! chance; with `relocalisation.confirmations` set, whole lineages move instead once
//! consecutive searches agree on the correction and the prediction does not match the old
//! pass as well (not the default: measured in docs/experiments/pf-seeds.md, it closes more
//! seeds' loops but still misses one ACES seed's first closure). The output is
//! the trajectory of the particle with the highest log weight accumulated over its whole
//! ancestry (GMapping's `weightSum`), read back through that ancestry; scans between two updates
//! are placed by odometry, with the correction at the next update spread over them linearly.
//! Random choices come from a seeded ChaCha8 generator, so a run is reproducible.

pub mod hit_means;
pub mod proposal;
pub mod relocalise;

use crate::cloud::scan_points;
use crate::error::check_fields;
use crate::icp_slam::loop_closure::SearchSource;
use crate::motion::{odometry_poses, MotionModelConfig, ScanOdometryConfig};
use crate::particles::{
    effective_sample_size, filter_checks, low_variance_resample, moved_enough, normalized_weights,
};
use crate::point_map::Keyframe;
use crate::LidarError;
use hit_means::HitMeans;
use nalgebra::Point2;
use proposal::{propose, GridScorer, PreparedScan, ProposalConfig};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use relocalise::{relocalise, RelocalisationConfig};
use serde::{Deserialize, Serialize};
use slamkit_core::pose::{pose2_to_pose3, wrap_angle};
use slamkit_core::{LaserScan, Pose2, StageTimings, Trajectory};
use slamkit_map::{shared_tile_stats, OccupancyGrid, OccupancyGridConfig};
use std::sync::Arc;
use std::time::Instant;

/// Particle-filter SLAM parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RbpfConfig {
    /// Number of particles.
    pub particles: usize,
    /// Seed of the random generator.
    pub seed: u64,
    /// Each particle's occupancy grid.
    pub grid: OccupancyGridConfig,
    /// Scan matching and the improved proposal.
    pub proposal: ProposalConfig,
    /// Odometry noise.
    pub motion: MotionModelConfig,
    /// Use the log's wheel odometry when every scan has it; scan-to-scan ICP otherwise.
    pub use_odometry: bool,
    /// Scan-to-scan ICP odometry for logs without wheel odometry.
    pub scan_odometry: ScanOdometryConfig,
    /// Beams shorter than this are not matched \[m\].
    pub min_range_m: f64,
    /// Beams at or beyond this are not matched \[m\].
    pub max_range_m: f64,
    /// Every n-th beam is matched (>= 1).
    pub beam_stride: usize,
    /// Run an update after the odometry moved this far since the last \[m\].
    pub update_linear_m: f64,
    /// Run an update after the odometry turned this much since the last \[rad\].
    pub update_angular_rad: f64,
    /// Resample when the effective sample size drops below this fraction of the particles.
    pub resample_threshold: f64,
    /// Accumulated log weights are divided by this when normalised for resampling, since the
    /// beams of successive scans are far from independent (GMapping divides by the particle
    /// count times `obsSigmaGain`).
    pub weight_temperature: f64,
    /// Scans with fewer usable beams are skipped.
    pub min_scan_points: usize,
    /// Matching against a particle's own past on re-entering mapped ground
    /// ([`relocalise`](mod@relocalise)).
    pub relocalisation: RelocalisationConfig,
}

impl Default for RbpfConfig {
    fn default() -> Self {
        Self {
            particles: 30,
            seed: 1,
            grid: OccupancyGridConfig {
                max_usable_range_m: 50.0,
                ..OccupancyGridConfig::default()
            },
            proposal: ProposalConfig::default(),
            motion: MotionModelConfig::default(),
            use_odometry: true,
            scan_odometry: ScanOdometryConfig::default(),
            min_range_m: 0.1,
            max_range_m: 50.0,
            beam_stride: 2,
            update_linear_m: 0.3,
            update_angular_rad: 0.2,
            resample_threshold: 0.5,
            weight_temperature: 1.0,
            min_scan_points: 20,
            relocalisation: RelocalisationConfig::default(),
        }
    }
}

impl RbpfConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), LidarError> {
        self.grid.validate().map_err(|_| {
            LidarError::invalid_config("grid", f64::NAN, "invalid occupancy grid configuration")
        })?;
        if !self.proposal.is_valid() {
            return Err(LidarError::invalid_config(
                "proposal",
                f64::NAN,
                "a proposal value is out of range",
            ));
        }
        if !self.motion.is_valid() {
            return Err(LidarError::invalid_config(
                "motion",
                f64::NAN,
                "a motion noise value is out of range",
            ));
        }
        self.relocalisation.validate()?;
        self.scan_odometry.icp.validate()?;
        if self.particles == 0 || self.particles > 100_000 {
            return Err(LidarError::invalid_config(
                "particles",
                self.particles as f64,
                "must be in 1..=100000",
            ));
        }
        let checks = [
            ("min_range_m", self.min_range_m, self.min_range_m >= 0.0),
            (
                "max_range_m",
                self.max_range_m,
                self.max_range_m > self.min_range_m,
            ),
            (
                "beam_stride",
                self.beam_stride as f64,
                self.beam_stride >= 1,
            ),
            (
                "weight_temperature",
                self.weight_temperature,
                self.weight_temperature.is_finite() && self.weight_temperature >= 1.0,
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

/// A pose of a particle's trajectory at one update, linked to the one before.
struct Node {
    scan: usize,
    world_from_base: Pose2,
    /// The update's scan points (base frame), shared by every particle's node of the update;
    /// `None` when relocalisation, their only reader, is off.
    cloud: Option<Arc<Keyframe>>,
    parent: Option<Arc<Node>>,
}

impl Drop for Node {
    /// Unlinks the chain iteratively: a recursive drop of a long trajectory would overflow the
    /// stack.
    fn drop(&mut self) {
        let mut next = self.parent.take();
        while let Some(node) = next {
            match Arc::try_unwrap(node) {
                Ok(mut owned) => next = owned.parent.take(),
                Err(_) => break,
            }
        }
    }
}

/// One hypothesis: a trajectory, its map and its weight.
#[derive(Clone)]
struct Particle {
    world_from_base: Pose2,
    grid: OccupancyGrid,
    /// Mean beam end point of each of `grid`'s cells, what the scan matcher scores against
    /// (`None` unless `proposal.mean_hit_points`).
    means: Option<HitMeans>,
    log_weight: f64,
    /// Sum of the log weight factors over the particle's whole ancestry, kept through
    /// resampling (GMapping's `weightSum`): picks the output trajectory.
    log_likelihood_sum: f64,
    node: Arc<Node>,
    /// The lineage's last relocalisation match, not yet confirmed (`relocalisation.confirmations`).
    closure: Option<PendingClosure>,
}

/// A lineage's relocalisation match waiting for agreement.
#[derive(Debug, Clone, Copy)]
struct PendingClosure {
    /// The world-frame correction the match asked for: matched = correction · predicted.
    correction: Pose2,
    /// Matches in agreement so far.
    count: usize,
    /// Filter update of the last of them.
    update: usize,
}

/// Memory used by the particles' maps.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct MapMemory {
    /// Bytes of all particles' grids, each shared tile counted once.
    pub shared_bytes: usize,
    /// Bytes the grids would take without sharing (sum over particles).
    pub unshared_bytes: usize,
    /// Bytes of one particle's grid (the best one).
    pub single_map_bytes: usize,
    /// Bytes of all particles' mean hit points, each shared tile counted once.
    pub hit_means_bytes: usize,
}

/// Counters over a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct RbpfStats {
    /// Scans given to the filter.
    pub scans_read: usize,
    /// Scans that ran a filter update.
    pub updates: usize,
    /// Scans skipped for too few usable beams (NaN, negative, no-return or empty).
    pub scans_skipped: usize,
    /// Particle proposals whose scan match failed (motion model sampled instead).
    pub matches_failed: usize,
    /// Resampling steps.
    pub resamples: usize,
    /// Particle poses moved by a relocalisation match.
    pub relocalisations: usize,
    /// Relocalisation searches that matched (with `relocalisation.confirmations`, each
    /// lineage's match counts once).
    pub relocalisation_matches: usize,
    /// Corrections taken by a whole lineage after `relocalisation.confirmations` matches in
    /// agreement.
    pub closures: usize,
    /// True when the log's wheel odometry was used, false for scan-to-scan ICP odometry.
    pub wheel_odometry: bool,
    /// Scans scan-to-scan ICP odometry could not align.
    pub odometry_failures: usize,
    /// Memory of the particle maps at the end of the run.
    pub memory_end: MapMemory,
    /// Largest shared memory of the particle maps seen during the run \[bytes\].
    pub peak_shared_bytes: usize,
}

/// What a scan did to the filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RbpfStep {
    /// The first usable scan: every particle's map starts from it.
    Initialised,
    /// A filter update ran.
    Updated,
    /// The robot has not moved enough since the last update.
    Waiting,
    /// Too few usable beams.
    Skipped,
}

/// The particle filter. Feed it scans in file order with [`Rbpf::process`].
pub struct Rbpf {
    config: RbpfConfig,
    particles: Vec<Particle>,
    rng: ChaCha8Rng,
    last_update_odometry: Option<Pose2>,
    stats: RbpfStats,
    timings: StageTimings,
}

impl Rbpf {
    /// A filter with no particles yet; the first usable scan initialises them.
    pub fn new(config: RbpfConfig) -> Result<Self, LidarError> {
        config.validate()?;
        Ok(Self {
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            config,
            particles: Vec::new(),
            last_update_odometry: None,
            stats: RbpfStats::default(),
            timings: StageTimings::default(),
        })
    }

    /// Processes scan number `index` whose odometry pose is `odometry`.
    pub fn process(&mut self, index: usize, scan: &LaserScan, odometry: &Pose2) -> RbpfStep {
        self.stats.scans_read += 1;
        let increment = match self.last_update_odometry {
            Some(last) => last.inverse() * odometry,
            None => Pose2::identity(),
        };
        let moved = moved_enough(
            &increment,
            self.config.update_linear_m,
            self.config.update_angular_rad,
        );
        if self.last_update_odometry.is_some() && !moved {
            return RbpfStep::Waiting;
        }
        let c = &self.config;
        let back_m = c.grid.resolution_m;
        let prepared = PreparedScan::new(scan, c.min_range_m, c.max_range_m, c.beam_stride, back_m);
        if prepared.len() < c.min_scan_points {
            self.stats.scans_skipped += 1;
            return RbpfStep::Skipped;
        }
        let step = if self.particles.is_empty() {
            match self.initialise(index, scan) {
                Some(()) => RbpfStep::Initialised,
                None => {
                    self.stats.scans_skipped += 1;
                    return RbpfStep::Skipped;
                }
            }
        } else {
            self.update(index, scan, &prepared, &increment);
            RbpfStep::Updated
        };
        self.last_update_odometry = Some(*odometry);
        step
    }

    /// Starts every particle at the origin with one map built from `scan` (shared by all).
    fn initialise(&mut self, index: usize, scan: &LaserScan) -> Option<()> {
        let mut grid = OccupancyGrid::new(self.config.grid.clone()).ok()?;
        grid.insert_scan(scan, &scan.base_from_laser).ok()?;
        let c = &self.config.grid;
        let means = self.config.proposal.mean_hit_points.then(|| {
            let mut means = HitMeans::new(grid.origin_m(), c.resolution_m, c.max_usable_range_m);
            means.insert_scan(scan, &scan.base_from_laser);
            means
        });
        let node = Arc::new(Node {
            scan: index,
            world_from_base: Pose2::identity(),
            cloud: self.keep(self.search_points(scan).as_deref()),
            parent: None,
        });
        let particle = Particle {
            world_from_base: Pose2::identity(),
            grid,
            means,
            log_weight: 0.0,
            log_likelihood_sum: 0.0,
            node,
            closure: None,
        };
        self.particles = vec![particle; self.config.particles];
        Some(())
    }

    /// One filter update: propose, weight, insert, maybe resample.
    fn update(
        &mut self,
        index: usize,
        scan: &LaserScan,
        prepared: &PreparedScan,
        increment: &Pose2,
    ) {
        self.stats.updates += 1;
        let started = Instant::now();
        let points = self.search_points(scan);
        if let Some(points) = &points {
            self.relocalise(points, increment);
        }
        let relocalised = Instant::now();
        let cloud = self.keep(points.as_deref());
        let config = &self.config;
        for particle in &mut self.particles {
            let scorer = GridScorer::new(&particle.grid, particle.means.as_ref(), &config.proposal);
            let p = propose(
                &scorer,
                prepared,
                &particle.world_from_base,
                increment,
                &config.motion,
                &config.proposal,
                &mut self.rng,
            );
            self.stats.matches_failed += usize::from(!p.matched);
            particle.world_from_base = p.world_from_base;
            particle.log_weight += p.log_weight;
            particle.log_likelihood_sum += p.log_weight;
        }
        let proposed = Instant::now();
        for particle in &mut self.particles {
            let world_from_laser = particle.world_from_base * scan.base_from_laser;
            // A finite pose inside the addressable area always inserts; a failure leaves the
            // particle's map as it was.
            let inserted = particle.grid.insert_scan(scan, &world_from_laser).is_ok();
            if let Some(means) = particle.means.as_mut().filter(|_| inserted) {
                means.insert_scan(scan, &world_from_laser);
            }
            particle.node = Arc::new(Node {
                scan: index,
                world_from_base: particle.world_from_base,
                cloud: cloud.clone(),
                parent: Some(particle.node.clone()),
            });
        }
        let inserted = Instant::now();
        self.resample_if_needed();
        self.timings.record("relocalise", ms(started, relocalised));
        self.timings.record("proposal", ms(relocalised, proposed));
        self.timings.record("map_update", ms(proposed, inserted));
        self.timings.record_since("resample", inserted);
        if self.stats.updates % 50 == 0 {
            let shared = shared_tile_stats(self.particles.iter().map(|p| &p.grid)).bytes;
            self.stats.peak_shared_bytes = self.stats.peak_shared_bytes.max(shared);
        }
    }

    /// The scan's points (base frame) within the relocalisation search's range, computed once
    /// per update for both the search and the kept cloud; `None` when relocalisation is off.
    fn search_points(&self, scan: &LaserScan) -> Option<Vec<Point2<f64>>> {
        let c = &self.config;
        c.relocalisation
            .enabled
            .then(|| scan_points(scan, c.min_range_m, c.relocalisation.search.max_range_m))
    }

    /// The search points as kept with the update's nodes (thinned, with normals).
    fn keep(&self, points: Option<&[Point2<f64>]>) -> Option<Arc<Keyframe>> {
        points.map(|p| Arc::new(self.config.relocalisation.keep(p)))
    }

    /// Moves particles that find the scan (its search `points`) in their own past to the
    /// matched pose (less the odometry `increment`, which the proposal adds back): every few
    /// updates a random fraction of the particles, each on its own match, or, with
    /// `relocalisation.confirmations`, whole lineages on confirmed matches
    /// ([`Rbpf::relocalise_lineages`]).
    fn relocalise(&mut self, points: &[Point2<f64>], increment: &Pose2) {
        let c = &self.config.relocalisation;
        if c.confirmations > 0 {
            self.relocalise_lineages(points, increment);
            return;
        }
        if self.stats.updates % c.every_updates.max(1) != 0 {
            return;
        }
        let source = SearchSource::new(points, &c.search);
        for particle in &mut self.particles {
            if !self.rng.gen_bool(c.fraction) {
                continue;
            }
            let predicted = particle.world_from_base * increment;
            let Some(matched) = relocalise(&particle.node, &predicted, &source, c, None) else {
                continue;
            };
            self.stats.relocalisation_matches += 1;
            particle.world_from_base = matched * increment.inverse();
            self.stats.relocalisations += 1;
        }
    }

    /// One search per lineage (the particles sharing their ancestor `min_separation_updates`
    /// back have the same searchable past; the one of highest weight searches), every few
    /// updates, and at the next update again for a lineage whose last search matched. A match
    /// asks for a world-frame correction; once `confirmations` matches in a row ask for the
    /// same correction (within `agree_m`, `agree_rad` at the prediction), every particle of
    /// the lineage is moved by it, which keeps their spread. The decision is the searches'
    /// agreement, not the weights (see [`RelocalisationConfig::confirmations`]), so a closure
    /// found is taken whatever the seed; agreement over several updates, about a metre of
    /// travel, rejects single false matches of a similar-looking place. A corridor repeats its
    /// false match, so a match also counts only when the prediction, refined by the same ICP,
    /// is not itself an accepted match elsewhere (`ambiguous` in [`relocalise`](mod@relocalise):
    /// then the old pass explains the scan where the lineage already is).
    fn relocalise_lineages(&mut self, points: &[Point2<f64>], increment: &Pose2) {
        let c = &self.config.relocalisation;
        let now = self.stats.updates;
        let due = now % c.every_updates.max(1) == 0;
        for p in &mut self.particles {
            let stale = p
                .closure
                .is_some_and(|q| now - q.update > c.pending_updates);
            if stale {
                p.closure = None;
            }
        }
        let lineage = lineage_keys(&self.particles, c.min_separation_updates.max(1));
        // The searching particle of each lineage: its highest weight.
        let mut searchers: Vec<usize> = Vec::new();
        for (i, key) in lineage.iter().enumerate() {
            match searchers.iter_mut().find(|r| lineage[**r] == *key) {
                Some(r) => {
                    if self.particles[i].log_weight > self.particles[*r].log_weight {
                        *r = i;
                    }
                }
                None => searchers.push(i),
            }
        }
        searchers.retain(|&r| due || self.particles[r].closure.is_some());
        if searchers.is_empty() {
            return;
        }
        let source = SearchSource::new(points, &c.search);
        for r in searchers {
            let searcher = &self.particles[r];
            let predicted = searcher.world_from_base * increment;
            let unambiguous = Some((c.agree_m, c.agree_rad));
            let Some(matched) = relocalise(&searcher.node, &predicted, &source, c, unambiguous)
            else {
                continue;
            };
            self.stats.relocalisation_matches += 1;
            let key = lineage[r];
            if agree(&predicted, &matched, c.min_jump_m, c.min_jump_rad) {
                // Within the climb's reach: the lineage is where the old map says.
                for (p, k) in self.particles.iter_mut().zip(&lineage) {
                    if *k == key {
                        p.closure = None;
                    }
                }
                continue;
            }
            let correction = matched * predicted.inverse();
            // The match agrees with the lineage's last one when that one's correction, applied
            // to today's prediction, lands where this match did.
            let agrees = |q: &PendingClosure| {
                agree(
                    &(q.correction * predicted),
                    &matched,
                    c.agree_m,
                    c.agree_rad,
                )
            };
            let count = searcher
                .closure
                .filter(|q| agrees(q))
                .map_or(1, |q| q.count + 1);
            let confirmed = count >= c.confirmations;
            for (p, _) in self
                .particles
                .iter_mut()
                .zip(&lineage)
                .filter(|(_, k)| **k == key)
            {
                if confirmed {
                    p.world_from_base = correction * p.world_from_base;
                    p.closure = None;
                    self.stats.relocalisations += 1;
                } else {
                    p.closure = Some(PendingClosure {
                        correction,
                        count,
                        update: now,
                    });
                }
            }
            self.stats.closures += usize::from(confirmed);
        }
    }

    fn resample_if_needed(&mut self) {
        let temperature = self.config.weight_temperature;
        let log_weights: Vec<f64> = self
            .particles
            .iter()
            .map(|p| p.log_weight / temperature)
            .collect();
        let weights = normalized_weights(&log_weights);
        let n = self.particles.len();
        if effective_sample_size(&weights) >= self.config.resample_threshold * n as f64 {
            // Keep weights bounded: shift so the best is 0.
            let max = log_weights
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max);
            for p in &mut self.particles {
                p.log_weight -= max * temperature;
            }
            return;
        }
        self.stats.resamples += 1;
        let picks = low_variance_resample(&weights, n, &mut self.rng);
        let mut next: Vec<Particle> = picks
            .iter()
            .filter_map(|&i| self.particles.get(i).cloned())
            .collect();
        for p in &mut next {
            p.log_weight = 0.0;
        }
        self.particles = next;
    }

    /// The particle whose ancestry explains the scans best (highest accumulated log weight, as
    /// GMapping's `getBestParticleIndex`): the current weights alone are reset by every
    /// resampling and would leave the choice to chance.
    fn best(&self) -> Option<&Particle> {
        self.particles
            .iter()
            .max_by(|a, b| a.log_likelihood_sum.total_cmp(&b.log_likelihood_sum))
    }

    /// The best particle's poses at its updates, as `(scan index, world_from_base)` in time
    /// order.
    pub fn best_updates(&self) -> Vec<(usize, Pose2)> {
        let mut out = Vec::new();
        let mut node = self.best().map(|p| &p.node);
        while let Some(n) = node {
            out.push((n.scan, n.world_from_base));
            node = n.parent.as_ref();
        }
        out.reverse();
        out
    }

    /// The best particle's pose at its last update, as `(scan index, world_from_base)`: the
    /// filter's estimate now, without walking its ancestry.
    pub fn best_pose(&self) -> Option<(usize, Pose2)> {
        self.best().map(|p| (p.node.scan, p.world_from_base))
    }

    /// The best particle's map.
    pub fn best_map(&self) -> Option<&OccupancyGrid> {
        self.best().map(|p| &p.grid)
    }

    /// Memory of the particles' maps now.
    pub fn map_memory(&self) -> MapMemory {
        MapMemory {
            shared_bytes: shared_tile_stats(self.particles.iter().map(|p| &p.grid)).bytes,
            unshared_bytes: self
                .particles
                .iter()
                .map(|p| p.grid.tile_stats().bytes)
                .sum(),
            single_map_bytes: self.best().map_or(0, |p| p.grid.tile_stats().bytes),
            hit_means_bytes: HitMeans::shared_bytes(
                self.particles.iter().filter_map(|p| p.means.as_ref()),
            ),
        }
    }

    /// The counters at the end of a run: those so far with where the odometry came from
    /// (`wheel_odometry`: the scans' own, else scan-to-scan ICP with `odometry_failures`) and
    /// the maps' memory now.
    pub fn final_stats(&self, wheel_odometry: bool, odometry_failures: usize) -> RbpfStats {
        let memory_end = self.map_memory();
        RbpfStats {
            wheel_odometry,
            odometry_failures,
            peak_shared_bytes: self.stats.peak_shared_bytes.max(memory_end.shared_bytes),
            memory_end,
            ..self.stats
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> &RbpfStats {
        &self.stats
    }

    /// Per-stage timings so far.
    pub fn timings(&self) -> &StageTimings {
        &self.timings
    }
}

/// Each particle's lineage: the address of its ancestor `depth` updates back (of its oldest
/// node when the trajectory is shorter). Particles of one lineage share every older pose.
fn lineage_keys(particles: &[Particle], depth: usize) -> Vec<*const Node> {
    particles
        .iter()
        .map(|p| {
            let mut node = &p.node;
            for _ in 0..depth {
                match &node.parent {
                    Some(parent) => node = parent,
                    None => break,
                }
            }
            Arc::as_ptr(node)
        })
        .collect()
}

/// True when poses `a` and `b` are within `linear_m` and `angular_rad` of each other.
fn agree(a: &Pose2, b: &Pose2, linear_m: f64, angular_rad: f64) -> bool {
    (a.translation.vector - b.translation.vector).norm() <= linear_m
        && wrap_angle(a.rotation.angle() - b.rotation.angle()).abs() <= angular_rad
}

fn ms(a: Instant, b: Instant) -> f64 {
    (b - a).as_secs_f64() * 1e3
}

/// Everything a full run produces.
#[derive(Debug, Clone)]
pub struct RbpfOutput {
    /// One pose per scan, in file order, with the scans' timestamps.
    pub trajectory: Trajectory,
    /// The same poses as planar `world_from_base`.
    pub poses: Vec<Pose2>,
    /// The best particle's map; `None` when no scan was usable.
    pub map: Option<OccupancyGrid>,
    /// Counters.
    pub stats: RbpfStats,
    /// Per-stage timings.
    pub timings: StageTimings,
}

/// Runs particle-filter SLAM over `scans` in order, calling `on_scan` after each.
pub fn run_rbpf(
    scans: &[LaserScan],
    config: &RbpfConfig,
    mut on_scan: impl FnMut(usize),
) -> Result<RbpfOutput, LidarError> {
    let mut filter = Rbpf::new(config.clone())?;
    let started = Instant::now();
    let (odometry, odometry_failures, wheel) =
        odometry_poses(scans, config.use_odometry, &config.scan_odometry);
    filter.timings.record_since("odometry", started);
    for (i, (scan, odom)) in scans.iter().zip(&odometry).enumerate() {
        filter.process(i, scan, odom);
        on_scan(i);
    }
    let stats = filter.final_stats(wheel, odometry_failures);
    let poses = interpolate_poses(&filter.best_updates(), &odometry);
    let mut trajectory = Trajectory::new();
    for (scan, pose) in scans.iter().zip(&poses) {
        trajectory.push(scan.timestamp, pose2_to_pose3(pose));
    }
    Ok(RbpfOutput {
        trajectory,
        poses,
        map: filter.best_map().cloned(),
        stats,
        timings: filter.timings,
    })
}

/// One pose per scan from the poses at the updates (`(scan index, pose)`, increasing index):
/// scans between two updates follow odometry from the earlier one, with the discrepancy found
/// at the later one spread linearly over them; scans outside follow odometry from the nearest
/// update. Without updates the odometry itself is returned.
pub fn interpolate_poses(updates: &[(usize, Pose2)], odometry: &[Pose2]) -> Vec<Pose2> {
    let Some(&(first_index, first_pose)) = updates.first() else {
        return odometry.to_vec();
    };
    let from = |anchor: usize, anchor_pose: &Pose2, i: usize| -> Pose2 {
        match (odometry.get(anchor), odometry.get(i)) {
            (Some(a), Some(b)) => anchor_pose * (a.inverse() * b),
            _ => *anchor_pose,
        }
    };
    let mut poses = Vec::with_capacity(odometry.len());
    let mut segment = 0;
    for i in 0..odometry.len() {
        while updates.get(segment + 1).is_some_and(|u| u.0 <= i) {
            segment += 1;
        }
        let (ia, pa) = updates
            .get(segment)
            .copied()
            .unwrap_or((first_index, first_pose));
        if i < ia {
            poses.push(from(ia, &pa, i));
            continue;
        }
        let odo = from(ia, &pa, i);
        let Some(&(ib, pb)) = updates.get(segment + 1) else {
            poses.push(odo);
            continue;
        };
        let predicted_b = from(ia, &pa, ib);
        let f = (i - ia) as f64 / (ib - ia) as f64;
        let dt = pb.translation.vector - predicted_b.translation.vector;
        let da = wrap_angle(pb.rotation.angle() - predicted_b.rotation.angle());
        poses.push(Pose2::new(
            odo.translation.vector + dt * f,
            odo.rotation.angle() + da * f,
        ));
    }
    poses
}

#[cfg(test)]
pub(crate) mod tests;
