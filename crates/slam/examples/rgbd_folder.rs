//! Visual odometry on a 7-Scenes folder through the session API alone: the dataset reader
//! gives observations, a [`VisualSlam`] session turns each into a pose, and the trajectory is
//! written in TUM format (`t tx ty tz qx qy qz qw`).
//!
//! ```text
//! cargo run --release -p slamkit-slam --example rgbd_folder -- \
//!     $SLAMKIT_DATA/rgbd/7scenes_redkitchen_frames_0000-0599 [trajectory.tum]
//! ```
//!
//! 7-Scenes' depth camera is not registered to its colour camera, so the session is told to
//! register depth (`register_depth`, a Kinect v1's calibration); the poses are the depth
//! camera's, the first at the identity.

use slamkit_core::Trajectory;
use slamkit_io::{write_tum, Dataset, DatasetFormat};
use slamkit_slam::profile::Profile;
use slamkit_slam::visual::{self, PointMapping};
use slamkit_slam::{TrackingStatus, VisualSlam};
use slamkit_vo::VoConfig;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args_os().skip(1);
    let folder = PathBuf::from(args.next().ok_or("usage: rgbd_folder FOLDER [OUT.tum]")?);
    let out = args.next().map(PathBuf::from);

    let dataset = Dataset::open(&folder, DatasetFormat::SevenScenes)?;
    // 7-Scenes: a Kinect v1 whose colour is not registered to depth
    let config = Profile::builtin("kinect-v1")?.apply("vo", VoConfig::default())?;
    let mut session =
        VisualSlam::new(&config, visual::rig_of(&dataset))?.with_point_map(PointMapping::Off)?;

    let mut trajectory = Trajectory::new();
    let mut lost = 0;
    for observation in dataset.observations() {
        let observation = match observation {
            Ok(o) => o,
            Err(e) => {
                eprintln!("skipped: {e}");
                continue;
            }
        };
        let Some(update) = session.push(observation) else {
            continue;
        };
        if update.status != TrackingStatus::Tracking {
            lost += 1;
        }
        if let Some(pose) = update.pose {
            trajectory.push(update.timestamp, pose);
        }
    }

    let stats = session.stats();
    eprintln!(
        "{} frames, {} tracked, {} not tracked",
        stats.frames, stats.processed, lost
    );
    match out {
        Some(path) => write_tum(&path, &trajectory)?,
        None => {
            for p in &trajectory.poses {
                let t = p.pose.translation.vector;
                println!("{:.6} {:.4} {:.4} {:.4}", p.timestamp, t.x, t.y, t.z);
            }
        }
    }
    Ok(())
}
