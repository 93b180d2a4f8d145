//! `slamkit map info|export`: what a `.skmap` file holds, and its contents as files any tool
//! opens.

use crate::output::prepare_out_dir;
use anyhow::Context;
use serde_json::json;
use slamkit_slam::lidar::LidarMap;
use slamkit_slam::map_file::{peek_version, MapFile, Rig};
use std::path::{Path, PathBuf};
use std::time::Instant;

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

fn load(file: &Path) -> anyhow::Result<(MapFile, u64, f64, (u16, u16))> {
    let started = Instant::now();
    let bytes = std::fs::read(file).with_context(|| format!("reading {}", file.display()))?;
    let map =
        MapFile::from_bytes(&bytes).with_context(|| format!("map file {}", file.display()))?;
    let seconds = started.elapsed().as_secs_f64();
    let version = peek_version(&bytes).unwrap_or_default();
    Ok((map, bytes.len() as u64, seconds, version))
}

fn info(file: &Path, as_json: bool) -> anyhow::Result<()> {
    let started = Instant::now();
    let (map, bytes, _, version) = load(file)?;
    let h = &map.header;
    let lidar = match h.rig {
        Rig::Lidar2d => Some(
            LidarMap::from_file(&map).with_context(|| format!("map file {}", file.display()))?,
        ),
        _ => None,
    };
    // Reading, checking and decoding the whole map, as a session loading it does.
    let seconds = started.elapsed().as_secs_f64();
    let sections: Vec<serde_json::Value> = map
        .sections
        .iter()
        .map(|s| json!({"tag": String::from_utf8_lossy(&s.tag), "bytes": s.data.len()}))
        .collect();
    let report = json!({
        "file": file,
        "format_version": format!("{}.{}", version.0, version.1),
        "rig": h.rig,
        "slamkit_version": h.slamkit_version,
        "created_unix_s": h.created_unix_s,
        "keyframes": h.keyframes,
        "edges": lidar.as_ref().map(|m| m.edges.len()),
        "scans": lidar.as_ref().map(|m| m.scans.len()),
        "extent_m": h.extent_m,
        "units": h.units,
        "frames": h.frames,
        "notes": h.notes,
        "file_bytes": bytes,
        "load_seconds": seconds,
        "sections": sections,
    });
    if as_json {
        println!("{report}");
        return Ok(());
    }
    println!("{}", file.display());
    println!(
        "  format      {}.{} (slamkit {})",
        version.0, version.1, h.slamkit_version
    );
    println!("  rig         {}", h.rig);
    println!("  created     {}", h.created_utc());
    println!("  keyframes   {}", h.keyframes);
    if let Some(m) = &lidar {
        println!("  edges       {}", m.edges.len());
        println!("  scans       {}", m.scans.len());
    }
    if let Some([x0, y0, x1, y1]) = h.extent_m {
        println!(
            "  extent      x {x0:.2} .. {x1:.2} m, y {y0:.2} .. {y1:.2} m ({:.1} × {:.1} m)",
            x1 - x0,
            y1 - y0
        );
    }
    println!("  size        {:.2} MB", bytes as f64 / 1e6);
    println!("  loaded in   {:.3} s", seconds);
    Ok(())
}

fn export(file: &Path, out: &Path) -> anyhow::Result<()> {
    let (map, _, _, _) = load(file)?;
    let out = prepare_out_dir(out)?;
    let exported = slamkit_slam::map_file::export::export(&map, file, &out)?;
    println!(
        "{} ({} points) in {}",
        exported.files.join(", "),
        exported.cloud_points,
        out.display()
    );
    Ok(())
}
