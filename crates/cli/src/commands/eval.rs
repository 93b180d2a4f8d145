//! `slamkit eval`: accuracy of a trajectory file against ground truth — ATE, RPE (as evo's
//! `evo_ape` / `evo_rpe`, to rounding) and the relations metric of the 2D lidar benchmarks.
//!
//! Trajectory files may be TUM, KITTI or EuRoC CSV (told from their content); when either file
//! is KITTI, poses pair by index, otherwise by nearest timestamp within `--max-diff`.

use anyhow::Context;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use indicatif::ProgressBar;
use slamkit_core::Trajectory;
use slamkit_eval::plot::{plot_errors, ErrorSeries, TopView};
use slamkit_eval::{
    ate, relations_error, rpe, Alignment, AteResult, DeltaUnit, ErrorStats, GroundTruthRelation,
    Pairing, RpeConfig, DEFAULT_MAX_DIFF_S,
};
use slamkit_io::{read_trajectory, TrajectoryFormat};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Arguments of `slamkit eval`.
#[derive(Debug, clap::Args)]
pub struct EvalArgs {
    /// The metric to compute.
    #[command(subcommand)]
    pub metric: EvalMetric,
}

/// The metrics of `slamkit eval`.
#[derive(Debug, clap::Subcommand)]
pub enum EvalMetric {
    /// Absolute trajectory error after alignment (evo_ape, translation part).
    Ate(AteArgs),
    /// Relative pose error over a delta in frames or metres (evo_rpe, translation part).
    Rpe(RpeArgs),
    /// Relations metric (Kümmerle et al. 2009) against a `.relations` file.
    Relations(RelationsArgs),
}

/// Input trajectories and output options shared by `ate` and `rpe`.
#[derive(Debug, clap::Args)]
pub struct PairArgs {
    /// Ground-truth trajectory (TUM, KITTI or EuRoC CSV).
    #[arg(long)]
    pub gt: PathBuf,
    /// Estimated trajectory (TUM, KITTI or EuRoC CSV).
    #[arg(long)]
    pub est: PathBuf,
    /// Largest time difference for pairing poses by timestamp in seconds (evo's --t_max_diff).
    #[arg(long, default_value_t = DEFAULT_MAX_DIFF_S, allow_negative_numbers = true)]
    pub max_diff: f64,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Write a figure (top view and error over time) to this .png or .svg file.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// Arguments of `slamkit eval ate`.
#[derive(Debug, clap::Args)]
pub struct AteArgs {
    #[command(flatten)]
    pub input: PairArgs,
    /// Alignment of the estimate onto the ground truth (evo: se3 = -a, sim3 = -as).
    #[arg(long, default_value = "se3", value_parser = alignment_parser())]
    pub align: Alignment,
}

/// Arguments of `slamkit eval rpe`.
#[derive(Debug, clap::Args)]
pub struct RpeArgs {
    #[command(flatten)]
    pub input: PairArgs,
    /// Distance between the poses of a pair, in --unit (frames: a whole number, 1 or more).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub delta: f64,
    /// Unit of --delta: associated frames or metres of travelled path.
    #[arg(long, default_value = "frames", value_parser = unit_parser())]
    pub unit: DeltaUnit,
    /// Pair every pose with the one --delta later (evo's --all_pairs), not only consecutive blocks.
    #[arg(long)]
    pub all_pairs: bool,
}

/// Arguments of `slamkit eval relations`.
#[derive(Debug, clap::Args)]
pub struct RelationsArgs {
    /// Ground-truth relations file (`t1 t2 x y z roll pitch yaw` per line).
    #[arg(long)]
    pub relations: PathBuf,
    /// Estimated trajectory (TUM, KITTI or EuRoC CSV).
    #[arg(long)]
    pub est: PathBuf,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

fn alignment_parser() -> impl TypedValueParser<Value = Alignment> {
    PossibleValuesParser::new(["se3", "sim3", "none"]).try_map(|s| s.parse::<Alignment>())
}

fn unit_parser() -> impl TypedValueParser<Value = DeltaUnit> {
    PossibleValuesParser::new(["frames", "m"]).map(|s| match s.as_str() {
        "m" => DeltaUnit::Metres,
        _ => DeltaUnit::Frames,
    })
}

/// Runs `slamkit eval`.
pub fn run(args: &EvalArgs) -> anyhow::Result<()> {
    match &args.metric {
        EvalMetric::Ate(a) => run_ate(a),
        EvalMetric::Rpe(a) => run_rpe(a),
        EvalMetric::Relations(a) => run_relations(a),
    }
}

fn run_ate(args: &AteArgs) -> anyhow::Result<()> {
    let stage = stage_spinner();
    let (gt, est, pairing) = load_pair(&args.input, &stage)?;
    stage.set_message(format!("ATE: pairing and aligning {} poses", est.len()));
    let result = ate(&gt, &est, pairing, args.align).context("computing ATE")?;
    stage.finish_and_clear();
    let title = format!("ATE ({} alignment)", args.align);
    let series = ErrorSeries {
        title: &title,
        label: "ATE (m)",
        timestamps: &result.timestamps,
        errors: &result.errors_m,
    };
    plot_and_print(&args.input, Some(&result), &series, &result.stats)
}

fn run_rpe(args: &RpeArgs) -> anyhow::Result<()> {
    let stage = stage_spinner();
    let (gt, est, pairing) = load_pair(&args.input, &stage)?;
    stage.set_message(format!(
        "RPE: pairing {} poses{}",
        est.len(),
        if args.all_pairs { ", all pairs" } else { "" }
    ));
    let config = RpeConfig {
        delta: args.delta,
        unit: args.unit,
        all_pairs: args.all_pairs,
        ..RpeConfig::default()
    };
    let result = rpe(&gt, &est, pairing, &config).context("computing RPE")?;
    stage.finish_and_clear();
    let title = format!(
        "RPE (delta {} {}{})",
        args.delta,
        args.unit,
        if args.all_pairs { ", all pairs" } else { "" }
    );
    // The top view shows the estimate rigidly aligned; RPE itself needs no alignment, so the
    // alignment is computed only for a plot.
    let aligned = args
        .input
        .plot
        .as_ref()
        .map(|_| {
            ate(&gt, &est, pairing, Alignment::Se3)
                .or_else(|_| ate(&gt, &est, pairing, Alignment::None))
                .context("aligning the estimate for the plot")
        })
        .transpose()?;
    let series = ErrorSeries {
        title: &title,
        label: "RPE (m)",
        timestamps: &result.timestamps,
        errors: &result.errors_m,
    };
    plot_and_print(&args.input, aligned.as_ref(), &series, &result.stats)
}

/// The output `ate` and `rpe` share: with `--plot`, the `aligned` trajectories seen from above
/// beside the error series; then the statistics (a table, or JSON with `--json`).
fn plot_and_print(
    input: &PairArgs,
    aligned: Option<&AteResult>,
    series: &ErrorSeries,
    stats: &ErrorStats,
) -> anyhow::Result<()> {
    if let (Some(path), Some(aligned)) = (&input.plot, aligned) {
        let view = TopView {
            reference: &aligned.reference_positions,
            estimate: &aligned.aligned_estimate_positions,
        };
        plot_errors(path, &view, series)?;
    }
    print_stats(series.title, stats, input.json)
}

fn run_relations(args: &RelationsArgs) -> anyhow::Result<()> {
    let relations = load_relations(&args.relations)?;
    let (est, _) = read(&args.est)?;
    let stats = relations_error(&relations, &est).with_context(|| {
        format!(
            "scoring {} on {}",
            args.est.display(),
            args.relations.display()
        )
    })?;
    if args.json {
        println!("{}", serde_json::to_string(&stats)?);
    } else {
        print!("{stats}");
    }
    Ok(())
}

/// Reads a `.relations` file.
pub fn load_relations(path: &Path) -> anyhow::Result<Vec<GroundTruthRelation>> {
    // The reader's error names the file; the context says only what was being read.
    slamkit_io::relations::read_relations(path).context("reading relations")
}

fn read(path: &Path) -> anyhow::Result<(Trajectory, TrajectoryFormat)> {
    // The reader's error names the file; the context says only what was being read.
    read_trajectory(path).context("reading trajectory")
}

/// A spinner on stderr naming the stage under way, so that an evaluation of millions of poses
/// (two million: about 6 s, mostly reading) is seen working; hidden when stderr is not a
/// terminal.
fn stage_spinner() -> ProgressBar {
    let spinner = ProgressBar::new_spinner();
    spinner.enable_steady_tick(Duration::from_millis(200));
    spinner
}

/// Reads ground truth and estimate and chooses how to pair them.
fn load_pair(
    args: &PairArgs,
    stage: &ProgressBar,
) -> anyhow::Result<(Trajectory, Trajectory, Pairing)> {
    if !(args.max_diff.is_finite() && args.max_diff >= 0.0) {
        anyhow::bail!(
            "--max-diff must be a non-negative number of seconds, got {}",
            args.max_diff
        );
    }
    stage.set_message(format!("reading {}", args.gt.display()));
    let (gt, gt_format) = read(&args.gt)?;
    stage.set_message(format!("reading {}", args.est.display()));
    let (est, est_format) = read(&args.est)?;
    Ok((
        gt,
        est,
        Pairing::for_formats(gt_format, est_format, args.max_diff),
    ))
}

fn print_stats(title: &str, stats: &ErrorStats, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string(stats)?);
    } else {
        print!("{title}, {} pairs\n{stats}", stats.pairs);
    }
    Ok(())
}
