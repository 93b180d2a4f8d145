//! `slamkit lidar`: placeholder until ICP-SLAM lands.

use crate::output::not_yet;

/// Arguments of `slamkit lidar`.
#[derive(Debug, clap::Args)]
pub struct LidarArgs {}

/// Runs `slamkit lidar`.
pub fn run(_args: &LidarArgs) -> anyhow::Result<()> {
    not_yet("lidar", "lidar SLAM, issue #3")
}
