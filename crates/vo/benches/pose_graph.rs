//! The SE(3) pose-graph optimiser on the real parking-garage graph (1661 poses, 6275 edges;
//! `$SLAMKIT_DATA/posegraph/parking-garage.g2o`, see its SOURCES.md): the symbolic elimination
//! (minimum-degree order and fill-in) alone, and a whole Levenberg–Marquardt run from the
//! file's initial poses. Skipped when `SLAMKIT_DATA` is not set.

use criterion::{criterion_main, Criterion};
use slamkit_core::block_elimination::Elimination;
use slamkit_vo::pose_graph::{LmConfig, PoseGraph};

fn pose_graph() {
    let Some(path) = slamkit_testdata::data("pose_graph bench", "posegraph/parking-garage.g2o")
    else {
        return;
    };
    let Ok(g2o) = slamkit_io::g2o::read_g2o(&path) else {
        eprintln!("skipped: pose_graph bench: cannot read {}", path.display());
        return;
    };
    let Ok(graph) = PoseGraph::from_g2o(&g2o) else {
        return;
    };
    let pairs: Vec<(usize, usize)> = graph.edges().iter().map(|e| (e.from, e.to)).collect();
    let mut c = Criterion::default().sample_size(10).configure_from_args();
    c.bench_function("vo/pose_graph_symbolic_parking_garage", |b| {
        b.iter(|| Elimination::new(graph.nodes().len(), &pairs))
    });
    c.bench_function("vo/pose_graph_lm_parking_garage", |b| {
        b.iter(|| graph.clone().optimize(&LmConfig::default()))
    });
}

criterion_main!(pose_graph);
