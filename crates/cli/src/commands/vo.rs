//! `slamkit vo`: visual odometry on an RGB-D or stereo dataset folder.

use crate::output::not_yet;
use std::path::PathBuf;

/// Dataset folder layouts `slamkit vo` reads.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum DatasetFormat {
    /// TUM RGB-D: rgb.txt, depth.txt, groundtruth.txt.
    Tum,
    /// KITTI odometry stereo: image_0/, image_1/, calib.txt, poses.txt.
    Kitti,
    /// Microsoft 7-Scenes: frame-NNNNNN.color/depth/pose.
    #[value(name = "7scenes")]
    SevenScenes,
    /// Open3D / Redwood RGB-D: color/, depth/, trajectory.log.
    Redwood,
    /// EuRoC MAV: cam0/, cam1/.
    Euroc,
}

/// Feature front ends.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Frontend {
    /// Shi–Tomasi corners tracked with pyramidal KLT.
    Klt,
    /// ORB features matched by Hamming distance.
    Orb,
}

/// Arguments of `slamkit vo`.
#[derive(Debug, clap::Args)]
pub struct VoArgs {
    /// Dataset folder.
    pub dataset_dir: PathBuf,
    /// Folder layout; told from the folder's content when omitted.
    #[arg(long)]
    pub format: Option<DatasetFormat>,
    /// Feature front end.
    #[arg(long, value_enum, default_value = "klt")]
    pub frontend: Frontend,
    /// TOML file with configuration overrides.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Play the dataset at its frame rate and drop the frames the pipeline cannot take.
    #[arg(long)]
    pub realtime: bool,
    /// Output folder.
    #[arg(long, default_value = "out/vo")]
    pub out: PathBuf,
}

/// Runs `slamkit vo`.
pub fn run(_args: &VoArgs) -> anyhow::Result<()> {
    not_yet("vo", "visual odometry, issue #4")
}
