//! Conversions between slamkit's types and what Python programs hold: trajectories as `(N, 8)`
//! float64 arrays of TUM rows (`t x y z qx qy qz qw`, the layout of a TUM file and of evo's
//! `np.column_stack((timestamps, positions_xyz, orientations_quat_xyzw))`), and results as plain
//! dicts (through their JSON, so Python sees the field names report.json shows).

use crate::SlamkitError;
use nalgebra::{Isometry3, Translation3};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use serde::Serialize;
use slamkit_core::Trajectory;
use slamkit_io::trajectory_file::unit_quaternion;

/// Columns of a trajectory array.
pub const TUM_COLUMNS: usize = 8;

/// `trajectory` as an `(N, 8)` array of TUM rows.
pub fn trajectory_to_array<'py>(
    py: Python<'py>,
    trajectory: &Trajectory,
) -> Bound<'py, PyArray2<f64>> {
    let mut rows = Array2::zeros((trajectory.poses.len(), TUM_COLUMNS));
    for (mut row, p) in rows.rows_mut().into_iter().zip(&trajectory.poses) {
        let t = p.pose.translation.vector;
        let q = p.pose.rotation.coords; // x, y, z, w
        let values = [p.timestamp, t.x, t.y, t.z, q.x, q.y, q.z, q.w];
        for (cell, value) in row.iter_mut().zip(values) {
            *cell = value;
        }
    }
    rows.into_pyarray(py)
}

/// An `(N, 8)` array of TUM rows as a trajectory: values finite, quaternions normalised as the
/// TUM reader normalises them.
///
/// # Errors
/// [`SlamkitError`] naming `what` and the row for a wrong shape or a bad value.
pub fn array_to_trajectory(array: &PyReadonlyArray2<'_, f64>, what: &str) -> PyResult<Trajectory> {
    let view = array.as_array();
    if view.ncols() != TUM_COLUMNS {
        return Err(SlamkitError::new_err(format!(
            "{what}: an (N, 8) array of TUM rows (t x y z qx qy qz qw) is expected, got shape \
             {:?}",
            view.shape()
        )));
    }
    let mut trajectory = Trajectory::new();
    for (i, row) in view.rows().into_iter().enumerate() {
        let bad = |m: String| SlamkitError::new_err(format!("{what}: row {i}: {m}"));
        if let Some(v) = row.iter().find(|v| !v.is_finite()) {
            return Err(bad(format!("{v} is not a finite number")));
        }
        let q = unit_quaternion(row[7], row[4], row[5], row[6]).map_err(bad)?;
        let pose = Isometry3::from_parts(Translation3::new(row[1], row[2], row[3]), q);
        trajectory.push(row[0], pose);
    }
    Ok(trajectory)
}

/// The value `choices` pairs with `name`, or an error naming the argument `what` and the
/// names it takes.
///
/// # Errors
/// [`SlamkitError`] for a name not among `choices`.
pub fn one_of<T: Copy>(what: &str, name: &str, choices: &[(&str, T)]) -> PyResult<T> {
    if let Some((_, value)) = choices.iter().find(|(n, _)| *n == name) {
        return Ok(*value);
    }
    let names: Vec<String> = choices.iter().map(|(n, _)| format!("{n:?}")).collect();
    Err(SlamkitError::new_err(format!(
        "{what} must be {}, got {name:?}",
        names.join(" or ")
    )))
}

/// `value` as the Python object its JSON gives (dicts, lists, floats, ints, strings, None).
///
/// # Errors
/// [`SlamkitError`] when `value` does not serialise.
pub fn to_python(py: Python<'_>, value: &impl Serialize) -> PyResult<Py<PyAny>> {
    let text = serde_json::to_string(value).map_err(crate::to_py_err)?;
    Ok(py.import("json")?.call_method1("loads", (text,))?.unbind())
}
