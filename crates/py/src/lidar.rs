//! 2D lidar: `read_carmen` gives a `LidarLog`; a `LidarSlam` session builds a new map
//! (ICP-SLAM or the particle filter), localises in a saved one or continues it, scan by scan
//! (`push_scan`) or over a whole log (`run`, the GIL released).

use crate::convert::{one_of, to_python, trajectory_to_array};
use crate::maps::Grid;
use crate::to_py_err;
use nalgebra::{Isometry2, Vector2};
use numpy::{PyArray1, PyArray2, PyReadonlyArray1};
use pyo3::prelude::*;
use slamkit_core::{LaserScan, Pose2};
use slamkit_io::bag::ScanTopics;
use slamkit_io::carmen::CarmenLog;
use slamkit_map::{OccupancyGridConfig, TriGrid};
use slamkit_slam::{LidarMap, LidarMethod, LidarSlam, LidarSlamConfig, Session, Update};
use std::path::PathBuf;

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_carmen, m)?)?;
    m.add_function(wrap_pyfunction!(read_lidar_log, m)?)?;
    m.add_function(wrap_pyfunction!(bag_info, m)?)?;
    m.add_class::<LidarLog>()?;
    m.add_class::<PyLidarSlam>()?;
    Ok(())
}

/// The laser scans (with their odometry) of a log.
#[pyclass(module = "slamkit", frozen)]
pub struct LidarLog {
    pub(crate) log: CarmenLog,
    /// What was read from a bag (topics, counts, the laser's mounting); None for a CARMEN log.
    #[pyo3(get)]
    description: Option<String>,
    /// Damage worth a warning: timestamps stepping back, a tilted laser, skipped messages.
    #[pyo3(get)]
    warnings: Vec<String>,
}

impl LidarLog {
    fn of(log: CarmenLog) -> Self {
        Self {
            log,
            description: None,
            warnings: Vec::new(),
        }
    }
}

#[pymethods]
impl LidarLog {
    fn __len__(&self) -> usize {
        self.log.scans.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "LidarLog({} scans, {} unreadable lines)",
            self.log.scans.len(),
            self.log.skipped.len()
        )
    }

    /// The scans `start..stop` as a log of their own (a part of a run, a first half to map and
    /// a second to continue).
    fn slice(&self, start: usize, stop: usize) -> PyResult<LidarLog> {
        let scans = self.log.scans.get(start..stop).ok_or_else(|| {
            pyo3::exceptions::PyIndexError::new_err(format!(
                "scans {start}..{stop} of a log of {}",
                self.log.scans.len()
            ))
        })?;
        Ok(LidarLog::of(CarmenLog {
            scans: scans.to_vec(),
            ..CarmenLog::default()
        }))
    }

    /// Each scan's time \[s\].
    fn timestamps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_iter(py, self.log.scans.iter().map(|s| s.timestamp))
    }

    /// Each scan's wheel odometry as `(N, 3)` rows `x y yaw` (NaN where a scan has none).
    fn odometry<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let rows: Vec<Vec<f64>> = self
            .log
            .scans
            .iter()
            .map(|s| {
                let (x, y, yaw) = s
                    .odometry
                    .map_or((f64::NAN, f64::NAN, f64::NAN), |p| pose2_row(&p));
                vec![x, y, yaw]
            })
            .collect();
        Ok(PyArray2::from_vec2(py, &rows)?)
    }

    /// Scan `index` as a dict: `timestamp`, `angle_min`, `angle_increment` \[rad\], `ranges`
    /// (array, m), `max_range`, `odometry` (`(x, y, yaw)` or None), `base_from_laser`.
    fn scan(&self, py: Python<'_>, index: usize) -> PyResult<Py<PyAny>> {
        let scan = self.log.scans.get(index).ok_or_else(|| {
            pyo3::exceptions::PyIndexError::new_err(format!(
                "scan {index} of a log of {}",
                self.log.scans.len()
            ))
        })?;
        let dict = pyo3::types::PyDict::new(py);
        dict.set_item("timestamp", scan.timestamp)?;
        dict.set_item("angle_min", scan.angle_min_rad)?;
        dict.set_item("angle_increment", scan.angle_increment_rad)?;
        dict.set_item("ranges", PyArray1::from_slice(py, &scan.ranges_m))?;
        dict.set_item("max_range", scan.max_range_m)?;
        dict.set_item("odometry", scan.odometry.map(|p| pose2_row(&p)))?;
        dict.set_item("base_from_laser", pose2_row(&scan.base_from_laser))?;
        Ok(dict.into_any().unbind())
    }
}

/// Reads a CARMEN log (plain or gzip): its laser scans and odometry. Lines that cannot be read
/// are counted (`repr`), not fatal.
#[pyfunction]
fn read_carmen(py: Python<'_>, path: PathBuf) -> PyResult<LidarLog> {
    let log = py
        .detach(|| slamkit_io::carmen::read_carmen(&path))
        .map_err(to_py_err)?;
    Ok(LidarLog::of(log))
}

/// Reads a 2D lidar log, whichever the path holds: a CARMEN file (plain or gzip) or a ROS 1
/// / ROS 2 bag (a `.bag`, an MCAP or `.db3` file, or a ROS 2 bag's folder), as `slamkit lidar`
/// does. In a bag the `sensor_msgs/LaserScan` and `nav_msgs/Odometry` topics are found by
/// type when there is one of each (`scan_topic`, `odom_topic` choose), the laser's mounting
/// comes from `/tf_static`.
#[pyfunction]
#[pyo3(signature = (path, scan_topic = None, odom_topic = None))]
fn read_lidar_log(
    py: Python<'_>,
    path: PathBuf,
    scan_topic: Option<String>,
    odom_topic: Option<String>,
) -> PyResult<LidarLog> {
    let topics = ScanTopics {
        scan: scan_topic,
        odom: odom_topic,
    };
    let file = py
        .detach(|| slamkit_io::lidar_log::read_lidar_log(&path, &topics))
        .map_err(to_py_err)?;
    Ok(LidarLog {
        log: file.log,
        description: file.description,
        warnings: file.warnings,
    })
}

/// What a ROS 1 or ROS 2 bag holds, as `slamkit bag info --json` prints it: `format`,
/// `topics` (each with `topic`, `message_type`, `messages`, ...), `messages`, `start_s`, `end_s`,
/// `duration_s`, ...
#[pyfunction]
fn bag_info(py: Python<'_>, path: PathBuf) -> PyResult<Py<PyAny>> {
    let info = py
        .detach(|| slamkit_io::bag::open(&path).and_then(|mut bag| bag.summary()))
        .map_err(to_py_err)?;
    let mut value = serde_json::to_value(&info)
        .map_err(|e| crate::SlamkitError::new_err(format!("{}: {e}", path.display())))?;
    value["duration_s"] = serde_json::json!(info.duration_s());
    to_python(py, &value)
}

/// `(x, y, yaw)`: what `push_scan` takes for odometry and mounting.
fn pose2_row(pose: &Pose2) -> (f64, f64, f64) {
    let t = pose.translation.vector;
    (t.x, t.y, pose.rotation.angle())
}

fn pose2(x: f64, y: f64, yaw: f64) -> Pose2 {
    Isometry2::new(Vector2::new(x, y), yaw)
}

/// A 2D lidar SLAM session (`slamkit lidar`'s): `method` `"icp"` (ICP-SLAM) or `"rbpf"` (the
/// particle filter, `particles` and `seed`), settings from a named `profile` and a TOML
/// `config` file as on the command line. `LidarSlam.localise(map)` and
/// `LidarSlam.resume(map)` start in a saved `.skmap` instead.
#[pyclass(module = "slamkit", name = "LidarSlam")]
pub struct PyLidarSlam {
    session: LidarSlam,
}

impl PyLidarSlam {
    fn in_map(
        py: Python<'_>,
        map: PathBuf,
        profile: Option<&str>,
        config: Option<PathBuf>,
        extend: bool,
    ) -> PyResult<Self> {
        let settings =
            LidarSlamConfig::from_files(LidarMethod::Icp, true, profile, config.as_deref())
                .map_err(to_py_err)?;
        let session = py
            .detach(|| {
                let (map, _) = LidarMap::load(&map)?;
                if extend {
                    LidarSlam::resume(settings, map)
                } else {
                    LidarSlam::localise(settings, map)
                }
            })
            .map_err(to_py_err)?;
        Ok(Self { session })
    }
}

#[pymethods]
impl PyLidarSlam {
    #[new]
    #[pyo3(signature = (method = "icp", particles = None, seed = None, profile = None, config = None))]
    fn new(
        method: &str,
        particles: Option<usize>,
        seed: Option<u64>,
        profile: Option<&str>,
        config: Option<PathBuf>,
    ) -> PyResult<Self> {
        let methods = [("icp", LidarMethod::Icp), ("rbpf", LidarMethod::Rbpf)];
        let method = one_of("method", method, &methods)?;
        let mut settings = LidarSlamConfig::from_files(method, false, profile, config.as_deref())
            .map_err(to_py_err)?;
        if let Some(particles) = particles {
            settings.rbpf.particles = particles;
        }
        if let Some(seed) = seed {
            settings.rbpf.seed = seed;
        }
        let session = LidarSlam::new(settings, Pose2::identity()).map_err(to_py_err)?;
        Ok(Self { session })
    }

    /// A session localising in the saved map `map` (not changing it); the start pose is
    /// found by global search.
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

    /// A session continuing the saved map `map`: the robot is found in it, then mapping goes
    /// on.
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

    /// Takes one scan (`ranges` in metres, beams from `angle_min` every `angle_increment`
    /// radians; readings at or beyond `max_range` are no return; `odometry` the wheel
    /// odometry `(x, y, yaw)` at scan time, `base_from_laser` the laser's mounting) and
    /// returns the update: a dict with `timestamp`, `pose` (`(x, y, yaw)` or None), `status`
    /// (`"initialising"`, `"tracking"`, `"predicted"`, `"lost"`), `keyframes_added`,
    /// `loop_closures`, `map_moved`.
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
        let scan = laser_scan(
            timestamp,
            &ranges,
            (angle_min, angle_increment, max_range),
            odometry,
            base_from_laser,
        );
        let update = py.detach(|| self.session.push_scan(scan));
        to_python(py, &update_value(&update))
    }

    /// Pushes every scan of `log` in order, the GIL released; returns the number of scans.
    fn run(&mut self, py: Python<'_>, log: &LidarLog) -> usize {
        let session = &mut self.session;
        py.detach(|| {
            for scan in &log.log.scans {
                session.push_scan(scan.clone());
            }
        });
        log.log.scans.len()
    }

    /// Every scan's pose as the session knows it now, an `(N, 8)` TUM array (z = 0, rotation
    /// about z); scans with no pose are left out.
    fn trajectory<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        trajectory_to_array(py, &self.session.trajectory())
    }

    /// The session's counters (`scans`, `fixes`, `odometry_rejected`, ...) and scan counts
    /// (`processed`, `skipped`, `failed`), as a dict.
    fn stats(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let value = serde_json::json!({
            "session": self.session.stats(),
            "frames": self.session.frame_counts(),
            "method": self.session.method_stats(),
        });
        to_python(py, &value)
    }

    /// The settings in use, as a dict (the `config` block of `slamkit lidar`'s report.json).
    fn config(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        to_python(py, self.session.config())
    }

    /// The occupancy grid of the map's keyframes as it stands.
    fn grid(&self, py: Python<'_>) -> PyResult<Grid> {
        let grid = py
            .detach(|| self.session.map().grid(OccupancyGridConfig::default()))
            .map_err(to_py_err)?;
        Grid::from_tri_grid(py, &TriGrid::from_occupancy_grid(&grid))
    }

    /// Writes the map as a `.skmap` file, atomically.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| Session::save(&self.session, &path))
            .map_err(to_py_err)
    }
}

/// A scan from `push_scan`'s arguments: `beams` is `(angle_min, angle_increment, max_range)`,
/// poses `(x, y, yaw)`.
pub(crate) fn laser_scan(
    timestamp: f64,
    ranges: &PyReadonlyArray1<'_, f64>,
    (angle_min, angle_increment, max_range): (f64, f64, f64),
    odometry: Option<(f64, f64, f64)>,
    base_from_laser: (f64, f64, f64),
) -> LaserScan {
    LaserScan {
        timestamp,
        angle_min_rad: angle_min,
        angle_increment_rad: angle_increment,
        ranges_m: ranges.as_array().to_vec(),
        max_range_m: max_range,
        odometry: odometry.map(|(x, y, yaw)| pose2(x, y, yaw)),
        base_from_laser: pose2(base_from_laser.0, base_from_laser.1, base_from_laser.2),
    }
}

/// An [`Update`] as a dict's JSON, the pose planar (`(x, y, yaw)`).
pub(crate) fn update_value(update: &Update) -> serde_json::Value {
    let pose = update.pose.map(|p| {
        let t = p.translation.vector;
        let (_, _, yaw) = p.rotation.euler_angles();
        (t.x, t.y, yaw)
    });
    serde_json::json!({
        "timestamp": update.timestamp,
        "pose": pose,
        "status": update.status,
        "keyframes_added": update.map.keyframes_added,
        "loop_closures": update.map.loop_closures,
        "map_moved": update.map.map_moved,
    })
}
