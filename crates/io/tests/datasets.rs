//! Readers and writers on the real files under `$SLAMKIT_DATA` (see its CAMERA_SOURCES.md for
//! where each file comes from). Each test reports itself skipped when the variable is unset.

use std::path::PathBuf;

use slamkit_core::Trajectory;
use slamkit_io::{read_trajectory, write_tum, IoError, TrajectoryFormat};

/// `$SLAMKIT_DATA/<rel>`, or `None` (with a skip message) when the variable is unset.
fn data(test: &str, rel: &str) -> Option<PathBuf> {
    match std::env::var("SLAMKIT_DATA") {
        Ok(root) => Some(PathBuf::from(root).join(rel)),
        Err(_) => {
            eprintln!("skipped: {test}: SLAMKIT_DATA not set");
            None
        }
    }
}

/// Largest difference of timestamps or homogeneous-matrix entries between two trajectories.
fn max_diff(a: &Trajectory, b: &Trajectory) -> f64 {
    assert_eq!(a.len(), b.len());
    a.poses
        .iter()
        .zip(&b.poses)
        .map(|(p, q)| {
            let dm = (p.pose.to_homogeneous() - q.pose.to_homogeneous())
                .abs()
                .max();
            dm.max((p.timestamp - q.timestamp).abs())
        })
        .fold(0.0, f64::max)
}

/// Checks (translation, quaternion x y z w) of a pose against the values printed in a file.
fn assert_pose(traj: &Trajectory, index: usize, t: [f64; 3], q_xyzw: [f64; 4], tol: f64) {
    let p = &traj.poses[index].pose;
    for (got, want) in p.translation.vector.iter().zip(t) {
        assert!((got - want).abs() < tol, "translation {got} vs {want}");
    }
    let n = q_xyzw.iter().map(|v| v * v).sum::<f64>().sqrt();
    let c = p.rotation.coords;
    let sign = if c.w * q_xyzw[3] < 0.0 { -1.0 } else { 1.0 };
    for (got, want) in c.iter().zip(q_xyzw) {
        assert!(
            (sign * got - want / n).abs() < tol,
            "quaternion {c:?} vs {q_xyzw:?}"
        );
    }
}

#[test]
fn every_reference_trajectory_reads_and_round_trips_through_tum() {
    let Some(root) = data("every_reference_trajectory", "trajectories") else {
        return;
    };
    let expected: &[(&str, usize, TrajectoryFormat)] = &[
        (
            "evo_test_data/freiburg1_xyz-groundtruth.txt",
            3000,
            TrajectoryFormat::Tum,
        ),
        (
            "evo_test_data/freiburg1_xyz-rgbdslam.txt",
            788,
            TrajectoryFormat::Tum,
        ),
        (
            "evo_test_data/fr2_desk_groundtruth.txt",
            20957,
            TrajectoryFormat::Tum,
        ),
        (
            "evo_test_data/fr2_desk_ORB.txt",
            2893,
            TrajectoryFormat::Tum,
        ),
        ("evo_test_data/V102.txt", 807, TrajectoryFormat::Tum),
        (
            "evo_test_data/V102_groundtruth.csv",
            16702,
            TrajectoryFormat::EurocCsv,
        ),
        (
            "evo_test_data/KITTI_00_gt.txt",
            4541,
            TrajectoryFormat::Kitti,
        ),
        (
            "evo_test_data/KITTI_00_ORB.txt",
            4541,
            TrajectoryFormat::Kitti,
        ),
        (
            "evo_test_data/KITTI_00_SPTAM.txt",
            4541,
            TrajectoryFormat::Kitti,
        ),
        (
            "kitti_odometry_gt_poses/00.txt",
            4541,
            TrajectoryFormat::Kitti,
        ),
        (
            "kitti_odometry_gt_poses/02.txt",
            4661,
            TrajectoryFormat::Kitti,
        ),
        (
            "kitti_odometry_gt_poses/03.txt",
            801,
            TrajectoryFormat::Kitti,
        ),
        (
            "kitti_odometry_gt_poses/04.txt",
            271,
            TrajectoryFormat::Kitti,
        ),
        (
            "kitti_odometry_gt_poses/05.txt",
            2761,
            TrajectoryFormat::Kitti,
        ),
        (
            "kitti_odometry_gt_poses/06.txt",
            1101,
            TrajectoryFormat::Kitti,
        ),
        (
            "kitti_odometry_gt_poses/07.txt",
            1101,
            TrajectoryFormat::Kitti,
        ),
        (
            "kitti_odometry_gt_poses/08.txt",
            4071,
            TrajectoryFormat::Kitti,
        ),
        (
            "kitti_odometry_gt_poses/09.txt",
            1591,
            TrajectoryFormat::Kitti,
        ),
        (
            "kitti_odometry_gt_poses/10.txt",
            1201,
            TrajectoryFormat::Kitti,
        ),
        ("mrpt/mrpt_aces_rbpfICP.tum", 7374, TrajectoryFormat::Tum),
        ("mrpt/mrpt_intel_icpLM.tum", 13631, TrajectoryFormat::Tum),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (rel, count, format) in expected {
        let (traj, got_format) = read_trajectory(&root.join(rel)).unwrap();
        assert_eq!((traj.len(), got_format), (*count, *format), "{rel}");
        let out = dir.path().join("back.tum");
        write_tum(&out, &traj).unwrap();
        let (back, back_format) = read_trajectory(&out).unwrap();
        assert_eq!(back_format, TrajectoryFormat::Tum);
        let diff = max_diff(&traj, &back);
        assert!(diff < 1e-9, "{rel}: round trip differs by {diff}");
    }
}

#[test]
fn reference_pose_values_match_the_files() {
    let Some(root) = data("reference_pose_values", "trajectories/evo_test_data") else {
        return;
    };
    // freiburg1_xyz-groundtruth.txt, first line:
    // 1305031098.6659 1.3563 0.6305 1.6380 0.6132 0.5962 -0.3311 -0.3986
    let (tum, _) = read_trajectory(&root.join("freiburg1_xyz-groundtruth.txt")).unwrap();
    assert!((tum.poses[0].timestamp - 1_305_031_098.665_9).abs() < 1e-6);
    assert_pose(
        &tum,
        0,
        [1.3563, 0.6305, 1.6380],
        [0.6132, 0.5962, -0.3311, -0.3986],
        1e-9,
    );
    // V102_groundtruth.csv, first row: 1403715524907143168,0.515356,1.996773,0.971104,
    // w 0.161996, x 0.789985, y -0.205376, z 0.554528.
    let (euroc, _) = read_trajectory(&root.join("V102_groundtruth.csv")).unwrap();
    assert!((euroc.poses[0].timestamp - 1_403_715_524.907_143).abs() < 1e-6);
    let q = [0.789985, -0.205376, 0.554528, 0.161996];
    assert_pose(&euroc, 0, [0.515356, 1.996773, 0.971104], q, 1e-9);
    let last = euroc.poses.last().unwrap().timestamp;
    assert!((last - 1_403_715_608.412_143).abs() < 1e-6);
    // KITTI_00_gt.txt, second line: t = (-4.690294e-02, -2.839928e-02, 8.586941e-01).
    let (kitti, _) = read_trajectory(&root.join("KITTI_00_gt.txt")).unwrap();
    assert_eq!(kitti.poses[1].timestamp, 1.0);
    let t = kitti.poses[1].pose.translation.vector;
    assert!(
        (t - nalgebra::Vector3::new(-4.690294e-02, -2.839928e-02, 8.586941e-01)).norm() < 1e-12
    );
    // Line 2's rotation entry R[0,1] = 5.272628e-04, kept through re-orthonormalisation.
    let r = kitti.poses[1].pose.rotation.to_rotation_matrix();
    assert!((r[(0, 1)] - 5.272628e-04).abs() < 1e-6);
}

#[test]
fn timestamp_only_file_is_rejected_naming_line_1() {
    let Some(path) = data(
        "timestamp_only_file",
        "trajectories/evo_test_data/KITTI_00_gt_times.txt",
    ) else {
        return;
    };
    match read_trajectory(&path) {
        Err(IoError::Parse { file, line, .. }) => {
            assert!(file.ends_with("KITTI_00_gt_times.txt"));
            assert_eq!(line, 1);
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
}
