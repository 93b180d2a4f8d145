//! `slamkit demo`: the whole system on a simulated drone, with no download.
//!
//! Simulates a flight through a built-in world (seeded, so every run gives the same data) and
//! pushes its readings into the drone's session ([`slamkit_slam::DroneSlam`], the same a user
//! runs on a recording with `slamkit lidar LOG --ranges --imu --flow`): layered ICP-SLAM
//! ([`slamkit_lidar::layers`]: one 2D map per 5 cm height layer,
//! the layer tracked by the up and down range finders, scans ignored while the drone tilts,
//! each scan predicted from the drone's recent velocity, its tilt, its yaw-rate gyro (heading
//! and gyro bias in a Kalman filter that the scans correct) and its downward optical-flow
//! velocity sensor ([`slamkit_sim::flow`]), matches kept only along the directions the scan
//! constrains, each fixed scan matched again to the older maps of the layers within 0.2 m),
//! and particle-filter SLAM ([`slamkit_slam::drone::particle_filter`]) on the
//! same scans in a single 2D map, its height taken from the layered tracker. Neither uses the
//! scans' rotate–translate–rotate odometry: its per-scan yaw error exceeds 0.19 rad on 5 % of
//! the `large` flight's scans. The particle filter takes its motion from the layered
//! matcher's pose increments, as MRPT's ICP-based RBPF takes scan-matching odometry, and keeps
//! its own maps and scan matching (`large`, seeds 1–4: PF mean error 0.20–2.2 m with the
//! drone's odometry, 0.08–0.84 m with scan-to-scan ICP, 0.04–0.08 m with the layered
//! increments). Each estimated 3D position is compared with the simulator's ground truth at the
//! same time.
//!
//! Writes in `--out`: `trajectory.tum`, `groundtruth.tum`, `map.pgm`/`map.yaml`/`map.png` (every
//! layer's scans in one grid), `maps/layer_NNN.{pgm,yaml,png}` (one grid per height layer),
//! `cloud.ply` (the merged layer maps), `trajectory_pf.tum` and `map_pf.{pgm,yaml,png}` (the
//! particle filter's best trajectory and map), `errors_icp.png` and `errors_pf.png` (top view
//! and error over time), `report.json` (`metrics.{icp,pf}.position_error_mean_m`,
//! `metrics.{icp,pf}.position_error_max_m`, and `metrics.layer_localisation`: the kidnapped-drone
//! check of [`layer_loc`], the particle-filter layer choice on the layer maps) and
//! `report.html` (all of it on one page, images embedded). The same flight seen by the
//! drone's simulated RGB-D camera goes through RGB-D visual odometry ([`vo_run`]): `rgbd/` (TUM
//! RGB-D folder), `trajectory_vo.tum`, `errors_vo.png`, `metrics.vo.ate_rmse_m`.

mod html;
mod layer_loc;
mod vo_run;

use crate::commands::drone_files::{processed_and_failed, run_session, write_maps, write_ply};
use crate::output::{peak_rss_bytes, prepare_out_dir, progress_bar, timings_json, write_report};
use anyhow::Context;
use nalgebra::{Point3, Translation3, UnitQuaternion};
use serde_json::json;
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{Pose3, Trajectory};
use slamkit_eval::plot::{plot_errors, ErrorSeries, TopView};
use slamkit_io::write_tum;
use slamkit_lidar::layers::LayeredSlamConfig;
use slamkit_map::{save_map_yaml, save_png};
use slamkit_sim::{LidarRun, SimConfig, Simulation, World as SimWorld};
use slamkit_slam::drone::particle_filter::drone_pf_config;
use slamkit_slam::DroneSlamConfig;
use std::path::{Path, PathBuf};
use std::time::Instant;

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

impl World {
    fn name(self) -> &'static str {
        match self {
            World::Small => "small",
            World::Large => "large",
            World::Office => "office",
        }
    }
}

/// Arguments of `slamkit demo`.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// Built-in world.
    #[arg(long, value_enum, default_value = "small")]
    pub world: World,
    /// Seed of the simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output folder.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
}

/// One SLAM method's result, ready to report.
struct MethodResult {
    /// Short name used in file names and report keys.
    key: &'static str,
    /// Name shown to people.
    title: &'static str,
    /// Estimated poses in the simulator's frame.
    estimate: Trajectory,
    /// 3D position error at each pose \[m\].
    errors_m: Vec<f64>,
}

impl MethodResult {
    fn mean_m(&self) -> f64 {
        self.errors_m.iter().sum::<f64>() / self.errors_m.len().max(1) as f64
    }

    fn max_m(&self) -> f64 {
        self.errors_m.iter().copied().fold(0.0, f64::max)
    }
}

/// Runs `slamkit demo`.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let out = prepare_out_dir(&args.out)?;
    let world = SimWorld::builtin(args.world.name())?;
    let sim = Simulation::new(world, SimConfig::default(), args.seed)
        .context("setting up the simulation")?;
    println!(
        "simulating a {:.0} s flight through the `{}` world (seed {})",
        sim.duration_s(),
        args.world.name(),
        args.seed
    );
    let run = sim.lidar_run();

    let config = DroneSlamConfig {
        layers: LayeredSlamConfig::default(),
        particle_filter: Some(drone_pf_config(args.seed)),
    };
    let slam_started = Instant::now();
    let session = run_session(run.observations(), config.clone())?;
    let slam_s = slam_started.elapsed().as_secs_f64();
    let pf_filter = session
        .particle_filter()
        .context("the session was configured with a particle filter")?;
    let estimates = session.estimates();
    let icp_poses: Vec<Pose3> = estimates.iter().map(|e| e.world_from_base).collect();
    let icp = evaluate("icp", "layered ICP-SLAM", &run, &icp_poses)?;
    let pf_poses = pf_filter.trajectory(&estimates);
    let pf = evaluate("pf", "particle-filter SLAM", &run, &pf_poses)?;

    write_tum(&out.join("trajectory.tum"), &icp.estimate)?;
    write_tum(&out.join("groundtruth.tum"), &run.ground_truth)?;
    let sim_from_slam = sim_from_slam(&run)?;
    let height = &config.layers.height;
    let (layer_files, layer_maps) = write_maps(
        &out,
        &run.scans,
        &estimates,
        &sim_from_slam,
        height.layer_height_m,
    )?;
    let layer_loc = layer_loc::relocalise(
        &run,
        session.scans(),
        &layer_maps,
        height,
        sim.world.height_m,
        args.seed,
    );
    drop(layer_maps);
    let cloud: Vec<Point3<f64>> = session
        .merged_cloud()
        .iter()
        .map(|p| sim_from_slam * p)
        .collect();
    write_ply(&out.join("cloud.ply"), &cloud)?;
    write_tum(&out.join("trajectory_pf.tum"), &pf.estimate)?;
    if let Some(grid) = pf_filter.map() {
        save_map_yaml(grid, &out.join("map_pf.yaml"))?;
        save_png(grid, &out.join("map_pf.png"))?;
    }
    let mut plots = Vec::new();
    for m in [&icp, &pf] {
        let plot = out.join(format!("errors_{}.png", m.key));
        plot_method(&plot, m, &run.ground_truth)?;
        plots.push((m.title, m.mean_m(), m.max_m(), plot));
    }

    let vo_bar = progress_bar(0, "rgbd-vo");
    let vo = vo_run::run_vo_demo(&sim.world, args.seed, &out, || vo_bar.inc(1))?;
    vo_bar.finish_and_clear();
    plots.push((
        vo.title,
        vo.ate.stats.mean,
        vo.ate.stats.max,
        vo.plot.clone(),
    ));

    let stats = session.stats();
    let (processed, failed) = processed_and_failed(&estimates);
    let report = json!({
        "input": { "world": args.world.name(), "seed": args.seed, "duration_s": sim.duration_s() },
        "config": { "sim": sim.config, "icp": config.layers, "pf": config.particle_filter },
        "frames": {
            "read": run.scans.len(),
            "processed": processed,
            "skipped": stats.scans_tilted + stats.scans_without_height,
            "failed": failed,
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
            "session_total_s": slam_s,
        },
        "peak_rss_bytes": peak_rss_bytes(),
        "metrics": {
            "icp": metrics_json(&icp, &run),
            "pf": metrics_json(&pf, &run),
            "vo": vo_run::metrics_json(&vo),
            "layer_localisation": layer_loc::metrics_json(layer_loc.as_ref()),
        },
        "vo": vo_run::report_json(&vo),
    });
    write_report(&out, &report)?;
    let page = html::Page {
        world: args.world.name(),
        seed: args.seed,
        duration_s: sim.duration_s(),
        path_length_m: run.ground_truth.path_length_m(),
        methods: plots,
        maps: [
            ("Map of all layers (layered ICP-SLAM)", out.join("map.png")),
            ("Particle-filter SLAM map", out.join("map_pf.png")),
        ]
        .into_iter()
        .filter(|(_, png)| png.exists())
        .collect(),
        layers: layer_files
            .iter()
            .map(|l| html::LayerImage {
                layer: l.layer,
                z_range_m: l.z_range_m,
                scans: l.scans,
                png: l.png.clone(),
            })
            .collect(),
        layer_choice: layer_loc::summary(layer_loc.as_ref()),
    };
    html::write(&out.join("report.html"), &page)?;
    println!(
        "method                 mean error  max error   (path {:.1} m, {} layers)",
        run.ground_truth.path_length_m(),
        layer_files.len()
    );
    for (title, mean, max, _) in &page.methods {
        println!("{title:<22} {mean:>8.3} m  {max:>7.3} m");
    }
    println!(
        "RGB-D VO ATE RMSE {:.3} m (SE(3)-aligned)",
        vo.ate.stats.rmse
    );
    println!("{}", page.layer_choice);
    println!("outputs in {}", out.display());
    Ok(())
}

/// The simulator's frame seen from SLAM's: SLAM's x, y and yaw start at the first true pose,
/// its heights are above the floor, which is the simulator's z = 0.
fn sim_from_slam(run: &LidarRun) -> anyhow::Result<Pose3> {
    let first = run
        .ground_truth
        .poses
        .first()
        .context("the simulation produced no scan")?;
    let planar = pose3_to_pose2(&first.pose);
    Ok(Pose3::from_parts(
        Translation3::new(planar.translation.x, planar.translation.y, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, planar.rotation.angle()),
    ))
}

/// The estimate in the simulator's frame and its 3D position error at every scan.
fn evaluate(
    key: &'static str,
    title: &'static str,
    run: &LidarRun,
    poses: &[Pose3],
) -> anyhow::Result<MethodResult> {
    let sim_from_slam = sim_from_slam(run)?;
    let mut estimate = Trajectory::new();
    for (pose, truth) in poses.iter().zip(&run.ground_truth.poses) {
        estimate.push(truth.timestamp, sim_from_slam * pose);
    }
    let errors_m = estimate
        .poses
        .iter()
        .zip(&run.ground_truth.poses)
        .map(|(e, t)| (e.pose.translation.vector - t.pose.translation.vector).norm())
        .collect();
    Ok(MethodResult {
        key,
        title,
        estimate,
        errors_m,
    })
}

fn metrics_json(m: &MethodResult, run: &LidarRun) -> serde_json::Value {
    let horizontal: Vec<f64> = m
        .estimate
        .poses
        .iter()
        .zip(&run.ground_truth.poses)
        .map(|(e, t)| {
            (e.pose.translation.vector - t.pose.translation.vector)
                .xy()
                .norm()
        })
        .collect();
    let vertical: Vec<f64> = m
        .estimate
        .poses
        .iter()
        .zip(&run.ground_truth.poses)
        .map(|(e, t)| (e.pose.translation.z - t.pose.translation.z).abs())
        .collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    json!({
        "position_error_mean_m": m.mean_m(),
        "position_error_max_m": m.max_m(),
        "horizontal_error_mean_m": mean(&horizontal),
        "height_error_mean_m": mean(&vertical),
        "path_length_m": run.ground_truth.path_length_m(),
    })
}

/// Top view of the truth and the estimate, and the error over time.
fn plot_method(path: &Path, m: &MethodResult, truth: &Trajectory) -> anyhow::Result<()> {
    let points = |t: &Trajectory| -> Vec<Point3<f64>> {
        t.poses
            .iter()
            .map(|p| Point3::from(p.pose.translation.vector))
            .collect()
    };
    let timestamps: Vec<f64> = m.estimate.poses.iter().map(|p| p.timestamp).collect();
    let title = format!("{}: position error", m.title);
    plot_errors(
        path,
        &TopView {
            reference: &points(truth),
            estimate: &points(&m.estimate),
        },
        &ErrorSeries {
            title: &title,
            label: "position error [m]",
            timestamps: &timestamps,
            errors: &m.errors_m,
        },
    )?;
    Ok(())
}
