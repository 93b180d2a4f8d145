//! The SE(3) pose-graph optimiser on a real pose graph against an independent optimiser.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use slamkit_vo::pose_graph::{LmConfig, PoseGraph};

/// GTSAM 4.3.0 (PyPI) Levenberg–Marquardt on the same problem (BetweenFactorPose3 with the
/// file's information, first vertex held by a 1e12 prior), from
/// `out/venv-gtsam/bin/python scripts/posegraph_gtsam.py $SLAMKIT_DATA/posegraph/parking-garage.g2o`
/// (run by `scripts/bench_posegraph.sh`), 2026-11-26.
const GTSAM_INITIAL_COST: f64 = 8363.601948120004;
const GTSAM_FINAL_COST: f64 = 0.634192401010533;

#[test]
fn parking_garage_reaches_gtsams_optimum() {
    // parking-garage.g2o: MOLAorg/mola_test_datasets (Carlone et al. 2015), see its SOURCES.md.
    let Some(path) = slamkit_testdata::data(
        "parking_garage_reaches_gtsams_optimum",
        "posegraph/parking-garage.g2o",
    ) else {
        return;
    };
    let g2o = slamkit_io::g2o::read_g2o(&path).unwrap();
    assert_eq!((g2o.vertices.len(), g2o.edges.len()), (1661, 6275));
    let mut graph = PoseGraph::from_g2o(&g2o).unwrap();
    let summary = graph.optimize(&LmConfig::default());
    let initial = (summary.initial_cost - GTSAM_INITIAL_COST).abs() / GTSAM_INITIAL_COST;
    let final_ = (summary.final_cost - GTSAM_FINAL_COST).abs() / GTSAM_FINAL_COST;
    assert!(
        initial < 1e-9,
        "initial cost {} ({initial:e})",
        summary.initial_cost
    );
    assert!(
        final_ < 1e-4,
        "final cost {} ({final_:e})",
        summary.final_cost
    );
    assert!((graph.cost() - summary.final_cost).abs() < 1e-12);
    assert_eq!(graph.nodes()[0], g2o.vertices[0].world_from_vertex);
}
