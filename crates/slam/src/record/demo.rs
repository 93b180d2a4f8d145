//! `slamkit demo --record`: the demo's flight and camera in one MCAP file, in time order.
//!
//! The demo computes its parts one after another over the same simulated time span (the
//! drone's session over the whole flight, then visual odometry over its first part), so the
//! recording is written once both are done, merging the two by time: every scan with the
//! pose each method gave it (`/scan`, `/pose` and `map → base_link` on `/tf` from layered
//! ICP-SLAM, `/pose_pf` from the particle filter, `/groundtruth`), the map of every layer as it
//! grows (`/map`, [`MAP_SNAPSHOTS`] times and at the end, built from the scans so far at their
//! final poses), the camera's images (`/camera/image`) with the visual odometry's poses
//! (`/camera/pose`, anchored at the camera's true start pose as `trajectory_vo.tum` is),
//! and at the end the paths and the merged point map of the layers (`/cloud`).

use super::{Recorder, IMAGE_TOPIC, MAP_SNAPSHOTS};
use crate::drone::simulated::SimulatedFlight;
use crate::visual::simulated::SimulatedVo;
use crate::SlamError;
use slamkit_core::{PointCloud, Pose3, Trajectory};
use slamkit_map::{OccupancyGridConfig, TriGrid};
use slamkit_sim::LidarRun;
use std::collections::BTreeMap;
use std::path::Path;

/// Writes the demo's recording to `path`: the flight `run` as `flight` estimated it, and the
/// camera's run `vo` (its `images` kept); returns the messages written per topic.
///
/// # Errors
/// [`SlamError::Recording`] when the file cannot be written, or a map snapshot not built.
pub fn record_demo(
    path: &Path,
    run: &LidarRun,
    flight: &SimulatedFlight,
    vo: &SimulatedVo,
) -> Result<BTreeMap<String, u64>, SlamError> {
    let mut recorder = Recorder::create(path)?;
    let scans = &run.scans;
    let every = scans.len().div_ceil(MAP_SNAPSHOTS).max(1);
    let vo_poses = poses_by_time(&vo.trajectory);
    let mut images = vo.images.iter().peekable();
    let mut path = Vec::with_capacity(scans.len());
    for (i, scan) in scans.iter().enumerate() {
        let t = scan.timestamp;
        while let Some((ti, jpeg)) = images.next_if(|(ti, _)| *ti <= t) {
            camera_frame(&mut recorder, *ti, jpeg, &vo_poses)?;
        }
        recorder.scan("/scan", "base_link", scan)?;
        if let Some(truth) = run.ground_truth.poses.get(i) {
            recorder.pose("/groundtruth", "map", t, &truth.pose)?;
        }
        if let Some(icp) = flight.icp.estimate.poses.get(i) {
            recorder.pose("/pose", "map", t, &icp.pose)?;
            recorder.transform(t, "map", "base_link", &icp.pose)?;
            path.push(icp.pose);
        }
        if let Some(pf) = flight.pf.estimate.poses.get(i) {
            recorder.pose("/pose_pf", "map", t, &pf.pose)?;
        }
        if (i + 1) % every == 0 || i + 1 == scans.len() {
            let grids = flight.session.layer_grids(
                &scans[..=i],
                &flight.sim_from_slam,
                &OccupancyGridConfig::default(),
            )?;
            recorder.grid("/map", "map", t, &TriGrid::from_occupancy_grid(&grids.all))?;
            recorder.poses("/path", "map", t, &path)?;
        }
    }
    for (t, jpeg) in images {
        camera_frame(&mut recorder, *t, jpeg, &vo_poses)?;
    }
    let end = scans.last().map_or(0.0, |s| s.timestamp);
    let pf_path: Vec<Pose3> = flight.pf.estimate.poses.iter().map(|p| p.pose).collect();
    recorder.poses("/path_pf", "map", end, &pf_path)?;
    let cloud = PointCloud {
        points: flight
            .session
            .merged_cloud()
            .iter()
            .map(|p| flight.sim_from_slam * p)
            .collect(),
        colors: None,
    };
    recorder.point_cloud("/cloud", "map", end, &cloud)?;
    recorder.finish()
}

/// A camera frame: its image and, when visual odometry tracked it, its pose.
fn camera_frame(
    recorder: &mut Recorder,
    t: f64,
    jpeg: &[u8],
    vo_poses: &BTreeMap<u64, Pose3>,
) -> Result<(), SlamError> {
    recorder.compressed_image(IMAGE_TOPIC, "camera", t, "jpeg", jpeg)?;
    match vo_poses.get(&t.to_bits()) {
        Some(pose) => recorder.pose("/camera/pose", "map", t, pose),
        None => Ok(()),
    }
}

/// The poses of `trajectory` by the bits of their timestamp (frames and poses carry the same
/// time, read from the same folder).
fn poses_by_time(trajectory: &Trajectory) -> BTreeMap<u64, Pose3> {
    trajectory
        .poses
        .iter()
        .map(|p| (p.timestamp.to_bits(), p.pose))
        .collect()
}
