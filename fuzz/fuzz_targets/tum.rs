//! Trajectory parser (TUM / KITTI / EuRoC CSV, format told from content) on arbitrary text:
//! never panics; an accepted trajectory is non-empty with unit rotations.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::trajectory_file::parse_trajectory;

fuzz_target!(|text: &str| {
    if let Ok((trajectory, _format)) = parse_trajectory(text) {
        assert!(!trajectory.is_empty());
        for p in &trajectory.poses {
            let q = p.pose.rotation.coords;
            assert!(q.iter().all(|c| c.is_finite()), "{p:?}");
            assert!((q.norm() - 1.0).abs() < 1e-6, "{p:?}");
        }
    }
});
