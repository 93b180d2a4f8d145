use super::*;
use crate::rbpf::tests::{room_loop, simulate};
use slamkit_map::OccupancyGridConfig;
use std::sync::Arc;

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

/// The simulated room mapped from scans at the true poses of the room loop moved by `shift`.
fn shifted_room_map(shift: Vector2<f64>) -> OccupancyGrid {
    let truth = room_loop();
    let (scans, _) = simulate(&truth);
    let mut grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
    for (scan, pose) in scans.iter().zip(&truth) {
        let moved = Pose2::new(pose.translation.vector + shift, pose.rotation.angle());
        grid.insert_scan(scan, &moved).unwrap();
    }
    grid
}

#[test]
fn particles_moved_to_another_map_are_weighed_against_it() {
    let config = MclConfig::default();
    let shift = Vector2::new(0.3, 0.0);
    let here = Arc::new(MclMap::new(&room_map(), &config.likelihood).unwrap());
    let there = Arc::new(MclMap::new(&shifted_room_map(shift), &config.likelihood).unwrap());
    let truth: Vec<Pose2> = room_loop().into_iter().skip(30).take(160).collect();
    let (scans, odometry) = simulate(&truth);
    let mut moved = Mcl::on_map(Arc::clone(&here), config.clone()).unwrap();
    let mut stayed = Mcl::on_map(here, config.clone()).unwrap();
    for (k, (scan, step)) in scans.iter().zip(odometry.windows(2)).enumerate() {
        if k == 60 {
            // the filter has converged in the first map: same particles after the move
            let before = moved.particles().to_vec();
            moved.move_to_map(Arc::clone(&there)).unwrap();
            assert_eq!(moved.particles(), &before[..]);
        }
        for mcl in [&mut moved, &mut stayed] {
            mcl.predict(&(step[0].inverse() * step[1]));
            mcl.correct(scan);
        }
    }
    // the last scans fit the second map 0.3 m further along x
    let end = truth.last().unwrap().translation.vector;
    let offset = |mcl: &Mcl| mcl.estimate().unwrap().world_from_base.translation.vector - end;
    let (m, s) = (offset(&moved), offset(&stayed));
    assert!((m - shift).norm() < 0.1, "moved: offset {m:?}");
    assert!(s.norm() < 0.1, "stayed: offset {s:?}");
    // a map prepared for another sensor model is refused
    let other = MclConfig {
        likelihood: LikelihoodFieldConfig {
            sigma_hit_m: 0.1,
            ..config.likelihood.clone()
        },
        ..config.clone()
    };
    let foreign = Arc::new(MclMap::new(&room_map(), &other.likelihood).unwrap());
    assert!(moved.move_to_map(Arc::clone(&foreign)).is_err());
    assert!(Mcl::on_map(foreign, config).is_err());
}

#[test]
fn spread_after_resampling_is_that_of_the_resampled_cloud() {
    let map = room_map();
    let truth: Vec<Pose2> = room_loop().into_iter().skip(30).take(3).collect();
    let (scans, _) = simulate(&truth);
    let mut mcl = Mcl::new(&map, MclConfig::default()).unwrap();
    // uniform over the free space before any update: the RMS distance to the mean of a
    // uniform 12 × 8 m rectangle is √((12² + 8²) / 12) = 4.16 m; the room's alcove and boxes
    // make it 4.0–4.6 m
    let global = mcl.spread_m();
    assert!((4.0..4.6).contains(&global), "{global}");
    let estimate = mcl.correct(&scans[0]).unwrap();
    assert_eq!(mcl.stats().resamples, 1);
    // after resampling the weights are uniform: the cloud's own spread
    let p = mcl.particles();
    let mean = p
        .iter()
        .fold(Vector2::zeros(), |a, q| a + q.translation.vector)
        / p.len() as f64;
    let rms = (p
        .iter()
        .map(|q| (q.translation.vector - mean).norm_squared())
        .sum::<f64>()
        / p.len() as f64)
        .sqrt();
    assert!(
        (mcl.spread_m() - rms).abs() < 1e-9,
        "{} {rms}",
        mcl.spread_m()
    );
    assert!(estimate.spread_m.is_finite());
}
