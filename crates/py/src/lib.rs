//! slamkit for Python: the module `slamkit`, built by maturin into an abi3 wheel.
//!
//! A thin layer over the libraries, so that a Python program gets what the CLI gets:
//!
//! * [`lidar`]: `read_carmen`, `read_lidar_log` (a CARMEN file or a ROS 1 / ROS 2 bag),
//!   `bag_info`, and `LidarSlam` (ICP-SLAM or the particle filter; a new map, localisation in
//!   a saved one, or its continuation).
//! * [`drone`]: `DroneSlam`, layered 2D lidar SLAM switched by up/down range finders.
//! * [`visual`]: `Dataset` (the RGB-D and stereo folder readers, RGB-D bags) and `VisualSlam`.
//! * [`maps`]: `Map`, a `.skmap` file: its description, its planning grid as a numpy array,
//!   its export.
//! * [`metrics`]: `read_trajectory`, `read_relations`, `ate`, `rpe`, `relations_error`.
//! * [`convert`]: trajectories as `(N, 8)` TUM arrays, results as plain Python objects.
//!
//! Heavy work (a whole log, a dataset, a metric over millions of poses) runs with the GIL
//! released. Every error is a `slamkit.SlamkitError` whose message is the CLI's one line.
//! The stubs in `slamkit.pyi` document the Python API.

use pyo3::prelude::*;

pub mod convert;
pub mod drone;
pub mod lidar;
pub mod maps;
pub mod metrics;
pub mod visual;

pyo3::create_exception!(
    slamkit,
    SlamkitError,
    pyo3::exceptions::PyException,
    "An error of slamkit: a file that cannot be read, bad settings, a failed run."
);

/// A [`SlamkitError`] carrying `err` and its causes on one line (`outer: cause: root`), as the
/// CLI prints them.
pub fn to_py_err(err: impl std::error::Error) -> PyErr {
    SlamkitError::new_err(slamkit_core::error::error_chain(&err))
}

/// The Python module.
#[pymodule]
fn slamkit(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("SlamkitError", m.py().get_type::<SlamkitError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    lidar::register(m)?;
    drone::register(m)?;
    visual::register(m)?;
    maps::register(m)?;
    metrics::register(m)?;
    Ok(())
}
