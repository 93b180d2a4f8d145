//! g2o pose-graph parser on arbitrary text: never panics; an accepted graph is well-formed
//! (finite unit poses, edges and FIX naming existing vertices, no self-loop, symmetric positive
//! definite information).
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::g2o::parse_g2o;

fuzz_target!(|text: &str| {
    if let Ok(graph) = parse_g2o(text) {
        assert!(!graph.vertices.is_empty());
        let n = graph.vertices.len();
        let poses = graph.vertices.iter().map(|v| v.world_from_vertex);
        for p in poses.chain(graph.edges.iter().map(|e| e.from_from_to)) {
            let q = p.rotation.coords;
            assert!(p.translation.vector.iter().all(|c| c.is_finite()));
            assert!(q.iter().all(|c| c.is_finite()) && (q.norm() - 1.0).abs() < 1e-9);
        }
        for e in &graph.edges {
            assert!(e.from < n && e.to < n && e.from != e.to);
            assert_eq!(e.information, e.information.transpose());
            assert!(e.information.cholesky().is_some());
        }
        assert!(graph.fixed.iter().all(|&i| i < n));
    }
});
