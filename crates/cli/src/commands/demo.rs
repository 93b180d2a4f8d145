//! `slamkit demo`: the whole system on a simulated drone, with no download.
//!
//! Simulates a flight through a built-in world (seeded, so every run gives the same data),
//! pushes its readings into the drone's session ([`slamkit_slam::DroneSlam`], the same a user
//! runs on a recording with `slamkit lidar LOG --ranges --imu --flow`): layered ICP-SLAM and
//! particle-filter SLAM on the layered increments, scored against the simulator's truth by
//! [`slamkit_slam::drone::simulated`] (its docs say how each works), then the kidnapped-drone
//! layer check ([`slamkit_slam::drone::kidnapped`]) and RGB-D visual odometry on the same
//! flight seen by the drone's camera ([`slamkit_slam::visual::simulated`]).
//!
//! Writes in `--out`: `trajectory.tum`, `groundtruth.tum`, `map.pgm`/`map.yaml`/`map.png` (every
//! layer's scans in one grid), `maps/layer_NNN.{pgm,yaml,png}` (one grid per height layer),
//! `cloud.ply` (the merged layer maps), `trajectory_pf.tum` and `map_pf.{pgm,yaml,png}` (the
//! particle filter's best trajectory and map), `errors_icp.png` and `errors_pf.png` (top view
//! and error over time), `rgbd/` (the camera's TUM RGB-D folder), `trajectory_vo.tum`,
//! `errors_vo.png`, `report.json` (`metrics.{icp,pf}.position_error_mean_m`,
//! `metrics.{icp,pf}.position_error_max_m`, `metrics.vo.ate_rmse_m`,
//! `metrics.layer_localisation`) and `report.html` (all of it on one page, images embedded).

use crate::commands::drone_files::{write_grids, write_ply, LayerFile};
use crate::output::{finish, peak_rss_bytes, progress_bar, timings_json, write_grid};
use anyhow::Context;
use nalgebra::Point3;
use serde_json::json;
use slamkit_eval::plot::{plot_position_errors, positions, TopView};
use slamkit_eval::report_html::{Figure, HtmlReport};
use slamkit_io::output_folder::OutputFolder;
use slamkit_io::write_tum;
use slamkit_map::OccupancyGridConfig;
use slamkit_sim::{SimConfig, Simulation, World};
use slamkit_slam::drone::kidnapped;
use slamkit_slam::drone::simulated::{flight_config, SimulatedFlight};
use slamkit_slam::visual::simulated::run_simulated_rgbd;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `slamkit demo`.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// Built-in world: `small` (5 × 5 m, 1 m high, boxes and cylinders), `large` (10 × 10 m,
    /// 2.4 m high, more obstacles and a ramp) or `office` (12.9 × 7.7 m, 2.5 m high, furnished).
    #[arg(long, default_value = "small", value_parser = ["small", "large", "office"])]
    pub world: String,
    /// Seed of the simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output folder.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
}

/// The files and folders a demo run writes in `--out`.
#[rustfmt::skip]
const OUTPUTS: &[&str] = &[
    "trajectory.tum", "groundtruth.tum", "trajectory_pf.tum", "trajectory_vo.tum", "cloud.ply",
    "map.pgm", "map.yaml", "map.png", "maps", "map_pf.pgm", "map_pf.yaml", "map_pf.png",
    "errors_icp.png", "errors_pf.png", "errors_vo.png", "rgbd", "report.json", "report.html",
];

/// A method's line in the table and the page: name, mean and max error \[m\], error plot.
type MethodLine = (&'static str, f64, f64, PathBuf);

/// Runs `slamkit demo`.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let out = folder.path().to_path_buf();
    let world = World::builtin(&args.world)?;
    let sim = Simulation::new(world, SimConfig::default(), args.seed)
        .context("setting up the simulation")?;
    println!(
        "simulating a {:.0} s flight through the `{}` world (seed {})",
        sim.duration_s(),
        args.world,
        args.seed
    );
    let run = sim.lidar_run();
    let config = flight_config(args.seed);
    let bar = progress_bar(run.scans.len() as u64, "drone-slam");
    let flight = SimulatedFlight::fly(&run, config.clone(), || bar.inc(1))?;
    bar.finish_and_clear();
    let session = &flight.session;
    let pf_filter = session
        .particle_filter()
        .context("the session was configured with a particle filter")?;
    let (icp, pf) = (&flight.icp, &flight.pf);

    write_tum(&out.join("trajectory.tum"), &icp.estimate)?;
    write_tum(&out.join("groundtruth.tum"), &run.ground_truth)?;
    let grid_config = OccupancyGridConfig::default();
    let grids = session.layer_grids(&run.scans, &flight.sim_from_slam, &grid_config)?;
    let layer_files = write_grids(&out, &grids)?;
    let height = &config.layers.height;
    let layer_maps = grids.into_layer_maps();
    let ceiling_m = sim.world.height_m;
    let layer_loc = kidnapped::relocalise(
        &run,
        session.scans(),
        &layer_maps,
        height,
        ceiling_m,
        args.seed,
    );
    drop(layer_maps);
    let cloud: Vec<Point3<f64>> = session
        .merged_cloud()
        .iter()
        .map(|p| flight.sim_from_slam * p)
        .collect();
    write_ply(&out.join("cloud.ply"), &cloud)?;
    write_tum(&out.join("trajectory_pf.tum"), &pf.estimate)?;
    if let Some(grid) = pf_filter.map() {
        write_grid(grid, &out.join("map_pf"))?;
    }
    let mut methods: Vec<MethodLine> = Vec::new();
    for m in [icp, pf] {
        let png = out.join(format!("errors_{}.png", m.key));
        let timestamps: Vec<f64> = m.estimate.poses.iter().map(|p| p.timestamp).collect();
        let (reference, estimate) = (positions(&run.ground_truth), positions(&m.estimate));
        let view = TopView {
            reference: &reference,
            estimate: &estimate,
        };
        let title = format!("{}: position error", m.title);
        plot_position_errors(&png, &title, &view, &timestamps, &m.errors_m)?;
        methods.push((m.title, m.mean_m(), m.max_m(), png));
    }

    let vo_bar = progress_bar(0, "rgbd-vo");
    let vo = run_simulated_rgbd(&sim.world, args.seed, &out.join("rgbd"), || vo_bar.inc(1))?;
    vo_bar.finish_and_clear();
    write_tum(&out.join("trajectory_vo.tum"), &vo.trajectory)?;
    let vo_plot = out.join("errors_vo.png");
    let a = &vo.ate;
    let view = TopView {
        reference: &a.reference_positions,
        estimate: &a.aligned_estimate_positions,
    };
    let title = "RGB-D visual odometry: position error (SE(3)-aligned)";
    plot_position_errors(&vo_plot, title, &view, &a.timestamps, &a.errors_m)?;
    methods.push(("RGB-D visual odometry", a.stats.mean, a.stats.max, vo_plot));

    let stats = session.stats();
    let counts = session.frame_counts();
    let report = json!({
        "input": { "world": args.world, "seed": args.seed, "duration_s": sim.duration_s() },
        "config": { "sim": sim.config, "icp": config.layers, "pf": config.particle_filter },
        "frames": {
            "read": run.scans.len(),
            "processed": counts.processed,
            "skipped": counts.skipped,
            "failed": counts.failed,
            "tilted": stats.scans_tilted,
            "degenerate": stats.scans_degenerate,
            "rejected": stats.matches_rejected,
        },
        "layers": {
            "count": layer_files.len(),
            "switches": stats.layer_switches,
            "returns": stats.layer_returns,
            "relocalisations": stats.relocalisations,
            "reference_fixes": stats.reference_fixes,
            "obstacle_edges": stats.obstacle_edges,
        },
        "wall_seconds": started.elapsed().as_secs_f64(),
        "pf": pf_filter.stats(),
        "timings_ms": {
            "icp": timings_json(session.timings()),
            "pf": timings_json(pf_filter.timings()),
            "session_total_s": flight.session_seconds,
        },
        "peak_rss_bytes": peak_rss_bytes(),
        "metrics": {
            "icp": icp.metrics(&run.ground_truth),
            "pf": pf.metrics(&run.ground_truth),
            "vo": {
                "ate_rmse_m": a.stats.rmse,
                "ate_mean_m": a.stats.mean,
                "ate_max_m": a.stats.max,
                "pairs": a.stats.pairs,
            },
            "layer_localisation": kidnapped::metrics_json(layer_loc.as_ref()),
        },
        "vo": {
            "camera": vo.camera,
            "frames": vo.stats,
            "timings_ms": timings_json(&vo.timings),
        },
    });
    let layer_choice = kidnapped::summary(layer_loc.as_ref());
    let path_length_m = run.ground_truth.path_length_m();
    let intro = format!(
        "Simulated drone flight of {:.0} s ({path_length_m:.1} m, seed {}): layered ICP-SLAM (one \
         2D map per height layer) and particle-filter SLAM (one 2D map).",
        sim.duration_s(),
        args.seed
    );
    let page = Page {
        title: format!("slamkit demo: {} world", args.world),
        intro,
        methods: &methods,
        layer_choice: &layer_choice,
        out: &out,
        layers: &layer_files,
    };
    write_html(&out.join("report.html"), &page)?;
    finish(folder, &report)?;
    println!(
        "method                 mean error  max error   (path {path_length_m:.1} m, {} layers)",
        layer_files.len()
    );
    for (title, mean, max, _) in &methods {
        println!("{title:<22} {mean:>8.3} m  {max:>7.3} m");
    }
    println!("RGB-D VO ATE RMSE {:.3} m (SE(3)-aligned)", a.stats.rmse);
    println!("{layer_choice}");
    println!("outputs in {}", args.out.display());
    Ok(())
}

/// What `report.html` shows.
struct Page<'a> {
    title: String,
    intro: String,
    methods: &'a [MethodLine],
    layer_choice: &'a str,
    out: &'a Path,
    layers: &'a [LayerFile],
}

/// Writes `report.html`: the error table, the error plots and the maps on one page.
fn write_html(path: &Path, p: &Page) -> anyhow::Result<()> {
    let mut page = HtmlReport::new(&p.title);
    page.paragraph(&p.intro);
    page.heading(2, "Position error against ground truth");
    let rows: Vec<Vec<String>> = p
        .methods
        .iter()
        .map(|(name, mean, max, _)| {
            vec![name.to_string(), format!("{mean:.3}"), format!("{max:.3}")]
        })
        .collect();
    page.table(&["method", "mean [m]", "max [m]"], &rows);
    page.paragraph(&format!("Kidnapped drone, {}", p.layer_choice));
    for (name, _, _, png) in p.methods {
        page.heading(3, name);
        page.image(&format!("{name} errors"), png, true)?;
    }
    let maps = [
        ("Map of all layers (layered ICP-SLAM)", "map.png"),
        ("Particle-filter SLAM map", "map_pf.png"),
    ];
    for (title, png) in maps.map(|(t, f)| (t, p.out.join(f))) {
        if png.exists() {
            page.heading(2, title);
            page.image(title, &png, false)?;
        }
    }
    page.heading(2, &format!("Maps per height layer ({})", p.layers.len()));
    let figures: Vec<Figure> = p
        .layers
        .iter()
        .map(|l| Figure {
            alt: format!("layer {}", l.layer),
            png: l.png.clone(),
            caption: format!(
                "layer {}: {:.2}–{:.2} m, {} scans",
                l.layer, l.z_range_m[0], l.z_range_m[1], l.scans
            ),
        })
        .collect();
    page.gallery(&figures)?;
    Ok(page.write(path)?)
}
