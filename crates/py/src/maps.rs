//! Map files: `Map` reads a `.skmap` of any rig (what it holds, its planning grid as a numpy
//! array, its export to PGM/YAML, PNG, PLY and TUM files), and `Grid` is a grid as numpy sees
//! it.

use crate::to_py_err;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use slamkit_map::TriGrid;
use slamkit_slam::map_file::info::MapInfo;
use slamkit_slam::map_file::{export, MapFile};
use std::path::PathBuf;

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Grid>()?;
    m.add_class::<Map>()?;
    Ok(())
}

/// An occupancy grid as ROS's `nav_msgs/OccupancyGrid` holds it: `data[j, i]` is the cell
/// whose lower-left corner is `origin + (i, j) * resolution` (row 0 at the origin's y), with
/// -1 unknown, 0 free and 100 occupied.
#[pyclass(module = "slamkit", frozen, get_all)]
pub struct Grid {
    /// The cells, `(height, width)` int8.
    pub data: Py<PyArray2<i8>>,
    /// Cell size \[m\].
    pub resolution: f64,
    /// Map coordinates of the lower-left corner of cell `(0, 0)` \[m\].
    pub origin: (f64, f64),
}

impl Grid {
    /// `grid` as numpy cells.
    pub fn from_tri_grid(py: Python<'_>, grid: &TriGrid) -> PyResult<Self> {
        let (width, height) = (grid.width(), grid.height());
        let cells = grid.cells().iter().map(|c| c.ros_value()).collect();
        let data = Array2::from_shape_vec((height, width), cells)
            .map_err(|e| crate::SlamkitError::new_err(format!("a {width} × {height} grid: {e}")))?;
        let origin = grid.origin_m();
        Ok(Self {
            data: data.into_pyarray(py).unbind(),
            resolution: grid.resolution_m(),
            origin: (origin.x, origin.y),
        })
    }
}

#[pymethods]
impl Grid {
    fn __repr__(&self, py: Python<'_>) -> String {
        let shape = self.data.bind(py).shape().to_vec();
        format!(
            "Grid({} × {} cells of {} m, origin ({}, {}))",
            shape.get(1).copied().unwrap_or(0),
            shape.first().copied().unwrap_or(0),
            self.resolution,
            self.origin.0,
            self.origin.1
        )
    }
}

/// A `.skmap` map file, read and checked (magic, version, checksum) when opened.
#[pyclass(module = "slamkit", frozen)]
pub struct Map {
    path: PathBuf,
    file: MapFile,
}

#[pymethods]
impl Map {
    /// Opens the map file at `path`.
    #[new]
    fn open(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let file = py.detach(|| MapFile::load(&path)).map_err(|e| {
            crate::SlamkitError::new_err(format!("map file {}: {e}", path.display()))
        })?;
        Ok(Self { path, file })
    }

    fn __repr__(&self) -> String {
        format!(
            "Map({}, rig {}, {} keyframes)",
            self.path.display(),
            self.file.header.rig,
            self.file.header.keyframes
        )
    }

    /// The rig that made the map: `"lidar2d"`, `"drone"`, `"rgbd"` or `"stereo"`.
    #[getter]
    fn rig(&self) -> String {
        self.file.header.rig.to_string()
    }

    /// What `slamkit map info --json` prints: version, rig, keyframes, extent, sections, load
    /// time, ...
    fn info(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let info = py.detach(|| MapInfo::read(&self.path)).map_err(to_py_err)?;
        crate::convert::to_python(py, &info)
    }

    /// The grid a robot plans in (2D lidar and drone maps: the keyframe scans' grid; a ground
    /// robot's RGB-D map: its floor grid); None for a camera map without one.
    fn grid(&self, py: Python<'_>) -> PyResult<Option<Grid>> {
        let grid = py
            .detach(|| export::planning_grid(&self.file, &self.path))
            .map_err(to_py_err)?;
        grid.map(|g| Grid::from_tri_grid(py, &g)).transpose()
    }

    /// Writes the map into the existing folder `out` as `slamkit map export` does; returns the
    /// names of the files written.
    fn export(&self, py: Python<'_>, out: PathBuf) -> PyResult<Vec<String>> {
        let exported = py
            .detach(|| export::export(&self.file, &self.path, &out))
            .map_err(to_py_err)?;
        Ok(exported.files.iter().map(|f| f.to_string()).collect())
    }
}
