//! `slamkit demo` as a library call: the whole system on a simulated drone, with no download.
//!
//! Simulates a flight through a built-in world (seeded, so every run gives the same data),
//! pushes its readings into the drone's session ([`DroneSlam`](super::DroneSlam), the same a user
//! runs on a recording): layered ICP-SLAM and particle-filter SLAM on the layered increments,
//! scored against the simulator's truth by [`super::simulated`], then the kidnapped-drone layer
//! check ([`super::kidnapped`]) and RGB-D visual odometry on the same flight seen by the drone's
//! camera ([`crate::visual::simulated`]). Everything it finds is written as files people open
//! (grids, plots, a PLY cloud) and returned as the report's JSON, which the caller writes with
//! its page (`slamkit demo` does it with [`crate::report::page::write_run_page`]).

use super::kidnapped;
use super::simulated::{flight_config, FlightErrors, SimulatedFlight};
use crate::record::record_demo;
use crate::visual::simulated::run_simulated_rgbd;
use crate::SlamError;
use serde_json::{json, Value};
use slamkit_eval::plot::{plot_position_errors, positions, TopView};
use slamkit_io::write_tum;

use slamkit_sim::{SimConfig, Simulation, World};
use std::path::Path;

/// The files and folders a demo writes in its output folder.
#[rustfmt::skip]
pub const DEMO_OUTPUTS: &[&str] = &[
    "trajectory.tum", "groundtruth.tum", "trajectory_pf.tum", "trajectory_vo.tum", "cloud.ply",
    "map.pgm", "map.yaml", "map.png", "maps", "map_pf.pgm", "map_pf.yaml", "map_pf.png",
    "errors_icp.png", "errors_pf.png", "errors_vo.png", "rgbd", "report.json", "report.html",
];

/// How far a demo has got, for a progress display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DemoStep {
    /// The flight is simulated: it lasts `duration_s` and gives `scans` scans.
    Simulated {
        /// Flight time \[s\].
        duration_s: f64,
        /// Scans the drone's session will take.
        scans: usize,
    },
    /// The drone's session took one more scan.
    Scan,
    /// Visual odometry took one more camera frame.
    CameraFrame,
}

/// One method's line in the demo's table: name, mean and largest error \[m\] (its plot is
/// `errors_KEY.png`).
#[derive(Debug, Clone)]
pub struct MethodErrors {
    /// Name shown to people.
    pub title: &'static str,
    /// Mean position error \[m\].
    pub mean_m: f64,
    /// Largest position error \[m\].
    pub max_m: f64,
}

/// What a demo found; its files are in the output folder.
#[derive(Debug, Clone)]
pub struct DemoOutcome {
    /// `report.json`'s content (the caller adds what only it knows: wall time, memory).
    pub report: Value,
    /// Layered ICP-SLAM, particle-filter SLAM and visual odometry, in that order.
    pub methods: Vec<MethodErrors>,
    /// The kidnapped-drone check in one sentence.
    pub layer_choice: String,
    /// Length of the true path \[m\].
    pub path_length_m: f64,
    /// Height layers mapped.
    pub layers: usize,
    /// Visual odometry's ATE RMSE after SE(3) alignment \[m\].
    pub vo_ate_rmse_m: f64,
}

impl DemoOutcome {
    /// The table a person reads at the end of a run.
    pub fn summary(&self) -> String {
        let mut text = format!(
            "method                 mean error  max error   (path {:.1} m, {} layers)\n",
            self.path_length_m, self.layers
        );
        for m in &self.methods {
            text += &format!("{:<22} {:>8.3} m  {:>7.3} m\n", m.title, m.mean_m, m.max_m);
        }
        text += &format!(
            "RGB-D VO ATE RMSE {:.3} m (SE(3)-aligned)\n",
            self.vo_ate_rmse_m
        );
        text + &self.layer_choice
    }
}

/// Runs the demo in the built-in `world` (`small`, `large` or `office`) with `seed`, writing
/// [`DEMO_OUTPUTS`] into `out` (an existing folder), and with `record` an MCAP recording of it
/// there ([`record_demo`]).
///
/// # Errors
/// An unknown world, a session that refuses its input, or a file that cannot be written.
pub fn run_demo(
    world: &str,
    seed: u64,
    out: &Path,
    record: Option<&Path>,
    progress: &dyn Fn(DemoStep),
) -> Result<DemoOutcome, SlamError> {
    let world_name = world;
    let sim = Simulation::new(World::builtin(world)?, SimConfig::default(), seed)?;
    let run = sim.lidar_run();
    progress(DemoStep::Simulated {
        duration_s: sim.duration_s(),
        scans: run.scans.len(),
    });
    let config = flight_config(seed);
    let flight = SimulatedFlight::fly(&run, config.clone(), || progress(DemoStep::Scan))?;
    let session = &flight.session;
    let pf_filter = session
        .particle_filter()
        .ok_or_else(|| SlamError::Config("the demo's session has no particle filter".into()))?;
    let (icp, pf) = (&flight.icp, &flight.pf);

    write_tum(&out.join("trajectory.tum"), &icp.estimate)?;
    write_tum(&out.join("groundtruth.tum"), &run.ground_truth)?;
    let (grids, layer_files) = session.write_maps(out, &run.scans, &flight.sim_from_slam)?;
    let height = &config.layers.height;
    let layer_maps = grids.into_layer_maps();
    let ceiling_m = sim.world.height_m;
    let scans = session.scans();
    let layer_loc = kidnapped::relocalise(&run, scans, &layer_maps, height, ceiling_m, seed);
    drop(layer_maps);
    write_tum(&out.join("trajectory_pf.tum"), &pf.estimate)?;
    let mut methods = Vec::new();
    for m in [icp, pf] {
        methods.push(plot_flight_errors(m, &run.ground_truth, out)?);
    }

    let vo = run_simulated_rgbd(
        &sim.world,
        seed,
        &out.join("rgbd"),
        record.is_some(),
        || progress(DemoStep::CameraFrame),
    )?;
    let recorded = match record {
        Some(path) => Some(record_demo(path, &run, &flight, &vo)?),
        None => None,
    };
    write_tum(&out.join("trajectory_vo.tum"), &vo.trajectory)?;
    let vo_plot = out.join("errors_vo.png");
    let a = &vo.ate;
    let view = TopView {
        reference: &a.reference_positions,
        estimate: &a.aligned_estimate_positions,
    };
    let title = "RGB-D visual odometry: position error (SE(3)-aligned)";
    plot_position_errors(&vo_plot, title, &view, &a.timestamps, &a.errors_m)?;
    methods.push(MethodErrors {
        title: "RGB-D visual odometry",
        mean_m: a.stats.mean,
        max_m: a.stats.max,
    });

    let stats = session.stats();
    let counts = session.frame_counts();
    let report = json!({
        "input": { "world": world_name, "seed": seed, "duration_s": sim.duration_s() },
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
        "pf": pf_filter.stats(),
        "timings_ms": {
            "icp": session.timings().summary(),
            "pf": pf_filter.timings().summary(),
            "session_total_s": flight.session_seconds,
        },
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
            "timings_ms": vo.timings.summary(),
        },
        "recording": recorded.map(|messages| json!({ "file": record, "messages": messages })),
    });
    let mut outcome = DemoOutcome {
        report,
        methods,
        layer_choice: kidnapped::summary(layer_loc.as_ref()),
        path_length_m: run.ground_truth.path_length_m(),
        layers: layer_files.len(),
        vo_ate_rmse_m: a.stats.rmse,
    };
    let intro = format!(
        "Simulated drone flight of {:.0} s ({:.1} m, seed {seed}): layered ICP-SLAM (one 2D map \
         per height layer) and particle-filter SLAM (one 2D map).",
        sim.duration_s(),
        outcome.path_length_m,
    );
    outcome.report["summary"] = json!(format!("{intro}\n\n{}", outcome.summary()));
    Ok(outcome)
}

/// Plots one method's position error against the truth as `out/errors_KEY.png`.
fn plot_flight_errors(
    m: &FlightErrors,
    truth: &slamkit_core::Trajectory,
    out: &Path,
) -> Result<MethodErrors, SlamError> {
    let plot = out.join(format!("errors_{}.png", m.key));
    let timestamps: Vec<f64> = m.estimate.poses.iter().map(|p| p.timestamp).collect();
    let (reference, estimate) = (positions(truth), positions(&m.estimate));
    let view = TopView {
        reference: &reference,
        estimate: &estimate,
    };
    let title = format!("{}: position error", m.title);
    plot_position_errors(&plot, &title, &view, &timestamps, &m.errors_m)?;
    Ok(MethodErrors {
        title: m.title,
        mean_m: m.mean_m(),
        max_m: m.max_m(),
    })
}
