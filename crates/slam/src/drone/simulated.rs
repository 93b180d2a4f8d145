//! The drone's session on a simulated flight, scored against the simulator's ground truth
//! (`slamkit demo`). The simulator's readings go through a [`DroneSlam`] in time order, as a
//! recording would, with the demo's particle filter on the layered increments; each estimated
//! 3D position is then compared with the true one at the same time. Like the simulated closed
//! loop, only the scoring reads the truth; the session never sees it.
//!
//! Layered ICP-SLAM ([`slamkit_lidar::layers`]) keeps one 2D map per 5 cm height layer, the
//! layer tracked by the up and down range finders, scans ignored while the drone tilts, each
//! scan predicted from the drone's recent velocity, its tilt, its yaw-rate gyro (heading and
//! gyro bias in a Kalman filter that the scans correct) and its downward optical-flow velocity
//! sensor ([`slamkit_sim::flow`]), matches kept only along the directions the scan constrains,
//! each fixed scan matched again to the older maps of the layers within 0.2 m. Particle-filter
//! SLAM ([`super::particle_filter`]) runs on the same scans in a single 2D map, its height taken
//! from the layered tracker. Neither uses the scans' rotate–translate–rotate odometry: its
//! per-scan yaw error exceeds 0.19 rad on 5 % of the `large` flight's scans. The particle filter
//! takes its motion from the layered matcher's pose increments, as MRPT's ICP-based RBPF takes
//! scan-matching odometry, and keeps its own maps and scan matching (`large`, seeds 1–4: PF mean
//! error 0.20–2.2 m with the drone's odometry, 0.08–0.84 m with scan-to-scan ICP, 0.04–0.08 m
//! with the layered increments).

use super::particle_filter::drone_pf_config;
use super::{DroneSlam, DroneSlamConfig};
use crate::SlamError;
use nalgebra::{Translation3, UnitQuaternion};
use serde::Serialize;
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{Pose3, Trajectory};
use slamkit_sim::LidarRun;
use std::time::Instant;

/// One method's estimate of a simulated flight and its errors.
#[derive(Debug, Clone)]
pub struct FlightErrors {
    /// Short name used in file names and report keys.
    pub key: &'static str,
    /// Name shown to people.
    pub title: &'static str,
    /// Estimated poses in the simulator's frame, at the true poses' times.
    pub estimate: Trajectory,
    /// 3D position error at each pose \[m\].
    pub errors_m: Vec<f64>,
}

/// Summary of a [`FlightErrors`] against the truth (`metrics.icp` and `metrics.pf` of the
/// demo's `report.json`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FlightMetrics {
    /// Mean 3D position error \[m\].
    pub position_error_mean_m: f64,
    /// Largest 3D position error \[m\].
    pub position_error_max_m: f64,
    /// Mean horizontal (x, y) position error \[m\].
    pub horizontal_error_mean_m: f64,
    /// Mean height error \[m\].
    pub height_error_mean_m: f64,
    /// Length of the true path \[m\].
    pub path_length_m: f64,
}

impl FlightErrors {
    /// The estimate `poses` (one per scan, frame of the session's first scan) moved into the
    /// simulator's frame ([`sim_from_slam`]) and its 3D position error at every scan.
    ///
    /// ```
    /// use slamkit_core::{Pose3, Trajectory};
    /// use slamkit_sim::LidarRun;
    /// use slamkit_slam::drone::simulated::FlightErrors;
    ///
    /// let mut truth = Trajectory::new();
    /// truth.push(0.0, Pose3::translation(1.0, 2.0, 0.5));
    /// truth.push(1.0, Pose3::translation(2.0, 2.0, 0.5));
    /// let run = LidarRun { scans: vec![], ranges: vec![], attitudes: vec![], flows: vec![], ground_truth: truth };
    /// // SLAM's frame starts at the first true x, y and heading; heights are above the floor
    /// let poses = [Pose3::translation(0.0, 0.0, 0.5), Pose3::translation(1.0, 0.0, 0.8)];
    /// let e = FlightErrors::new("icp", "ICP", &run, &poses)?;
    /// assert!(e.errors_m[0] < 1e-12 && (e.errors_m[1] - 0.3).abs() < 1e-12);
    /// assert!((e.mean_m() - 0.15).abs() < 1e-12 && (e.max_m() - 0.3).abs() < 1e-12);
    /// # Ok::<(), slamkit_slam::SlamError>(())
    /// ```
    pub fn new(
        key: &'static str,
        title: &'static str,
        run: &LidarRun,
        poses: &[Pose3],
    ) -> Result<Self, SlamError> {
        let sim_from_slam = sim_from_slam(run)?;
        let mut estimate = Trajectory::new();
        for (pose, truth) in poses.iter().zip(&run.ground_truth.poses) {
            estimate.push(truth.timestamp, sim_from_slam * pose);
        }
        let errors_m = estimate
            .poses
            .iter()
            .zip(&run.ground_truth.poses)
            .map(|(e, t)| (e.pose.translation.vector - t.pose.translation.vector).norm())
            .collect();
        Ok(Self {
            key,
            title,
            estimate,
            errors_m,
        })
    }

    /// Mean 3D position error \[m\] (0 with no pose).
    pub fn mean_m(&self) -> f64 {
        self.errors_m.iter().sum::<f64>() / self.errors_m.len().max(1) as f64
    }

    /// Largest 3D position error \[m\] (0 with no pose).
    pub fn max_m(&self) -> f64 {
        self.errors_m.iter().copied().fold(0.0, f64::max)
    }

    /// Mean, largest, horizontal and height errors against `truth` (the run's ground truth).
    pub fn metrics(&self, truth: &Trajectory) -> FlightMetrics {
        let pairs = || self.estimate.poses.iter().zip(&truth.poses);
        let horizontal: Vec<f64> = pairs()
            .map(|(e, t)| {
                (e.pose.translation.vector - t.pose.translation.vector)
                    .xy()
                    .norm()
            })
            .collect();
        let vertical: Vec<f64> = pairs()
            .map(|(e, t)| (e.pose.translation.z - t.pose.translation.z).abs())
            .collect();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        FlightMetrics {
            position_error_mean_m: self.mean_m(),
            position_error_max_m: self.max_m(),
            horizontal_error_mean_m: mean(&horizontal),
            height_error_mean_m: mean(&vertical),
            path_length_m: truth.path_length_m(),
        }
    }
}

/// The simulator's frame seen from SLAM's: SLAM's x, y and yaw start at the first true pose,
/// its heights are above the floor, which is the simulator's z = 0.
pub fn sim_from_slam(run: &LidarRun) -> Result<Pose3, SlamError> {
    let first = run
        .ground_truth
        .poses
        .first()
        .ok_or_else(|| SlamError::Scoring("the simulation produced no scan".into()))?;
    let planar = pose3_to_pose2(&first.pose);
    Ok(Pose3::from_parts(
        Translation3::new(planar.translation.x, planar.translation.y, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, planar.rotation.angle()),
    ))
}

/// The demo's settings: layered ICP-SLAM's defaults and the drone's particle filter seeded
/// with `seed`.
pub fn flight_config(seed: u64) -> DroneSlamConfig {
    DroneSlamConfig {
        particle_filter: Some(drone_pf_config(seed)),
        ..DroneSlamConfig::default()
    }
}

/// A simulated flight through a [`DroneSlam`] with a particle filter, and both methods'
/// errors.
pub struct SimulatedFlight {
    /// The session after the last scan.
    pub session: DroneSlam,
    /// Wall time of the session \[s\].
    pub session_seconds: f64,
    /// The simulator's frame seen from the session's first-scan frame.
    pub sim_from_slam: Pose3,
    /// Layered ICP-SLAM's errors.
    pub icp: FlightErrors,
    /// The particle filter's errors (its best particle's smoothed trajectory).
    pub pf: FlightErrors,
}

impl SimulatedFlight {
    /// Pushes every reading of `run` into a new session with `config` (which must configure
    /// a particle filter), calling `on_scan` after each scan, and scores both methods
    /// against the run's truth.
    pub fn fly(
        run: &LidarRun,
        config: DroneSlamConfig,
        on_scan: impl FnMut(),
    ) -> Result<Self, SlamError> {
        let started = Instant::now();
        let session = DroneSlam::from_observations(config, run.observations(), on_scan)?;
        let session_seconds = started.elapsed().as_secs_f64();
        let pf_filter = session.particle_filter().ok_or_else(|| {
            SlamError::Config("the flight needs a session with a particle filter".into())
        })?;
        let estimates = session.estimates();
        let icp_poses: Vec<Pose3> = estimates.iter().map(|e| e.world_from_base).collect();
        let icp = FlightErrors::new("icp", "layered ICP-SLAM", run, &icp_poses)?;
        let pf_poses = pf_filter.trajectory(&estimates);
        let pf = FlightErrors::new("pf", "particle-filter SLAM", run, &pf_poses)?;
        Ok(Self {
            sim_from_slam: sim_from_slam(run)?,
            session,
            session_seconds,
            icp,
            pf,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_sim::{SimConfig, Simulation, World};

    /// The first `seconds` of the `small` world's flight with seed 1.
    fn short_run(seconds: f64) -> LidarRun {
        let sim = Simulation::new(World::builtin("small").unwrap(), SimConfig::default(), 1);
        let mut run = sim.unwrap().lidar_run();
        let n = run.scans.iter().filter(|s| s.timestamp <= seconds).count();
        run.scans.truncate(n);
        run.ground_truth.poses.truncate(n);
        run.ranges.retain(|r| r.timestamp <= seconds);
        run.attitudes.retain(|a| a.timestamp <= seconds);
        run.flows.retain(|f| f.timestamp <= seconds);
        run
    }

    #[test]
    fn a_short_flight_is_scored_at_every_scan() {
        let run = short_run(20.0);
        let mut scans = 0;
        let flight = SimulatedFlight::fly(&run, flight_config(1), || scans += 1).unwrap();
        assert_eq!(scans, run.scans.len());
        for m in [&flight.icp, &flight.pf] {
            assert_eq!(m.errors_m.len(), run.scans.len(), "{}", m.title);
            let metrics = m.metrics(&run.ground_truth);
            // measured: 8 mm (ICP), 33 mm (particle filter) over these 20 s
            assert!(
                metrics.position_error_mean_m < 0.05,
                "{}: {metrics:?}",
                m.title
            );
            assert!(metrics.horizontal_error_mean_m <= metrics.position_error_mean_m + 1e-12);
            assert!(metrics.height_error_mean_m <= metrics.position_error_mean_m + 1e-12);
        }
        let no_pf = DroneSlamConfig::default();
        assert!(matches!(
            SimulatedFlight::fly(&run, no_pf, || ()),
            Err(SlamError::Config(_))
        ));
    }
}
