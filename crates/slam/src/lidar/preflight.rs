//! Checks of a 2D lidar log and settings before a run, so that a run that cannot give a
//! result, or would ask for more memory than a machine has, is refused at its start.
//!
//! * [`ensure_usable`]: a log none of whose scans can be matched (every range negative: a dead
//!   sensor) is an error, not a run that writes identity poses and scores them.
//! * [`particle_maps_min_bytes`]: the memory the particle filter's maps need at the least,
//!   measured on the log's own scans; [`ensure_fits_memory`] compares it with the machine's.

use crate::SlamError;
use slamkit_core::LaserScan;
use slamkit_lidar::icp_slam::IcpSlamConfig;
use slamkit_lidar::rbpf::hit_means::HitMeans;
use slamkit_lidar::rbpf::RbpfConfig;
use slamkit_map::OccupancyGrid;

/// Scans of the log's start measured by [`particle_maps_min_bytes`].
const MEASURED_SCANS: usize = 20;

/// Refuses `scans` when none has `config.min_scan_points` beams within the matcher's range.
///
/// ```
/// use slamkit_core::{LaserScan, Pose2};
/// use slamkit_lidar::icp_slam::IcpSlamConfig;
/// let dead = LaserScan {
///     timestamp: 0.0,
///     angle_min_rad: -1.5,
///     angle_increment_rad: 0.01,
///     ranges_m: vec![-1.0; 300],
///     max_range_m: 30.0,
///     odometry: None,
///     base_from_laser: Pose2::identity(),
/// };
/// let err = slamkit_slam::lidar::preflight::ensure_usable(&[dead], &IcpSlamConfig::default());
/// assert!(err.unwrap_err().to_string().starts_with("no usable scan"));
/// ```
pub fn ensure_usable(scans: &[LaserScan], config: &IcpSlamConfig) -> Result<(), SlamError> {
    let usable = scans
        .iter()
        .any(|scan| config.scan_points(scan).len() >= config.min_scan_points);
    if usable {
        return Ok(());
    }
    Err(SlamError::NoUsableScan(format!(
        "none of its {} scans has {} beams within {} to {} m (icp.min_scan_points, \
         icp.min_range_m, icp.max_range_m)",
        scans.len(),
        config.min_scan_points,
        config.min_range_m,
        config.max_range_m,
    )))
}

/// The bytes `config.particles` particle maps take at the least on `scans`: from its second
/// update on, every particle holds its own copy of each grid tile (and, with
/// `proposal.mean_hit_points`, each hit-mean tile) that one scan touches, so the filter needs
/// `particles ×` what one scan's map takes, measured here as the largest over the log's first
/// scans. Its maps grow from there as the robot explores. `None` for a log without a scan the
/// grid takes.
pub fn particle_maps_min_bytes(config: &RbpfConfig, scans: &[LaserScan]) -> Option<u64> {
    let c = &config.grid;
    let per_particle = scans
        .iter()
        .take(MEASURED_SCANS)
        .filter_map(|scan| {
            let mut grid = OccupancyGrid::new(c.clone()).ok()?;
            grid.insert_scan(scan, &scan.base_from_laser).ok()?;
            let means = config.proposal.mean_hit_points.then(|| {
                let mut means =
                    HitMeans::new(grid.origin_m(), c.resolution_m, c.max_usable_range_m);
                means.insert_scan(scan, &scan.base_from_laser);
                HitMeans::shared_bytes([&means])
            });
            Some(grid.tile_stats().bytes + means.unwrap_or(0))
        })
        .max()?;
    Some(per_particle as u64 * config.particles as u64)
}

/// Refuses a run whose particle maps need more memory than this machine has
/// ([`crate::memory::total_bytes`]), before it starts: `bytes` is the least they take
/// ([`particle_maps_min_bytes`], `None` when unknown), shared by `particles` particles.
///
/// ```
/// use slamkit_slam::lidar::preflight::ensure_fits_memory;
/// assert!(ensure_fits_memory(Some(1 << 20), 30).is_ok());
/// assert!(ensure_fits_memory(None, 30).is_ok());
/// if slamkit_slam::memory::total_bytes().is_some() {
///     let err = ensure_fits_memory(Some(u64::MAX), 100_000).unwrap_err();
///     assert!(err.to_string().contains("use fewer particles"), "{err}");
/// }
/// ```
pub fn ensure_fits_memory(bytes: Option<u64>, particles: usize) -> Result<(), SlamError> {
    let (Some(bytes), Some(limit)) = (bytes, crate::memory::total_bytes()) else {
        return Ok(());
    };
    if bytes <= limit {
        return Ok(());
    }
    Err(SlamError::Config(format!(
        "{particles} particles need at least {:.1} GB for their maps ({:.2} MB each: the grid \
         tiles one scan covers), more than this machine's {:.1} GB of memory; use fewer particles",
        bytes as f64 / 1e9,
        bytes as f64 / particles.max(1) as f64 / 1e6,
        limit as f64 / 1e9
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scan of a 4 × 4 m room's walls seen from its centre.
    fn room_scan() -> LaserScan {
        let n = 361;
        let ranges = (0..n)
            .map(|i| {
                let a = -std::f64::consts::FRAC_PI_2 + i as f64 * std::f64::consts::PI / 360.0;
                2.0 / a.cos().abs().max(a.sin().abs())
            })
            .collect();
        LaserScan {
            timestamp: 0.0,
            angle_min_rad: -std::f64::consts::FRAC_PI_2,
            angle_increment_rad: std::f64::consts::PI / 360.0,
            ranges_m: ranges,
            max_range_m: 30.0,
            odometry: None,
            base_from_laser: slamkit_core::Pose2::identity(),
        }
    }

    #[test]
    fn particle_maps_scale_with_the_particles_and_the_tiles_a_scan_touches() {
        let config = RbpfConfig::default();
        let scan = room_scan();
        let one = particle_maps_min_bytes(
            &RbpfConfig {
                particles: 1,
                ..config.clone()
            },
            std::slice::from_ref(&scan),
        )
        .unwrap();
        // The front half of a 4 m room at 5 cm seen from its centre (0..2 m × -2..2 m) lies in
        // 2 to 4 tiles of 64 × 64 four-byte cells (3.2 m a side), as the tile borders fall,
        // plus the tile index.
        let tile = 64 * 64 * 4;
        assert!((2 * tile..5 * tile).contains(&one), "{one}");
        let many = RbpfConfig {
            particles: 1000,
            ..config
        };
        assert_eq!(particle_maps_min_bytes(&many, &[scan]), Some(1000 * one));
        assert_eq!(particle_maps_min_bytes(&many, &[]), None);
    }

    #[test]
    fn a_log_of_negative_ranges_is_not_usable() {
        let config = IcpSlamConfig::default();
        assert!(ensure_usable(&[room_scan()], &config).is_ok());
        let mut dead = room_scan();
        dead.ranges_m.iter_mut().for_each(|r| *r = -1.0);
        let err = ensure_usable(&[dead.clone(), dead], &config)
            .unwrap_err()
            .to_string();
        assert!(err.contains("none of its 2 scans"), "{err}");
    }
}
