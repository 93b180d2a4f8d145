//! `slamkit eval`: placeholder until the evaluation module lands.

use crate::output::not_yet;

/// Arguments of `slamkit eval`.
#[derive(Debug, clap::Args)]
pub struct EvalArgs {}

/// Runs `slamkit eval`.
pub fn run(_args: &EvalArgs) -> anyhow::Result<()> {
    not_yet("eval", "evaluation, issue #2")
}
