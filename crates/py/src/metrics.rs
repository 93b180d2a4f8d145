//! Trajectory files and accuracy metrics: `read_trajectory`, `read_relations`, `ate`, `rpe`
//! and `relations_error`, computed as `slamkit eval` computes them (ATE and RPE as evo's
//! `evo_ape` / `evo_rpe`, translation part; the relations metric of Kümmerle et al. 2009).

use crate::convert::{array_to_trajectory, one_of, to_python, trajectory_to_array};
use crate::{to_py_err, SlamkitError};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use slamkit_core::Trajectory;
use slamkit_eval::{Alignment, DeltaUnit, ErrorStats, Pairing, RpeConfig, DEFAULT_MAX_DIFF_S};
use std::path::PathBuf;

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_trajectory, m)?)?;
    m.add_function(wrap_pyfunction!(read_relations, m)?)?;
    m.add_function(wrap_pyfunction!(ate, m)?)?;
    m.add_function(wrap_pyfunction!(rpe, m)?)?;
    m.add_function(wrap_pyfunction!(relations_error, m)?)?;
    m.add("DEFAULT_MAX_DIFF_S", DEFAULT_MAX_DIFF_S)?;
    Ok(())
}

/// Reads a trajectory file (TUM, KITTI or EuRoC CSV, told from its content) as an `(N, 8)`
/// array of TUM rows, and its format's name.
#[pyfunction]
fn read_trajectory(py: Python<'_>, path: PathBuf) -> PyResult<(Bound<'_, PyArray2<f64>>, String)> {
    let (trajectory, format) =
        py.detach(|| slamkit_io::read_trajectory(&path).map_err(to_py_err))?;
    let name = format!("{format:?}").to_lowercase();
    Ok((trajectory_to_array(py, &trajectory), name))
}

/// Reads a `.relations` file as an `(M, 8)` array: `t1 t2 x y z roll pitch yaw`, the motion
/// from the pose at `t1` to the pose at `t2` in the first's frame (angles in radians).
#[pyfunction]
fn read_relations(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArray2<f64>>> {
    let relations = slamkit_io::relations::read_relations(&path).map_err(to_py_err)?;
    let mut rows = Array2::zeros((relations.len(), 8));
    for (mut row, r) in rows.rows_mut().into_iter().zip(&relations) {
        let t = r.t1_from_t2.translation.vector;
        let (roll, pitch, yaw) = r.t1_from_t2.rotation.euler_angles();
        for (cell, value) in row
            .iter_mut()
            .zip([r.t1, r.t2, t.x, t.y, t.z, roll, pitch, yaw])
        {
            *cell = value;
        }
    }
    Ok(rows.into_pyarray(py))
}

/// How two trajectories pair: `"time"` (nearest timestamp within `max_diff` seconds) or
/// `"index"` (pose i with pose i, as for KITTI files).
fn pairing(name: &str, max_diff: f64) -> PyResult<Pairing> {
    match name {
        "time" if max_diff.is_finite() && max_diff >= 0.0 => Ok(Pairing::NearestTime {
            max_diff_s: max_diff,
        }),
        "time" => Err(SlamkitError::new_err(format!(
            "max_diff must be a non-negative number of seconds, got {max_diff}"
        ))),
        "index" => Ok(Pairing::Index),
        other => Err(SlamkitError::new_err(format!(
            "pairing must be \"time\" or \"index\", got {other:?}"
        ))),
    }
}

/// The statistics as a dict (`rmse`, `mean`, `median`, `std`, `min`, `max`, `sse`, `pairs`),
/// with each pair's `errors` and `timestamps` as arrays.
fn stats_dict<'py>(
    py: Python<'py>,
    stats: &ErrorStats,
    errors: Vec<f64>,
    timestamps: Vec<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let dict = to_python(py, stats)?.into_bound(py).cast_into::<PyDict>()?;
    dict.set_item("errors", PyArray1::from_vec(py, errors))?;
    dict.set_item("timestamps", PyArray1::from_vec(py, timestamps))?;
    Ok(dict)
}

fn two_trajectories(
    reference: &PyReadonlyArray2<'_, f64>,
    estimate: &PyReadonlyArray2<'_, f64>,
) -> PyResult<(Trajectory, Trajectory)> {
    Ok((
        array_to_trajectory(reference, "reference")?,
        array_to_trajectory(estimate, "estimate")?,
    ))
}

/// Absolute trajectory error of `estimate` against `reference` (both `(N, 8)` TUM arrays)
/// after `align` (`"se3"`, `"sim3"` or `"none"`): evo_ape's translation part.
#[pyfunction]
#[pyo3(signature = (reference, estimate, align = "se3", max_diff = DEFAULT_MAX_DIFF_S, pairing = "time"))]
fn ate<'py>(
    py: Python<'py>,
    reference: PyReadonlyArray2<'py, f64>,
    estimate: PyReadonlyArray2<'py, f64>,
    align: &str,
    max_diff: f64,
    pairing: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let (reference, estimate) = two_trajectories(&reference, &estimate)?;
    let pairing = self::pairing(pairing, max_diff)?;
    let align: Alignment = align.parse().map_err(to_py_err)?;
    let result = py
        .detach(|| slamkit_eval::ate(&reference, &estimate, pairing, align))
        .map_err(to_py_err)?;
    stats_dict(py, &result.stats, result.errors_m, result.timestamps)
}

/// Relative pose error of `estimate` against `reference` over `delta` (`unit` `"frames"` or
/// `"m"`), with `all_pairs` as evo's `--all_pairs`: evo_rpe's translation part.
#[pyfunction]
#[pyo3(signature = (reference, estimate, delta = 1.0, unit = "frames", all_pairs = false, max_diff = DEFAULT_MAX_DIFF_S, pairing = "time"))]
#[allow(clippy::too_many_arguments)]
fn rpe<'py>(
    py: Python<'py>,
    reference: PyReadonlyArray2<'py, f64>,
    estimate: PyReadonlyArray2<'py, f64>,
    delta: f64,
    unit: &str,
    all_pairs: bool,
    max_diff: f64,
    pairing: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let (reference, estimate) = two_trajectories(&reference, &estimate)?;
    let pairing = self::pairing(pairing, max_diff)?;
    let units = [("frames", DeltaUnit::Frames), ("m", DeltaUnit::Metres)];
    let unit = one_of("unit", unit, &units)?;
    let config = RpeConfig {
        delta,
        unit,
        all_pairs,
        ..RpeConfig::default()
    };
    let result = py
        .detach(|| slamkit_eval::rpe(&reference, &estimate, pairing, &config))
        .map_err(to_py_err)?;
    stats_dict(py, &result.stats, result.errors_m, result.timestamps)
}

/// The relations metric of `estimate` (an `(N, 8)` TUM array) against the `.relations` file
/// at `relations`: a dict with `trans_mean` \[m\], `trans_std`, `rot_mean_deg`, `rot_std_deg`,
/// `count`, ... as `slamkit eval relations --json` prints it.
#[pyfunction]
fn relations_error(
    py: Python<'_>,
    relations: PathBuf,
    estimate: PyReadonlyArray2<'_, f64>,
) -> PyResult<Py<PyAny>> {
    let estimate = array_to_trajectory(&estimate, "estimate")?;
    let relations = slamkit_io::relations::read_relations(&relations).map_err(to_py_err)?;
    let stats = py
        .detach(|| slamkit_eval::relations_error(&relations, &estimate))
        .map_err(to_py_err)?;
    to_python(py, &stats)
}
