//! 2D lidar SLAM on a CARMEN log through the session API alone: read the log, push every scan
//! into a `LidarSlam` session as an `Observation`, print how tracking went, save the map and
//! write the trajectory.
//!
//! ```sh
//! cargo run --release -p slamkit-slam --example lidar_log -- \
//!     $SLAMKIT_DATA/lidar2d/intel/intel.fromrosbag.clf.gz /tmp/intel.skmap /tmp/intel.tum
//! ```
//!
//! Localising in the saved map later is the same loop with `LidarSlam::localise(config,
//! LidarMap::load(path)?.0)`.

use slamkit_core::{Observation, Pose2};
use slamkit_slam::{LidarSlam, LidarSlamConfig, Session, TrackingStatus};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [log, map, trajectory] = args.as_slice() else {
        return Err("usage: lidar_log LOG.clf[.gz] MAP.skmap TRAJECTORY.tum".into());
    };
    let scans = slamkit_io::carmen::read_carmen(log)?.scans;
    let mut session = LidarSlam::new(LidarSlamConfig::default(), Pose2::identity())?;
    let (mut tracking, mut keyframes, mut closures) = (0, 0, 0);
    for scan in scans {
        if let Some(update) = session.push(Observation::Scan(scan)) {
            tracking += usize::from(update.status == TrackingStatus::Tracking);
            keyframes += update.map.keyframes_added;
            closures += update.map.loop_closures;
        }
    }
    session.save(map)?;
    slamkit_io::trajectory_file::write_tum(trajectory, &session.trajectory())?;
    println!(
        "{} scans, {tracking} tracked, {keyframes} keyframes, {closures} loop closures; map in {}",
        session.stats().scans,
        map.display()
    );
    Ok(())
}
