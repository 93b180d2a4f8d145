//! `slamkit sim`: simulated sensors in a world, written in real dataset formats.

use crate::output::not_yet;
use std::path::PathBuf;

/// Arguments of `slamkit sim`.
#[derive(Debug, clap::Args)]
pub struct SimArgs {
    /// World: `small`, `large`, `office`, or a TOML world file.
    #[arg(long)]
    pub world: String,
    /// Sensors to simulate, comma separated: lidar2d, range, rgbd, stereo.
    #[arg(long, value_delimiter = ',', default_value = "lidar2d")]
    pub sensors: Vec<String>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `slamkit sim`.
pub fn run(_args: &SimArgs) -> anyhow::Result<()> {
    not_yet("sim", "simulator, issue #5")
}
