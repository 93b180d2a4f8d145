//! Optimises a g2o SE(3) pose graph with `slamkit_vo::pose_graph` and prints one JSON object:
//! initial and final cost (`½ Σ eᵀΩe`, SE(3) log-map error), iterations and the wall time of
//! each optimisation (the graph is rebuilt from the file for every repeat; reading the file is
//! not timed). `scripts/bench_posegraph.sh` runs it beside GTSAM.
//!
//! usage: cargo run --release -p slamkit-vo --example posegraph -- FILE.g2o [REPEATS]

use slamkit_vo::pose_graph::{LmConfig, PoseGraph};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args.next().ok_or("usage: posegraph FILE.g2o [REPEATS]")?;
    let repeats: usize = args.next().map_or(Ok(3), |r| r.parse())?;
    let g2o = slamkit_io::g2o::read_g2o(std::path::Path::new(&path))?;
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let mut graph = PoseGraph::from_g2o(&g2o)?;
        let start = Instant::now();
        let summary = graph.optimize(&LmConfig::default());
        times.push(start.elapsed().as_secs_f64());
        last = Some(summary);
    }
    let summary = last.ok_or("no run")?;
    let mut sorted = times.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(f64::NAN);
    let times: Vec<String> = times.iter().map(|t| format!("{t:.6}")).collect();
    println!(
        "{{\"optimiser\": \"slamkit\", \"vertices\": {}, \"edges\": {}, \"initial_cost\": {:.10e}, \
         \"final_cost\": {:.10e}, \"iterations\": {}, \"rejected_steps\": {}, \
         \"times_s\": [{}], \"median_s\": {median:.6}}}",
        g2o.vertices.len(),
        g2o.edges.len(),
        summary.initial_cost,
        summary.final_cost,
        summary.iterations,
        summary.rejected_steps,
        times.join(", ")
    );
    Ok(())
}
