//! Particle-filter SLAM beside the layered mapper: GMapping-style RBPF
//! ([`slamkit_lidar::rbpf`]) on the same scans in a single 2D map, its motion the layered
//! matcher's pose increments (as MRPT's ICP-based RBPF takes scan-matching odometry) and its
//! height, roll and pitch the layered tracker's. The scans' own odometry is not used: a
//! drone's rotate–translate–rotate odometry is off by more than 0.19 rad on 5 % of the `large`
//! flight's scans (`large`, seeds 1–4: PF mean error 0.20–2.2 m with the drone's odometry,
//! 0.08–0.84 m with scan-to-scan ICP, 0.04–0.08 m with the layered increments).

use crate::SlamError;
use nalgebra::{Translation3, UnitQuaternion};
use slamkit_core::{LaserScan, Pose2, Pose3, StageTimings};
use slamkit_lidar::layers::LayeredEstimate;
use slamkit_lidar::rbpf::{interpolate_poses, Rbpf, RbpfConfig, RbpfStats};
use slamkit_map::OccupancyGrid;

/// Share of GMapping's translation noise (`trans_per_*`, `min_trans_sigma_m`) the particle
/// filter's motion model has. Its motion is the layered matcher's pose increments: their
/// translation drifts where the scans do not pin it (up to 0.05 m per metre flown, `large`
/// seed 2), their heading follows the gyro (see [`PF_ROTATION_NOISE_SCALE`]).
pub const PF_TRANSLATION_NOISE_SCALE: f64 = 0.5;

/// Share of GMapping's rotation noise (`rot_per_*`, `min_rot_sigma_rad`) of the particle
/// filter's motion model: the increments' heading comes from the gyro, which drifts less than
/// 0.1 rad over a flight.
pub const PF_ROTATION_NOISE_SCALE: f64 = 0.1;

/// The drone's particle-filter settings: the defaults with [`PF_TRANSLATION_NOISE_SCALE`] and
/// [`PF_ROTATION_NOISE_SCALE`] of the motion noise, and the scan match climbing on the scan
/// likelihood times the motion model (`climb_with_motion_prior`): on the single 2D map of all
/// heights a climb on the scan alone turned the particles' heading 0.1–0.2 rad off the gyro's
/// (`office` seeds 1–5, median mean error 0.342 m with GMapping's climb and 0.1 of its noise,
/// 0.142 m with this; BENCHMARKS.md).
pub fn drone_pf_config(seed: u64) -> RbpfConfig {
    let mut config = RbpfConfig {
        seed,
        ..RbpfConfig::default()
    };
    config.proposal.climb_with_motion_prior = true;
    let m = &mut config.motion;
    for noise in [
        &mut m.trans_per_trans,
        &mut m.trans_per_rot,
        &mut m.min_trans_sigma_m,
    ] {
        *noise *= PF_TRANSLATION_NOISE_SCALE;
    }
    for noise in [
        &mut m.rot_per_trans,
        &mut m.rot_per_rot,
        &mut m.min_rot_sigma_rad,
    ] {
        *noise *= PF_ROTATION_NOISE_SCALE;
    }
    config
}

/// The particle filter, fed one scan and its layered estimate at a time.
pub struct DronePf {
    filter: Rbpf,
    /// The layered estimate's planar pose without re-localisations at every scan: the
    /// filter's odometry.
    odometry: Vec<Pose2>,
}

impl DronePf {
    /// A filter with `config` (see [`drone_pf_config`]; its odometry settings are not read:
    /// the odometry is always the layered increments).
    pub fn new(config: RbpfConfig) -> Result<Self, SlamError> {
        Ok(Self {
            filter: Rbpf::new(config)?,
            odometry: Vec::new(),
        })
    }

    /// Takes the next scan with its layered estimate; returns the filter's best pose now: its
    /// best particle's at its last update, moved by the layered increments since (`None`
    /// before the first usable scan). The odometry is the estimate's smooth pose, without the
    /// re-localisations: a jump in odometry would be motion to the filter, whose own map does
    /// not move with the layered maps.
    pub fn push(&mut self, scan: &LaserScan, estimate: &LayeredEstimate) -> Option<Pose3> {
        let odometry = estimate.smooth_world_from_base;
        let index = self.odometry.len();
        self.odometry.push(odometry);
        self.filter.process(index, scan, &odometry);
        let (at, pose) = self.filter.best_pose()?;
        let since = self.odometry.get(at)?.inverse() * odometry;
        Some(with_height(&(pose * since), estimate))
    }

    /// The best particle's planar trajectory over every scan so far, read back through its
    /// ancestry: scans between two updates follow the odometry with the correction found at
    /// the later one spread over them ([`interpolate_poses`]).
    pub fn planar_trajectory(&self) -> Vec<Pose2> {
        interpolate_poses(&self.filter.best_updates(), &self.odometry)
    }

    /// [`Self::planar_trajectory`] in 3D with the height, roll and pitch of `estimates` (the
    /// layered estimates of the same scans).
    pub fn trajectory(&self, estimates: &[LayeredEstimate]) -> Vec<Pose3> {
        self.planar_trajectory()
            .iter()
            .zip(estimates)
            .map(|(p, e)| with_height(p, e))
            .collect()
    }

    /// The best particle's map.
    pub fn map(&self) -> Option<&OccupancyGrid> {
        self.filter.best_map()
    }

    /// Counters so far, with the maps' memory now.
    pub fn stats(&self) -> RbpfStats {
        self.filter.final_stats(true, 0)
    }

    /// Per-stage timings so far.
    pub fn timings(&self) -> &StageTimings {
        self.filter.timings()
    }
}

/// A 3D pose from a planar one, with the height, roll and pitch of the layered tracker at the
/// same scan (the particle filter keeps a single 2D map).
pub fn with_height(planar: &Pose2, estimate: &LayeredEstimate) -> Pose3 {
    let (roll, pitch, _) = estimate.world_from_base.rotation.euler_angles();
    Pose3::from_parts(
        Translation3::new(
            planar.translation.x,
            planar.translation.y,
            estimate.world_from_base.translation.z,
        ),
        UnitQuaternion::from_euler_angles(roll, pitch, planar.rotation.angle()),
    )
}
