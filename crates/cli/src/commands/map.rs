//! `slamkit map info|export|merge`: what a `.skmap` file holds, its contents as files any tool
//! opens, and several robots' 2D lidar maps merged into one.

use anyhow::Context;
use slamkit_io::output_folder::OutputFolder;
use slamkit_slam::lidar::LidarMap;
use slamkit_slam::map_file::info::MapInfo;
use slamkit_slam::map_file::MapFile;
use slamkit_slam::merge::output::{write_merge, MERGE_FILES};
use slamkit_slam::merge::{merge_maps, MergeConfig};
use std::path::{Path, PathBuf};

/// Arguments of `slamkit map`.
#[derive(Debug, clap::Args)]
pub struct MapArgs {
    #[command(subcommand)]
    command: MapCommand,
}

#[derive(Debug, clap::Subcommand)]
enum MapCommand {
    /// Print a map file's version, rig, keyframes, extent and size.
    Info {
        /// The `.skmap` file.
        file: PathBuf,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Write a map file's contents as map.pgm/.yaml/.png (the grid a robot plans in, for 2D
    /// lidar, drone and ground-robot maps), cloud.ply (the map's points) and trajectory.tum (the
    /// scans or keyframes that built it).
    Export {
        /// The `.skmap` file.
        file: PathBuf,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
    },
    /// Merge 2D lidar maps whose relative poses are unknown (several robots, or one robot on
    /// several days) into one: writes map.skmap, its exports (map.pgm/.yaml/.png, cloud.ply,
    /// trajectory.tum), trajectory_NAME.tum per merged input in the merged frame, and
    /// report.json with the closures found, accepted and rejected and the inputs left out.
    Merge {
        /// The `.skmap` files (two or more); each is named by its file stem.
        #[arg(required = true, num_args = 2..)]
        files: Vec<PathBuf>,
        /// TOML file with merge settings laid over the defaults (the fields report.json shows
        /// under `config`, such as `[places] spacing_m = 1.0`).
        #[arg(long)]
        config: Option<PathBuf>,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
    },
}

/// The merge settings: the defaults, with those of the TOML file `path` laid over them.
pub fn merge_config(path: Option<&Path>) -> anyhow::Result<MergeConfig> {
    let Some(path) = path else {
        return Ok(MergeConfig::default());
    };
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let config: MergeConfig =
        toml::from_str(&text).with_context(|| format!("merge settings in {}", path.display()))?;
    config.validate()?;
    Ok(config)
}

/// Runs `slamkit map`.
pub fn run(args: &MapArgs) -> anyhow::Result<()> {
    match &args.command {
        MapCommand::Info { file, json } => info(file, *json),
        MapCommand::Export { file, out } => export(file, out),
        MapCommand::Merge { files, config, out } => merge(files, config.as_deref(), out),
    }
}

fn info(file: &Path, as_json: bool) -> anyhow::Result<()> {
    let info = MapInfo::read(file)?;
    if as_json {
        println!("{}", serde_json::to_value(&info)?);
        return Ok(());
    }
    print!("{info}");
    Ok(())
}

fn export(file: &Path, out: &Path) -> anyhow::Result<()> {
    let map = MapFile::load(file).with_context(|| format!("map file {}", file.display()))?;
    let files = &[
        "map.pgm",
        "map.yaml",
        "map.png",
        "cloud.ply",
        "trajectory.tum",
    ];
    let folder = OutputFolder::create(out, files)?;
    let exported = slamkit_slam::map_file::export::export(&map, file, folder.path())?;
    folder.commit()?;
    println!(
        "{} ({} points) in {}",
        exported.files.join(", "),
        exported.cloud_points,
        out.display()
    );
    Ok(())
}

fn merge(files: &[PathBuf], config: Option<&Path>, out: &Path) -> anyhow::Result<()> {
    let start = std::time::Instant::now();
    let mut maps = Vec::with_capacity(files.len());
    for file in files {
        let (map, _) = LidarMap::load(file)?;
        maps.push(map);
    }
    let names = robot_names(files);
    let config = merge_config(config)?;
    let outcome = merge_maps(&maps, &config)?;
    let folder = OutputFolder::create(out, MERGE_FILES)?;
    let mut report = write_merge(&outcome, &maps, &names, "map merge", folder.path())?;
    report["input"] = serde_json::json!(files);
    report["config"] = serde_json::to_value(&config)?;
    report["wall_seconds"] = serde_json::json!(start.elapsed().as_secs_f64());
    report["timings_ms"] = serde_json::json!(outcome.timings.summary());
    crate::output::finish_with_page(folder, &report, "slamkit map merge")?;
    let unmerged = outcome.unmerged();
    println!(
        "{} of {} maps merged ({} closures found, {} accepted){} in {}",
        outcome.stats.merged_inputs,
        files.len(),
        outcome.closures.len(),
        outcome.stats.accepted,
        if unmerged.is_empty() {
            String::new()
        } else {
            let left: Vec<&str> = unmerged.iter().map(|&i| names[i].as_str()).collect();
            format!("; left out: {}", left.join(", "))
        },
        out.display()
    );
    Ok(())
}

/// Each input's name: its file stem, with `_2`, `_3`, ... added when stems repeat.
fn robot_names(files: &[PathBuf]) -> Vec<String> {
    let mut names: Vec<String> = Vec::with_capacity(files.len());
    for (i, file) in files.iter().enumerate() {
        let stem = file.file_stem().map_or_else(
            || format!("input{}", i + 1),
            |s| s.to_string_lossy().into_owned(),
        );
        let mut name = stem.clone();
        let mut n = 1;
        while names.contains(&name) {
            n += 1;
            name = format!("{stem}_{n}");
        }
        names.push(name);
    }
    names
}
