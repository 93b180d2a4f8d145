//! A merge written as files, the same for `slamkit map merge` (offline) and a fleet's merger
//! (online): the merged map file, its exports, each input's trajectory in the merged frame.

use super::MergeOutcome;
use crate::lidar::LidarMap;
use crate::map_file::export::export;
use crate::map_file::{MapFile, MapFileError};
use crate::SlamError;
use std::path::Path;

/// The files of a merge's output folder whatever the inputs: those [`write_merge`] writes
/// (besides one `trajectory_<name>.tum` per merged input) and `report.json`, which the caller
/// writes with the report it returns.
pub const MERGE_FILES: &[&str] = &[
    "map.skmap",
    "map.pgm",
    "map.yaml",
    "map.png",
    "cloud.ply",
    "trajectory.tum",
    "report.json",
    "report.html",
];

/// The merged map of `outcome` as a map file, its header's notes `method` and the inputs'
/// `names`: what [`write_merge`] saves as `map.skmap`, and what a fleet's merger sends to its
/// robots.
///
/// # Errors
/// [`MapFileError`] when the map cannot be encoded.
pub fn merged_map_file(
    outcome: &MergeOutcome,
    names: &[String],
    method: &str,
) -> Result<MapFile, MapFileError> {
    let notes = serde_json::json!({ "method": method, "inputs": names });
    outcome.map.to_new_file(notes)
}

/// Writes the merged map of `outcome` into the folder `dir` (which must exist): `map.skmap`
/// ([`merged_map_file`]), its exports (grid, cloud, keyframe trajectory; [`export`]) and
/// `trajectory_<name>.tum` for each merged input, every scan of its runs in the merged frame.
/// Returns the merge's report ([`MergeOutcome::report`]) with each closure's keyframe times
/// taken from `maps`, the merge's inputs.
///
/// # Errors
/// [`SlamError::MapFile`] when the map file cannot be written, and the exporters' and
/// trajectory writer's errors.
pub fn write_merge(
    outcome: &MergeOutcome,
    maps: &[LidarMap],
    names: &[String],
    method: &str,
    dir: &Path,
) -> Result<serde_json::Value, SlamError> {
    let file = merged_map_file(outcome, names, method).map_err(|source| SlamError::MapFile {
        path: dir.join("map.skmap"),
        source,
    })?;
    write_merge_file(&file, outcome, maps, names, dir)
}

/// [`write_merge`] with the merged map file already made (`file`, [`merged_map_file`] of
/// `outcome`), saved as it is: a fleet's merger writes the very bytes it sent its robots.
///
/// # Errors
/// As [`write_merge`].
pub fn write_merge_file(
    file: &MapFile,
    outcome: &MergeOutcome,
    maps: &[LidarMap],
    names: &[String],
    dir: &Path,
) -> Result<serde_json::Value, SlamError> {
    let path = dir.join("map.skmap");
    file.save(&path).map_err(|source| SlamError::MapFile {
        path: path.clone(),
        source,
    })?;
    export(file, &path, dir)?;
    for (name, input) in names.iter().zip(&outcome.inputs) {
        if let Some(trajectory) = &input.trajectory {
            let path = dir.join(format!("trajectory_{name}.tum"));
            slamkit_io::trajectory_file::write_tum(&path, trajectory)?;
        }
    }
    let keyframe_times: Vec<Vec<f64>> = maps
        .iter()
        .map(|m| m.keyframes.iter().map(|k| k.scan.timestamp).collect())
        .collect();
    Ok(outcome.report(names, &keyframe_times))
}
