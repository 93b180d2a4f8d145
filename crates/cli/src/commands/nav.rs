//! `slamkit nav`: the closed loop in the simulator.

use crate::output::not_yet;
use std::path::PathBuf;

/// Arguments of `slamkit nav`.
#[derive(Debug, clap::Args)]
pub struct NavArgs {
    /// World: `small`, `large`, `office`, or a TOML world file.
    #[arg(long)]
    pub world: String,
    /// Goal `X,Y` (m); the world's built-in goal when omitted.
    #[arg(long, allow_hyphen_values = true)]
    pub goal: Option<String>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output folder.
    #[arg(long, default_value = "out/nav")]
    pub out: PathBuf,
}

/// Runs `slamkit nav`.
pub fn run(_args: &NavArgs) -> anyhow::Result<()> {
    not_yet("nav", "closed-loop navigation, issue #6")
}
