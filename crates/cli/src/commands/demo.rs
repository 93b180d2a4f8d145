//! `slamkit demo`: the whole system on a simulated drone, with no download.
//!
//! Simulates a flight through a built-in world (seeded, so every run gives the same data) and
//! runs layered ICP-SLAM on it ([`slamkit_lidar::layers`]: one 2D map per 5 cm height layer,
//! the layer tracked by the up and down range finders, scans ignored while the drone tilts,
//! each scan predicted from the drone's recent velocity, its tilt, its yaw-rate gyro (heading
//! and gyro bias in a Kalman filter that the scans correct) and its downward optical-flow
//! velocity sensor ([`slamkit_sim::flow`]), matches kept only along the directions the scan
//! constrains, each fixed scan matched again to the older maps of the layers within 0.2 m),
//! and particle-filter SLAM ([`slamkit_lidar::rbpf`]) on the
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

use crate::output::{peak_rss_bytes, prepare_out_dir, progress_bar, timings_json, write_report};
use anyhow::Context;
use nalgebra::{Point3, Translation3, UnitQuaternion, Vector2};
use serde_json::json;
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{LaserScan, Pose2, Pose3, Trajectory};
use slamkit_eval::plot::{plot_errors, ErrorSeries, TopView};
use slamkit_io::write_tum;
use slamkit_lidar::layers::{
    LayerInput, LayerScanStatus, LayeredEstimate, LayeredIcpSlam, LayeredSlamConfig,
};
use slamkit_lidar::rbpf::{run_rbpf, RbpfConfig, RbpfOutput};
use slamkit_map::{save_map_yaml, save_png, OccupancyGrid, OccupancyGridConfig};
use slamkit_sim::{FlowReading, LidarRun, RangeReading, SimConfig, Simulation, World as SimWorld};
use std::collections::BTreeMap;
use std::fmt::Write as _;
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

/// A height layer's grid map written to disk.
struct LayerFile {
    layer: i64,
    z_range_m: [f64; 2],
    scans: usize,
    png: PathBuf,
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

    let config = LayeredSlamConfig::default();
    let slam_started = Instant::now();
    let (slam, estimates) = run_layered(&run, &config)?;
    let slam_s = slam_started.elapsed().as_secs_f64();
    let icp_poses: Vec<Pose3> = estimates.iter().map(|e| e.world_from_base).collect();
    let icp = evaluate("icp", "layered ICP-SLAM", &run, &icp_poses)?;
    let pf_config = pf_config(args.seed);
    let pf_started = Instant::now();
    let pf_run = run_pf(&with_odometry(&run.scans, &estimates), &pf_config)?;
    let pf_s = pf_started.elapsed().as_secs_f64();
    let pf_poses = with_height(&pf_run.poses, &estimates);
    let pf = evaluate("pf", "particle-filter SLAM", &run, &pf_poses)?;

    write_tum(&out.join("trajectory.tum"), &icp.estimate)?;
    write_tum(&out.join("groundtruth.tum"), &run.ground_truth)?;
    let sim_from_slam = sim_from_slam(&run)?;
    let (layer_files, layer_maps) = write_maps(&out, &run, &estimates, &sim_from_slam)?;
    let layer_loc = layer_loc::relocalise(
        &run,
        &estimates,
        &layer_maps,
        &config.height,
        sim.world.height_m,
        args.seed,
    );
    drop(layer_maps);
    let cloud: Vec<Point3<f64>> = slam
        .merged_cloud()
        .iter()
        .map(|p| sim_from_slam * p)
        .collect();
    write_ply(&out.join("cloud.ply"), &cloud)?;
    write_tum(&out.join("trajectory_pf.tum"), &pf.estimate)?;
    if let Some(grid) = &pf_run.map {
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

    let stats = slam.stats();
    let report = json!({
        "input": { "world": args.world.name(), "seed": args.seed, "duration_s": sim.duration_s() },
        "config": { "sim": sim.config, "icp": config, "pf": pf_config },
        "frames": {
            "read": run.scans.len(),
            "processed": count(&estimates, |s| matches!(s, LayerScanStatus::Slam(_))),
            "skipped": stats.scans_tilted + stats.scans_without_height,
            "failed": count(&estimates, |s| matches!(s, LayerScanStatus::Slam(
                slamkit_lidar::icp_slam::ScanStatus::MatchFailed))),
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
        "pf": pf_run.stats,
        "timings_ms": {
            "icp": timings_json(slam.timings()),
            "icp_total_s": slam_s,
            "pf": timings_json(&pf_run.timings),
            "pf_total_s": pf_s,
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

/// Runs layered ICP-SLAM over the run: each scan with the range reading and attitude of its
/// time.
fn run_layered(
    run: &LidarRun,
    config: &LayeredSlamConfig,
) -> anyhow::Result<(LayeredIcpSlam, Vec<LayeredEstimate>)> {
    let mut slam = LayeredIcpSlam::new(config.clone())?;
    let bar = progress_bar(run.scans.len() as u64, "icp-slam");
    let mut estimates = Vec::with_capacity(run.scans.len());
    let mut previous_s = None;
    for (scan, attitude) in run.scans.iter().zip(&run.attitudes) {
        let range = latest_reading(&run.ranges, scan.timestamp);
        let flow = previous_s.and_then(|t0| mean_flow(&run.flows, t0, scan.timestamp));
        previous_s = Some(scan.timestamp);
        let input = LayerInput {
            scan,
            up_m: range.and_then(|r| r.up_m),
            down_m: range.and_then(|r| r.down_m),
            roll_rad: attitude.roll_rad,
            pitch_rad: attitude.pitch_rad,
            gyro_yaw_rad: Some(attitude.gyro_yaw_rad),
            flow_velocity_mps: flow,
        };
        estimates.push(slam.process(&input));
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok((slam, estimates))
}

/// Share of GMapping's translation noise (`trans_per_*`, `min_trans_sigma_m`) the particle
/// filter's motion model has. Its motion is the layered matcher's pose increments: their
/// translation drifts where the scans do not pin it (up to 0.05 m per metre flown, `large`
/// seed 2), their heading follows the gyro (see [`PF_ROTATION_NOISE_SCALE`]).
const PF_TRANSLATION_NOISE_SCALE: f64 = 0.5;

/// Share of GMapping's rotation noise (`rot_per_*`, `min_rot_sigma_rad`) of the particle
/// filter's motion model: the increments' heading comes from the gyro, which drifts less than
/// 0.1 rad over a flight.
const PF_ROTATION_NOISE_SCALE: f64 = 0.1;

/// The particle filter's settings: the defaults with [`PF_TRANSLATION_NOISE_SCALE`] and
/// [`PF_ROTATION_NOISE_SCALE`] of the motion noise, and the scan match climbing on the scan
/// likelihood times the motion model (`climb_with_motion_prior`): on the single 2D map of all
/// heights a climb on the scan alone turned the particles' heading 0.1–0.2 rad off the gyro's
/// (`office` seeds 1–5, median mean error 0.342 m with GMapping's climb and 0.1 of its noise,
/// 0.142 m with this; BENCHMARKS.md).
fn pf_config(seed: u64) -> RbpfConfig {
    let mut config = RbpfConfig {
        seed,
        ..RbpfConfig::default()
    };
    config.proposal.climb_with_motion_prior = true;
    let m = &mut config.motion;
    for noise in [
        &mut m.trans_per_trans,
        &mut m.trans_per_rot,
        &mut m.min_trans_sigma_m,
    ] {
        *noise *= PF_TRANSLATION_NOISE_SCALE;
    }
    for noise in [
        &mut m.rot_per_trans,
        &mut m.rot_per_rot,
        &mut m.min_rot_sigma_rad,
    ] {
        *noise *= PF_ROTATION_NOISE_SCALE;
    }
    config
}

/// Runs particle-filter SLAM on the same scans, with a progress bar.
fn run_pf(scans: &[LaserScan], config: &RbpfConfig) -> anyhow::Result<RbpfOutput> {
    let bar = progress_bar(scans.len() as u64, "pf-slam");
    let output = run_rbpf(scans, config, |_| bar.inc(1))?;
    bar.finish_and_clear();
    Ok(output)
}

/// The scans with the layered estimate's planar pose as their odometry, without its
/// re-localisations (a jump in odometry would be motion to the particle filter, whose own map
/// does not move with the layered maps).
fn with_odometry(scans: &[LaserScan], estimates: &[LayeredEstimate]) -> Vec<LaserScan> {
    scans
        .iter()
        .zip(estimates)
        .map(|(scan, e)| LaserScan {
            odometry: Some(e.smooth_world_from_base),
            ..scan.clone()
        })
        .collect()
}

/// 3D poses from the particle filter's planar ones, with the height, roll and pitch of the
/// layered tracker at the same scan (the particle filter keeps a single 2D map).
fn with_height(planar: &[Pose2], estimates: &[LayeredEstimate]) -> Vec<Pose3> {
    planar
        .iter()
        .zip(estimates)
        .map(|(p, e)| {
            let (roll, pitch, _) = e.world_from_base.rotation.euler_angles();
            Pose3::from_parts(
                Translation3::new(
                    p.translation.x,
                    p.translation.y,
                    e.world_from_base.translation.z,
                ),
                UnitQuaternion::from_euler_angles(roll, pitch, p.rotation.angle()),
            )
        })
        .collect()
}

/// The mean optical-flow velocity over the readings that end in `(t0, t1]`, weighted by their
/// integration periods; `None` when one of them has no velocity (or there is none).
fn mean_flow(readings: &[FlowReading], t0: f64, t1: f64) -> Option<Vector2<f64>> {
    let first = readings.partition_point(|r| r.timestamp <= t0);
    let last = readings.partition_point(|r| r.timestamp <= t1);
    let window = readings.get(first..last)?;
    let (sum, span) = window
        .iter()
        .try_fold((Vector2::zeros(), 0.0), |(sum, span), r| {
            r.velocity_mps
                .map(|v| (sum + v * r.integration_s, span + r.integration_s))
        })?;
    (span > 0.0).then(|| sum / span)
}

/// The last range reading taken at or before `t`.
fn latest_reading(readings: &[RangeReading], t: f64) -> Option<&RangeReading> {
    let after = readings.partition_point(|r| r.timestamp <= t);
    after.checked_sub(1).and_then(|i| readings.get(i))
}

fn count(estimates: &[LayeredEstimate], pred: impl Fn(&LayerScanStatus) -> bool) -> usize {
    estimates.iter().filter(|e| pred(&e.status)).count()
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

/// Writes one grid per height layer (`maps/layer_NNN.*`) and one of every scan (`map.*`), each
/// scan inserted at its estimated pose; returns the files and the layer grids (simulator frame).
fn write_maps(
    out: &Path,
    run: &LidarRun,
    estimates: &[LayeredEstimate],
    sim_from_slam: &Pose3,
) -> anyhow::Result<(Vec<LayerFile>, BTreeMap<i64, OccupancyGrid>)> {
    let grid_config = OccupancyGridConfig::default();
    let mut all = OccupancyGrid::new(grid_config.clone())?;
    let mut layers: BTreeMap<i64, (OccupancyGrid, usize)> = BTreeMap::new();
    for (scan, est) in run.scans.iter().zip(estimates) {
        let (LayerScanStatus::Slam(_), Some(layer)) = (est.status, est.layer) else {
            continue;
        };
        let world_from_base: Pose2 = pose3_to_pose2(&(sim_from_slam * est.world_from_base));
        let world_from_laser = world_from_base * scan.base_from_laser;
        all.insert_scan(scan, &world_from_laser)?;
        let entry = match layers.entry(layer) {
            std::collections::btree_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::btree_map::Entry::Vacant(v) => {
                v.insert((OccupancyGrid::new(grid_config.clone())?, 0))
            }
        };
        entry.0.insert_scan(scan, &world_from_laser)?;
        entry.1 += 1;
    }
    save_map_yaml(&all, &out.join("map.yaml"))?;
    save_png(&all, &out.join("map.png"))?;
    let dir = out.join("maps");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let thickness = LayeredSlamConfig::default().height.layer_height_m;
    let mut files = Vec::new();
    for (layer, (grid, scans)) in &layers {
        let stem = dir.join(format!("layer_{layer:03}"));
        save_map_yaml(grid, &stem.with_extension("yaml"))?;
        let png = stem.with_extension("png");
        save_png(grid, &png)?;
        let bottom = *layer as f64 * thickness;
        files.push(LayerFile {
            layer: *layer,
            z_range_m: [bottom, bottom + thickness],
            scans: *scans,
            png,
        });
    }
    let grids = layers.into_iter().map(|(k, (grid, _))| (k, grid)).collect();
    Ok((files, grids))
}

/// Writes `points` as an ASCII PLY point cloud.
fn write_ply(path: &Path, points: &[Point3<f64>]) -> anyhow::Result<()> {
    let mut text = format!(
        "ply\nformat ascii 1.0\ncomment slamkit demo: merged height-layer maps\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        points.len()
    );
    for p in points {
        let _ = writeln!(text, "{:.4} {:.4} {:.4}", p.x, p.y, p.z);
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
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
