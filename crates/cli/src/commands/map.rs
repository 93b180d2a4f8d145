//! `slamkit map info|export`: what a `.skmap` file holds, and its contents as files any tool
//! opens.

use anyhow::Context;
use slamkit_io::output_folder::OutputFolder;
use slamkit_slam::map_file::info::MapInfo;
use slamkit_slam::map_file::MapFile;
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
}

/// Runs `slamkit map`.
pub fn run(args: &MapArgs) -> anyhow::Result<()> {
    match &args.command {
        MapCommand::Info { file, json } => info(file, *json),
        MapCommand::Export { file, out } => export(file, out),
    }
}

fn info(file: &Path, as_json: bool) -> anyhow::Result<()> {
    let info = MapInfo::read(file)?;
    if as_json {
        println!("{}", serde_json::to_value(&info)?);
        return Ok(());
    }
    let h = &info.header;
    println!("{}", file.display());
    println!(
        "  format      {} (slamkit {})",
        info.format_version, h.slamkit_version
    );
    println!("  rig         {}", h.rig);
    println!("  created     {}", h.created_utc());
    println!("  keyframes   {}", h.keyframes);
    if let (Some(edges), Some(scans)) = (info.edges, info.scans) {
        println!("  edges       {edges}");
        println!("  scans       {scans}");
    }
    if let Some([x0, y0, x1, y1]) = h.extent_m {
        println!(
            "  extent      x {x0:.2} .. {x1:.2} m, y {y0:.2} .. {y1:.2} m ({:.1} × {:.1} m)",
            x1 - x0,
            y1 - y0
        );
    }
    println!("  size        {:.2} MB", info.file_bytes as f64 / 1e6);
    println!("  loaded in   {:.3} s", info.load_seconds);
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
