//! `slamkit demo`: the whole system on a simulated robot, with no download.

use crate::output::not_yet;
use std::path::PathBuf;

/// Built-in worlds.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum World {
    /// 5 × 5 m, 1 m high, boxes and cylinders.
    Small,
    /// 10 × 10 m, 2.4 m high, more obstacles and a ramp.
    Large,
    /// 12.9 × 7.7 m, 2.5 m high, furnished.
    Office,
}

/// Arguments of `slamkit demo`.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// Built-in world.
    #[arg(long, value_enum, default_value = "small")]
    pub world: World,
    /// Output folder.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
}

/// Runs `slamkit demo`.
pub fn run(_args: &DemoArgs) -> anyhow::Result<()> {
    not_yet("demo", "simulator demo, issue #5")
}
