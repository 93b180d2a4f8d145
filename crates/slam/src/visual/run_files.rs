//! What a [`VisualSlam`] run over a dataset leaves (`slamkit vo`): the trajectory in the
//! dataset's own format as well as TUM, the ground truth beside it, the point map as PLY, and
//! the report's fields about frames, map, timings, accuracy and loop closures, scored against
//! the dataset's ground truth when it has one (the session itself never reads it).

use super::planning_map::{self, PlanningMapConfig};
use super::{check_closures, LoopClosure, LoopStats, VisualOutput, VisualRun, VisualSlam};
use crate::report::merge_json;
use crate::SlamError;
use serde_json::{json, Value};
use slamkit_core::{Pose3, Trajectory};
use slamkit_io::{Dataset, DatasetFormat};
use slamkit_vo::frame::Rig;
use slamkit_vo::{evaluate, VoMetrics};
use std::path::Path;
use std::time::Instant;

/// A finished run over a dataset, as `slamkit vo` writes it.
pub struct DatasetRun {
    /// The frames' trajectory and statuses ([`super::run`]).
    pub run: VisualRun,
    /// The session's point map, timings and counters ([`VisualSlam::finish`]).
    pub output: VisualOutput,
    /// Loop closure's counters and closures, when it was on.
    pub loops: Option<(LoopStats, Vec<LoopClosure>)>,
    /// Keyframes in the session's map at the end.
    pub keyframes: usize,
    /// Each keyframe's timestamp and final `world_from_camera` (with loop closure on, where
    /// the last correction left it): what the planning maps are built from.
    pub keyframe_poses: Vec<(f64, Pose3)>,
    /// The rig, for the planning maps.
    pub rig: Rig,
}

impl DatasetRun {
    /// Ends `session` after [`super::run`] gave `run`.
    pub fn finish(session: VisualSlam, run: VisualRun) -> Result<Self, SlamError> {
        let map = session.map();
        let keyframe_poses = map
            .keyframes
            .iter()
            .map(|k| (k.timestamp, k.pose))
            .collect();
        let loops = session.loop_closures();
        let rig = session.rig().clone();
        let output = session.finish()?;
        Ok(Self {
            run,
            output,
            loops,
            keyframes: map.keyframes.len(),
            keyframe_poses,
            rig,
        })
    }

    /// Writes `trajectory.tum` (and `trajectory.kitti` for a KITTI dataset), `groundtruth.tum`
    /// when `dataset` has ground truth, `cloud.ply` (the point map) and the maps to plan in
    /// built from the keyframes ([`planning_map::write_planning_maps`] with `planning`:
    /// `octree.bt` and `floor.pgm/.yaml/.png` for RGB-D) into `out`;
    /// returns the report's `frames`, `map`, `planning_map`, `timings_ms`, `metrics`,
    /// `loop_closure` and `frame_status` fields, and the accuracy against the ground truth.
    pub fn write(
        &self,
        out: &Path,
        dataset: &Dataset,
        format: DatasetFormat,
        planning: &PlanningMapConfig,
    ) -> Result<(Value, Option<VoMetrics>), SlamError> {
        if format == DatasetFormat::Kitti {
            let trajectory = &self.run.trajectory;
            slamkit_io::trajectory_file::write_kitti(&out.join("trajectory.kitti"), trajectory)?;
        }
        if dataset.ground_truth().is_some() {
            dataset.write_ground_truth_tum(&out.join("groundtruth.tum"))?;
        }
        let started = Instant::now();
        let planning_map = planning_map::write_planning_maps(
            dataset,
            &self.keyframe_poses,
            &self.rig,
            planning,
            out,
        )?;
        let planning_ms = started.elapsed().as_secs_f64() * 1e3;
        let (mut report, metrics) = self.write_files(out, dataset.ground_truth())?;
        report["planning_map"] = planning_map;
        report["planning_map"]["build_ms"] = json!(planning_ms);
        Ok((report, metrics))
    }

    /// Writes `trajectory.tum` and `cloud.ply` into `out` (a run of any source: a dataset, a
    /// live camera); returns the report's fields as [`Self::write`] does, scored against
    /// `ground_truth` when there is one.
    pub fn write_files(
        &self,
        out: &Path,
        ground_truth: Option<&Trajectory>,
    ) -> Result<(Value, Option<VoMetrics>), SlamError> {
        let trajectory = &self.run.trajectory;
        slamkit_io::trajectory_file::write_tum(&out.join("trajectory.tum"), trajectory)?;
        // A run that cannot be scored (a camera driven in a straight line leaves the SE(3)
        // alignment undetermined, as evo's Umeyama refuses it too) keeps its outputs; the
        // report says why there is no score.
        let (metrics, metrics_error) = match ground_truth.map(|gt| evaluate(trajectory, gt)) {
            Some(Ok(m)) => (Some(m), None),
            Some(Err(e)) => (None, Some(slamkit_core::error::error_chain(&e))),
            None => (None, None),
        };
        let loop_closure = self.loops.as_ref().map(|(stats, closures)| {
            let check = ground_truth.map(|gt| check_closures(closures, gt));
            json!({ "stats": stats, "closures": closures, "against_ground_truth": check })
        });
        let map = self.output.point_map.as_ref();
        let map = map.ok_or_else(|| SlamError::Config("the session kept no point map".into()))?;
        map.write_ply(&out.join("cloud.ply"))?;
        let mut frames = json!(self.output.stats);
        merge_json(&mut frames, json!(self.run.stats));
        let mut timings = self.run.timings.clone();
        timings.merge(&self.output.timings);
        let report = json!({
            "frames": frames,
            "map": {
                "points": map.len(),
                "dropped_points": map.dropped(),
                "keyframes": self.keyframes,
            },
            "timings_ms": timings.summary(),
            "metrics": metrics,
            "metrics_error": metrics_error,
            "loop_closure": loop_closure,
            "frame_status": self.run.frames,
        });
        Ok((report, metrics))
    }
}

/// The lines a person reads at the end of a visual run, from its `report`: frame counts, why
/// the run was not scored when a ground truth could not score it, and, when timed, the
/// per-frame time.
///
/// ```
/// let report = serde_json::json!({
///     "frames": { "frames": 3, "processed": 3, "failed": 0, "dropped": 0, "skipped": 0 },
///     "timings_ms": { "frame": { "median_ms": 9.54, "p95_ms": 12.0 } },
/// });
/// assert_eq!(
///     slamkit_slam::visual::run_files::summary(&report),
///     "vo: 3 frames, 3 processed, 0 failed, 0 dropped, 0 skipped\n\
///      per-frame time: median 9.5 ms, p95 12.0 ms"
/// );
/// // a run the ground truth could not score says why
/// let report = serde_json::json!({
///     "frames": { "frames": 3, "processed": 3, "failed": 0, "dropped": 0, "skipped": 0 },
///     "metrics_error": "aligning the estimate onto the reference: destination points are \
///                       degenerate (coincident or collinear)",
///     "timings_ms": {},
/// });
/// assert!(slamkit_slam::visual::run_files::summary(&report)
///     .ends_with("not scored against the ground truth: aligning the estimate onto the \
///                 reference: destination points are degenerate (coincident or collinear)"));
/// ```
pub fn summary(report: &Value) -> String {
    let f = &report["frames"];
    let mut text = format!(
        "vo: {} frames, {} processed, {} failed, {} dropped, {} skipped",
        f["frames"], f["processed"], f["failed"], f["dropped"], f["skipped"]
    );
    if let Some(why) = report["metrics_error"].as_str() {
        text += &format!("\nnot scored against the ground truth: {why}");
    }
    if let Some(t) = report["timings_ms"].get("frame") {
        let ms = |key: &str| t[key].as_f64().unwrap_or(f64::NAN);
        text += &format!(
            "\nper-frame time: median {:.1} ms, p95 {:.1} ms",
            ms("median_ms"),
            ms("p95_ms")
        );
    }
    text
}
