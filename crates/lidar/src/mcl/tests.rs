use super::*;
use crate::rbpf::tests::{room_loop, simulate};
use slamkit_map::OccupancyGridConfig;

/// The simulated room mapped from scans at the true poses of the room loop.
fn room_map() -> OccupancyGrid {
    let truth = room_loop();
    let (scans, _) = simulate(&truth);
    let mut grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
    for (scan, pose) in scans.iter().zip(&truth) {
        grid.insert_scan(scan, pose).unwrap();
    }
    grid
}

fn position_error(a: &Pose2, b: &Pose2) -> f64 {
    (a.translation.vector - b.translation.vector).norm()
}

#[test]
fn particle_count_follows_the_formula() {
    // S = 100 m², r = 0.25 m, θ = 60°: P = 0.19635 / 100 / 6 = 3.2725e-4, and
    // ln(0.1) / ln(1 − P) = 7035.03, rounded up so the 90 % guarantee holds.
    let n = global_particle_count(100.0, 0.25, 60.0);
    let p: f64 = PI * 0.0625 / 100.0 / 6.0;
    assert_eq!(n, (0.1f64.ln() / (1.0 - p).ln()).ceil() as usize);
    assert_eq!(n, 7036);
    assert_eq!(global_particle_count(0.01, 0.25, 360.0), 1);
    // A free area inside the capture circle leaves only the heading to find: ln 0.1 / ln(5/6).
    assert_eq!(global_particle_count(0.01, 0.25, 60.0), 13);
    assert_eq!(global_particle_count(0.0, 0.25, 60.0), 1);
    assert_eq!(global_particle_count(f64::NAN, 0.25, 60.0), 1);
}

#[test]
fn converges_from_a_global_start_in_the_simulated_room() {
    let map = room_map();
    let truth: Vec<Pose2> = room_loop().into_iter().skip(30).take(120).collect();
    let (scans, _) = simulate(&truth);
    let out = run_mcl(&scans, &map, &MclConfig::default(), |_| {}).unwrap();
    let stats = out.stats;
    assert!(
        stats.free_area_m2 > 80.0 && stats.free_area_m2 < 110.0,
        "{stats:?}"
    );
    assert!(stats.global_particles > 5000, "{stats:?}");
    let first = stats.first_converged_scan.expect("converges");
    assert!(first < 60, "converged at scan {first}");
    // The map frame is the world frame of the simulation: compare directly.
    for (i, (est, t)) in out.poses.iter().zip(&truth).enumerate().skip(first + 10) {
        let err = position_error(est, t);
        assert!(err < 0.2, "scan {i}: error {err} m");
    }
    assert_eq!(out.trajectory.len(), scans.len());
}

#[test]
fn recovers_after_being_kidnapped() {
    let map = room_map();
    let path = room_loop();
    // Drive the first half of the loop, then get carried to the start of the last leg while the
    // odometry notices nothing.
    let mut truth: Vec<Pose2> = path[20..110].to_vec();
    let jump = path.len() - 70;
    truth.extend_from_slice(&path[jump..jump + 60]);
    let (mut scans, _) = simulate(&truth);
    // Odometry as if the robot had kept going straight from where it was.
    let (_, continuous) = simulate(&path[20..170]);
    for (scan, odo) in scans.iter_mut().zip(&continuous) {
        scan.odometry = Some(*odo);
    }
    let out = run_mcl(&scans, &map, &MclConfig::default(), |_| {}).unwrap();
    let end = out.poses.len() - 1;
    let err = position_error(&out.poses[end], &truth[end]);
    assert!(
        err < 0.2,
        "after the kidnapping: error {err} m, {:?}",
        out.stats
    );
    assert!(out.stats.relocalisations + usize::from(out.stats.injected > 0) > 0);
}

#[test]
fn empty_map_is_an_error_not_a_panic() {
    let map = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
    assert!(Mcl::new(&map, MclConfig::default()).is_err());
    let bad = MclConfig {
        beams: 0,
        ..MclConfig::default()
    };
    assert!(matches!(
        Mcl::new(&room_map(), bad),
        Err(LidarError::InvalidConfig { .. })
    ));
}
