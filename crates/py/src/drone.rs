//! The drone: a `DroneSlam` session (`slamkit lidar LOG --ranges ...`'s) maps a flight in
//! height layers, switched by its up- and down-looking range finders, from its scans, range
//! pairs and optionally attitude and optical flow, reading by reading (`push_*`) or over a
//! whole recorded flight (`run`, the GIL released).

use crate::convert::{to_python, trajectory_to_array};
use crate::lidar::{laser_scan, update_value, LidarLog};
use crate::maps::Grid;
use crate::to_py_err;
use nalgebra::Vector2;
use numpy::{PyArray2, PyReadonlyArray1};
use pyo3::prelude::*;
use slamkit_core::observation::{time_ordered, FlowSample, ImuSample, RangePair};
use slamkit_core::Observation;
use slamkit_io::carmen::CarmenLog;
use slamkit_io::drone_csv::read_observations;
use slamkit_map::{OccupancyGridConfig, TriGrid};
use slamkit_slam::drone::map::DroneMap;
use slamkit_slam::{DroneSlam, DroneSlamConfig, Session};
use std::path::PathBuf;

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDroneSlam>()?;
    Ok(())
}

/// A drone's layered 2D lidar SLAM session: settings from a named `profile` and a TOML
/// `config` file as on the command line; with `particles`, the particle filter runs on the
/// layered increments too (seeded by `seed`). `DroneSlam.localise(map)` and
/// `DroneSlam.resume(map)` start in a drone's saved `.skmap` instead.
#[pyclass(module = "slamkit", name = "DroneSlam")]
pub struct PyDroneSlam {
    session: DroneSlam,
    /// The scans pushed, which the grids are drawn from (the session keeps point maps).
    scans: CarmenLog,
}

impl PyDroneSlam {
    fn in_map(
        py: Python<'_>,
        map: PathBuf,
        profile: Option<&str>,
        config: Option<PathBuf>,
        extend: bool,
    ) -> PyResult<Self> {
        let settings = DroneSlamConfig::from_files(None, None, profile, config.as_deref())
            .map_err(to_py_err)?;
        let session = py
            .detach(|| {
                let map = DroneMap::load(&map)?;
                if extend {
                    DroneSlam::resume(settings, map)
                } else {
                    DroneSlam::localise(settings, map)
                }
            })
            .map_err(to_py_err)?;
        Ok(Self::with(session))
    }

    fn with(session: DroneSlam) -> Self {
        Self {
            session,
            scans: CarmenLog::default(),
        }
    }

    /// Takes a non-scan reading (stored for the next scan).
    fn reading(&mut self, observation: Observation) {
        self.session.push(observation);
    }
}

#[pymethods]
impl PyDroneSlam {
    #[new]
    #[pyo3(signature = (particles = None, seed = None, profile = None, config = None))]
    fn new(
        particles: Option<usize>,
        seed: Option<u64>,
        profile: Option<&str>,
        config: Option<PathBuf>,
    ) -> PyResult<Self> {
        let settings = DroneSlamConfig::from_files(particles, seed, profile, config.as_deref())
            .map_err(to_py_err)?;
        Ok(Self::with(DroneSlam::new(settings).map_err(to_py_err)?))
    }

    /// A session localising in the drone's saved map `map` (not changing it); the drone is
    /// found in it by a global search.
    #[staticmethod]
    #[pyo3(signature = (map, profile = None, config = None))]
    fn localise(
        py: Python<'_>,
        map: PathBuf,
        profile: Option<&str>,
        config: Option<PathBuf>,
    ) -> PyResult<Self> {
        Self::in_map(py, map, profile, config, false)
    }

    /// A session continuing the drone's saved map `map`: the drone is found in it, then
    /// mapping goes on.
    #[staticmethod]
    #[pyo3(signature = (map, profile = None, config = None))]
    fn resume(
        py: Python<'_>,
        map: PathBuf,
        profile: Option<&str>,
        config: Option<PathBuf>,
    ) -> PyResult<Self> {
        Self::in_map(py, map, profile, config, true)
    }

    /// Takes one scan, as `LidarSlam.push_scan` does, and returns the update: a dict with
    /// `timestamp`, `pose` (`(x, y, yaw)` or None), `height` (m above the floor, or None),
    /// `layer`, `status`, `keyframes_added`, `loop_closures`, `map_moved`. Push the range
    /// finders' (and attitude, flow) readings up to the scan's time first.
    #[pyo3(signature = (timestamp, ranges, angle_min, angle_increment, max_range, odometry = None, base_from_laser = (0.0, 0.0, 0.0)))]
    #[allow(clippy::too_many_arguments)]
    fn push_scan(
        &mut self,
        py: Python<'_>,
        timestamp: f64,
        ranges: PyReadonlyArray1<'_, f64>,
        angle_min: f64,
        angle_increment: f64,
        max_range: f64,
        odometry: Option<(f64, f64, f64)>,
        base_from_laser: (f64, f64, f64),
    ) -> PyResult<Py<PyAny>> {
        let beams = (angle_min, angle_increment, max_range);
        let scan = laser_scan(timestamp, &ranges, beams, odometry, base_from_laser);
        self.scans.scans.push(scan.clone());
        let session = &mut self.session;
        let update = py.detach(|| session.push(Observation::Scan(scan)));
        let mut value = update.as_ref().map(update_value).unwrap_or_default();
        let pose = update.and_then(|u| u.pose);
        value["height"] = serde_json::json!(pose.map(|p| p.translation.z));
        value["layer"] =
            serde_json::json!(self.session.scans().last().and_then(|r| r.estimate.layer));
        to_python(py, &value)
    }

    /// Takes a range pair: the up-looking sensor's distance to the ceiling and the
    /// down-looking one's to the floor \[m\] (None: no reading).
    #[pyo3(signature = (timestamp, up = None, down = None))]
    fn push_range(&mut self, timestamp: f64, up: Option<f64>, down: Option<f64>) {
        self.reading(Observation::Range(RangePair {
            timestamp,
            up_m: up,
            down_m: down,
        }));
    }

    /// Takes the attitude (`roll`, `pitch` \[rad\]) and the gyro's integrated heading
    /// (`gyro_yaw` \[rad\], any origin; None without a gyro).
    #[pyo3(signature = (timestamp, roll, pitch, gyro_yaw = None))]
    fn push_attitude(&mut self, timestamp: f64, roll: f64, pitch: f64, gyro_yaw: Option<f64>) {
        self.reading(Observation::Imu(ImuSample {
            timestamp,
            roll_rad: roll,
            pitch_rad: pitch,
            gyro_yaw_rad: gyro_yaw,
        }));
    }

    /// Takes an optical-flow reading: the mean body-frame velocity `(forward, left)` \[m/s\]
    /// over the `integration` period \[s\] ending at `timestamp` (None: no surface in range).
    #[pyo3(signature = (timestamp, integration, velocity = None))]
    fn push_flow(&mut self, timestamp: f64, integration: f64, velocity: Option<(f64, f64)>) {
        self.reading(Observation::Flow(FlowSample {
            timestamp,
            integration_s: integration,
            velocity_mps: velocity.map(|(forward, left)| Vector2::new(forward, left)),
        }));
    }

    /// Runs a recorded flight, the GIL released: the scans of `log` in time order with the
    /// CSV files of the range finders (`ranges`) and optionally attitude (`imu`) and flow
    /// (`flow`), as `slamkit lidar LOG --ranges ...` reads them. Returns the readings per file
    /// as a dict.
    #[pyo3(signature = (log, ranges, imu = None, flow = None))]
    fn run(
        &mut self,
        py: Python<'_>,
        log: &LidarLog,
        ranges: PathBuf,
        imu: Option<PathBuf>,
        flow: Option<PathBuf>,
    ) -> PyResult<Py<PyAny>> {
        let (session, scans) = (&mut self.session, &mut self.scans.scans);
        let counts = py
            .detach(|| {
                let readings = read_observations(&ranges, imu.as_deref(), flow.as_deref())?;
                let mut observations = readings.observations;
                observations.extend(log.log.scans.iter().cloned().map(Observation::Scan));
                for observation in time_ordered(observations) {
                    if let Observation::Scan(scan) = &observation {
                        scans.push(scan.clone());
                    }
                    session.push(observation);
                }
                Ok::<_, slamkit_io::IoError>(readings.counts)
            })
            .map_err(to_py_err)?;
        to_python(py, &counts)
    }

    /// Every scan's pose in the map frame as the session knows it now, an `(N, 8)` TUM array
    /// (z the height above the floor).
    fn trajectory<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        trajectory_to_array(py, &self.session.trajectory())
    }

    /// The particle filter's trajectory (its best particle's), or None without the filter.
    fn pf_trajectory<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.session
            .pf_trajectory()
            .map(|t| trajectory_to_array(py, &t))
    }

    /// The height layers mapped so far: a list of dicts with `layer`, `z_range` \[m\] and
    /// `scans`.
    fn layers(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let grids = self.grids(py)?;
        let layers: Vec<serde_json::Value> = grids
            .layers
            .iter()
            .map(|(layer, l)| {
                serde_json::json!({ "layer": layer, "z_range": l.z_range_m, "scans": l.scans })
            })
            .collect();
        to_python(py, &layers)
    }

    /// The occupancy grid of height layer `layer`'s scans, or of every layer's with None, in
    /// the map frame.
    #[pyo3(signature = (layer = None))]
    fn grid(&self, py: Python<'_>, layer: Option<i64>) -> PyResult<Grid> {
        let grids = self.grids(py)?;
        let grid = match layer {
            None => &grids.all,
            Some(k) => {
                &grids
                    .layers
                    .get(&k)
                    .ok_or_else(|| {
                        pyo3::exceptions::PyKeyError::new_err(format!("no layer {k} mapped"))
                    })?
                    .grid
            }
        };
        Grid::from_tri_grid(py, &TriGrid::from_occupancy_grid(grid))
    }

    /// The session's settings, counters and timings, as a dict (the session's part of
    /// `slamkit lidar LOG --ranges ...`'s report.json: `config`, `frames`, `stats`, `in_map`,
    /// `pf`, `timings_ms`).
    fn stats(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        to_python(py, &self.session.run_report(&self.scans))
    }

    /// Writes the map as a `.skmap` file, atomically.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| Session::save(&self.session, &path))
            .map_err(to_py_err)
    }
}

impl PyDroneSlam {
    fn grids(&self, py: Python<'_>) -> PyResult<slamkit_slam::drone::grids::LayerGrids> {
        let (session, scans) = (&self.session, &self.scans.scans);
        py.detach(|| {
            session.layer_grids(
                scans,
                &session.map_from_world(),
                &OccupancyGridConfig::default(),
            )
        })
        .map_err(to_py_err)
    }
}
