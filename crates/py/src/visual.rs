//! Cameras: `Dataset` opens an RGB-D or stereo folder (TUM, KITTI, 7-Scenes, Redwood, EuRoC)
//! and a `VisualSlam` session runs over it as `slamkit vo` does (visual odometry, with
//! `slam=True` keyframes, place recognition and loop closure).

use crate::convert::{one_of, to_python, trajectory_to_array};
use crate::{to_py_err, SlamkitError};
use numpy::PyArray2;
use pyo3::prelude::*;
use slamkit_io::bag::RgbdTopics;
use slamkit_io::{Dataset as IoDataset, DatasetFormat};
use slamkit_slam::visual::{self, PointMapping, RunOptions, VisualRun};
use slamkit_slam::{Session, VisualSlam as Session_};
use slamkit_vo::FrontendKind;
use std::path::PathBuf;

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Dataset>()?;
    m.add_class::<VisualSlam>()?;
    Ok(())
}

/// A dataset folder, or a ROS 1 / ROS 2 bag of an RGB-D camera: `format` one of `"tum"`,
/// `"kitti"`, `"7scenes"`, `"redwood"`, `"euroc"`, `"rosbag"`, or None to tell it from the
/// path. In a bag the colour, depth and `CameraInfo` topics are found by type and encoding
/// when there is one of each (`rgb_topic`, `depth_topic`, `camera_info_topic` choose).
#[pyclass(module = "slamkit", frozen)]
pub struct Dataset {
    dir: PathBuf,
    format: DatasetFormat,
    dataset: IoDataset,
}

#[pymethods]
impl Dataset {
    #[new]
    #[pyo3(signature = (path, format = None, rgb_topic = None, depth_topic = None, camera_info_topic = None))]
    fn open(
        py: Python<'_>,
        path: PathBuf,
        format: Option<&str>,
        rgb_topic: Option<String>,
        depth_topic: Option<String>,
        camera_info_topic: Option<String>,
    ) -> PyResult<Self> {
        let format = match format {
            Some(name) => name.parse().map_err(to_py_err)?,
            None => slamkit_io::layout::detect_layout(&path)
                .map_err(to_py_err)?
                .ok_or_else(|| {
                    SlamkitError::new_err(format!(
                        "cannot tell the layout of {}: pass format",
                        path.display()
                    ))
                })?,
        };
        let topics = RgbdTopics {
            rgb: rgb_topic,
            depth: depth_topic,
            camera_info: camera_info_topic,
        };
        if format != DatasetFormat::RosBag && topics != RgbdTopics::default() {
            return Err(SlamkitError::new_err(format!(
                "the topic options apply to bags; {} is not one",
                path.display()
            )));
        }
        let dataset = py
            .detach(|| match format {
                DatasetFormat::RosBag => IoDataset::open_bag(&path, &topics),
                _ => IoDataset::open(&path, format),
            })
            .map_err(|e| SlamkitError::new_err(format!("opening {}: {e}", path.display())))?;
        Ok(Self {
            dir: path,
            format,
            dataset,
        })
    }

    fn __len__(&self) -> usize {
        self.dataset.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Dataset({}, {:?}, {} frames)",
            self.dir.display(),
            self.format,
            self.dataset.len()
        )
    }

    /// The ground truth as an `(N, 8)` TUM array, or None when the folder has none.
    fn ground_truth<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.dataset
            .ground_truth()
            .map(|gt| trajectory_to_array(py, gt))
    }
}

/// A camera session (`slamkit vo`'s) for `dataset`'s camera rig: `frontend` `"klt"` or
/// `"orb"`, settings from a named `profile` (by default the camera of the dataset's layout)
/// and a TOML `config` file; `slam=True` adds keyframes, place recognition and loop closure.
#[pyclass(module = "slamkit")]
pub struct VisualSlam {
    session: Session_,
    run: Option<VisualRun>,
}

#[pymethods]
impl VisualSlam {
    #[new]
    #[pyo3(signature = (dataset, frontend = "klt", profile = None, config = None, slam = false))]
    fn new(
        dataset: &Dataset,
        frontend: &str,
        profile: Option<&str>,
        config: Option<PathBuf>,
        slam: bool,
    ) -> PyResult<Self> {
        let frontends = [("klt", FrontendKind::Klt), ("orb", FrontendKind::Orb)];
        let frontend = one_of("frontend", frontend, &frontends)?;
        let settings =
            visual::session_settings(frontend, dataset.format, profile, config.as_deref(), slam)
                .map_err(to_py_err)?;
        let session = Session_::new(&settings, visual::rig_of(&dataset.dataset))
            .and_then(|s| s.with_point_map(PointMapping::Off))
            .map_err(to_py_err)?;
        Ok(Self { session, run: None })
    }

    /// Runs the session over every frame of `dataset`, the GIL released (decoding overlaps
    /// tracking as in `slamkit vo`); returns the frame counts as a dict. A frame that cannot be
    /// read is counted and skipped.
    fn run(&mut self, py: Python<'_>, dataset: &Dataset) -> PyResult<Py<PyAny>> {
        let session = &mut self.session;
        let run = py
            .detach(|| {
                visual::run(
                    session,
                    dataset.dataset.observations(),
                    RunOptions::default(),
                    |_| {},
                )
            })
            .map_err(to_py_err)?;
        let counts = serde_json::json!({
            "run": run.stats,
            "session": self.session.stats(),
            "skipped": run.skipped,
        });
        self.run = Some(run);
        to_python(py, &counts)
    }

    /// The poses of the last `run`, an `(N, 8)` TUM array of the rig's reference camera
    /// (`world_from_camera`, the first frame at the identity); frames that failed have none.
    fn trajectory<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let run = self
            .run
            .as_ref()
            .ok_or_else(|| SlamkitError::new_err("no run yet: call run(dataset) first"))?;
        Ok(trajectory_to_array(py, &run.trajectory))
    }

    /// Writes the map (keyframes, their 3D points and descriptors) as a `.skmap` file.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| Session::save(&self.session, &path))
            .map_err(to_py_err)
    }
}
