//! Readers and writers on the real files under `$SLAMKIT_DATA` (see its CAMERA_SOURCES.md for
//! where each file comes from). Each test reports itself skipped when the variable is unset.

// The fixture helpers below are test code too, outside `#[test]` functions.

use slamkit_testdata::data;
use std::path::Path;

use nalgebra::{Quaternion, Translation3, UnitQuaternion, Vector3};
use slamkit_core::{Pose3, Trajectory};
use slamkit_io::tum_rgbd::{TumCamera, TumRgbdConfig};
use slamkit_io::{kitti, seven_scenes, tum_rgbd, Dataset, DatasetFormat};
use slamkit_io::{read_trajectory, write_tum, IoError, TrajectoryFormat};

/// `$SLAMKIT_DATA/<rel>`, or `None` (with a skip message) when the variable is unset.
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
        let diff = traj.max_difference(&back).unwrap();
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

// ---------------------------------------------------------------------------------------------
// Dataset folders.

fn assert_close(got: f64, want: f64, tol: f64, what: &str) {
    assert!((got - want).abs() <= tol, "{what}: {got} vs {want}");
}

#[test]
fn kitti_06_clip_frames_calibration_and_ground_truth() {
    // KITTI odometry 06 frames 0–50 (niconielsen32/VisualSLAM, CAMERA_SOURCES.md section 1).
    let Some(dir) = data("kitti_06_clip", "stereo/kitti_odometry_06_0000-0050") else {
        return;
    };
    let Dataset::Stereo(seq) = Dataset::open(&dir, DatasetFormat::Kitti).unwrap() else {
        panic!("KITTI is stereo");
    };
    assert_eq!(seq.frames.len(), 51);
    assert_eq!(seq.frames[0].timestamp, 0.0);
    assert_close(
        seq.frames[50].timestamp,
        5.0,
        1e-12,
        "last stamp (10 Hz, no times.txt)",
    );
    let k = seq.left_camera.intrinsics;
    assert_eq!(
        (k.fx, k.fy, k.cx, k.cy),
        (707.0912, 707.0912, 601.8873, 183.1104)
    );
    assert_eq!((k.width, k.height), (1226, 370));
    assert_close(seq.baseline_m(), 0.5372, 1e-4, "baseline");
    assert!(seq.rectified);
    // poses.txt last line: t = (-9.814360e-01, -1.190278e+00, 5.983857e+01).
    let gt = seq.ground_truth.as_ref().unwrap();
    assert_eq!(gt.len(), 51);
    assert_close(gt.poses[50].timestamp, 5.0, 1e-12, "GT stamp");
    let t = gt.poses[50].pose.translation.vector;
    assert!((t - Vector3::new(-9.814360e-01, -1.190278e+00, 5.983857e+01)).norm() < 1e-9);
    let images = seq.load(&seq.frames[50]).unwrap();
    assert_eq!((images.left.width(), images.right.height()), (1226, 370));
    // The label-less upstream calibration gives the same numbers.
    let raw = std::fs::read_to_string(dir.join("calib_as_committed.txt")).unwrap();
    let labelled = std::fs::read_to_string(dir.join("calib.txt")).unwrap();
    assert_eq!(
        kitti::parse_calib(&raw).unwrap(),
        kitti::parse_calib(&labelled).unwrap()
    );
}

#[test]
fn seven_scenes_redkitchen_frames_intrinsics_and_poses() {
    // 7-Scenes RedKitchen frames 0–599 (andyzeng/tsdf-fusion-python, section 7).
    let Some(dir) = data(
        "seven_scenes_redkitchen",
        "rgbd/7scenes_redkitchen_frames_0000-0599",
    ) else {
        return;
    };
    let seq = seven_scenes::open(&dir).unwrap();
    assert_eq!(seq.frames.len(), 600);
    assert_eq!(seq.frames[0].timestamp, 0.0);
    assert_close(seq.frames[599].timestamp, 599.0 / 30.0, 1e-12, "last stamp");
    let k = seq.depth_camera.intrinsics;
    assert_eq!(
        (k.fx, k.fy, k.cx, k.cy, k.width, k.height),
        (585.0, 585.0, 320.0, 240.0, 640, 480)
    );
    assert_eq!(seq.depth_units_per_metre, 1000.0);
    // frame-000000.pose.txt translation column.
    let gt = seq.ground_truth.as_ref().unwrap();
    assert_eq!(gt.len(), 600);
    let t = gt.poses[0].pose.translation.vector;
    let want = Vector3::new(-3.4045634e-01, 1.6469818e-02, 2.9656917e-01);
    assert!((t - want).norm() < 1e-9);
    // Re-orthonormalised rotation stays within the file's 4e-4 of the raw matrix.
    let r = gt.poses[0].pose.rotation.to_rotation_matrix();
    assert_close(r[(0, 0)], 0.9093129, 4e-4, "R00");
    assert_close(r[(1, 2)], 0.045279626, 4e-4, "R12");
    // Median step between frames is millimetres (CAMERA_SOURCES.md: 7.4 mm over 1000 frames).
    let mut steps: Vec<f64> = gt
        .poses
        .windows(2)
        .map(|w| (w[1].pose.translation.vector - w[0].pose.translation.vector).norm())
        .collect();
    steps.sort_by(f64::total_cmp);
    assert!(
        (0.003..0.015).contains(&steps[steps.len() / 2]),
        "median step {}",
        steps[300]
    );
    let images = seq.load(&seq.frames[0]).unwrap();
    let depth = images.depth_m.data();
    let invalid = depth.iter().filter(|d| **d == 0.0).count() as f64 / depth.len() as f64;
    assert!(
        (0.05..0.25).contains(&invalid),
        "invalid fraction {invalid}"
    );
    assert!(depth.iter().all(|d| (0.0..10.0).contains(d)));
    // Ground truth written as TUM reads back to the same poses.
    let out = tempfile::tempdir().unwrap();
    let tum = out.path().join("gt.tum");
    Dataset::Rgbd(seq.clone())
        .write_ground_truth_tum(&tum)
        .unwrap();
    let (back, _) = read_trajectory(&tum).unwrap();
    assert!(gt.max_difference(&back).unwrap() < 1e-9);
}

#[test]
fn redwood_five_frames_camera_and_log() {
    // Open3D TestData RGBD (Redwood, section 3).
    let Some(dir) = data(
        "redwood_five_frames",
        "rgbd/open3d_testdata_redwood_5frames",
    ) else {
        return;
    };
    let Dataset::Rgbd(seq) = Dataset::open(&dir, DatasetFormat::Redwood).unwrap() else {
        panic!("Redwood is RGB-D");
    };
    assert_eq!(seq.frames.len(), 5);
    assert_close(seq.frames[4].timestamp, 4.0 / 30.0, 1e-12, "last stamp");
    let k = seq.color_camera.intrinsics;
    assert_eq!(
        (k.fx, k.fy, k.cx, k.cy, k.width, k.height),
        (525.0, 525.0, 319.5, 239.5, 640, 480)
    );
    // trajectory.log first block, translation column.
    let gt = seq.ground_truth.as_ref().unwrap();
    assert_eq!(gt.len(), 5);
    let want = Vector3::new(-0.31057997014702826, 0.5730122438481298, 2.1264800183565487);
    assert!((gt.poses[0].pose.translation.vector - want).norm() < 1e-12);
    let images = seq.load(&seq.frames[2]).unwrap();
    assert_eq!(images.color.width(), 640);
    let valid: Vec<f32> = images
        .depth_m
        .data()
        .iter()
        .copied()
        .filter(|d| *d > 0.0)
        .collect();
    let mean = valid.iter().sum::<f32>() / valid.len() as f32;
    assert!((0.5..5.0).contains(&mean), "mean depth {mean} m");
}

#[test]
fn euroc_micro_frames_calibration_and_ground_truth() {
    // EuRoC V1_01_easy micro clip (Kimera-VIO test data + original GT, section 6).
    let Some(dir) = data("euroc_micro", "stereo/euroc_v101_micro") else {
        return;
    };
    let Dataset::Stereo(seq) = Dataset::open(&dir, DatasetFormat::Euroc).unwrap() else {
        panic!("EuRoC is stereo");
    };
    // data.csv lists 95 rows; only the first 20 PNGs of each camera are kept.
    assert_eq!(seq.frames.len(), 20);
    assert_close(
        seq.frames[0].timestamp,
        1_403_715_273.262_143,
        1e-6,
        "first stamp",
    );
    assert_close(
        seq.frames[19].timestamp,
        1_403_715_274.212_143,
        1e-6,
        "last stamp",
    );
    let cam0 = seq.left_camera;
    let k = cam0.intrinsics;
    assert_eq!(
        (k.fx, k.fy, k.cx, k.cy, k.width, k.height),
        (458.654, 457.296, 367.215, 248.375, 752, 480)
    );
    assert_eq!(
        (cam0.distortion.k1, cam0.distortion.p2),
        (-0.28340811, 1.76187114e-05)
    );
    assert_eq!(seq.right_camera.intrinsics.fx, 457.587);
    assert_close(seq.baseline_m(), 0.1101, 1e-4, "baseline");
    assert!(!seq.rectified);
    // GT: world_from_cam0 = world_from_body (first CSV row) * body_from_cam0 (cam0 T_BS).
    let gt = seq.ground_truth.as_ref().unwrap();
    assert_eq!(gt.len(), 999);
    let q = Quaternion::new(0.060514, -0.828459, -0.058956, -0.553641);
    let world_from_body = Pose3::from_parts(
        Translation3::new(0.878612, 2.142470, 0.947262),
        UnitQuaternion::from_quaternion(q),
    );
    let body_from_cam0_t = Vector3::new(-0.0216401454975, -0.064676986768, 0.00981073058949);
    let want = world_from_body * nalgebra::Point3::from(body_from_cam0_t);
    assert!((gt.poses[0].pose.translation.vector - want.coords).norm() < 1e-9);
    let images = seq.load(&seq.frames[0]).unwrap();
    assert_eq!((images.left.width(), images.left.height()), (752, 480));
}

#[test]
fn tum_folder_from_the_fr3_sample_frame() {
    // TUM fr3/long_office_household first frame (Open3D TestData, section 4), laid out as a
    // TUM folder with hand-written lists and ground truth.
    let Some(src) = data(
        "tum_fr3_sample",
        "rgbd/tum_fr3_long_office_household_samples",
    ) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp
        .path()
        .join("rgbd_dataset_freiburg3_long_office_household");
    for sub in ["rgb", "depth"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    std::fs::copy(
        src.join("TUM_color.png"),
        dir.join("rgb/1341847980.722988.png"),
    )
    .unwrap();
    std::fs::copy(
        src.join("TUM_depth.png"),
        dir.join("depth/1341847980.723020.png"),
    )
    .unwrap();
    let rgb = "# color images\n1341847980.722988 rgb/1341847980.722988.png\n\
               1341847981.0 rgb/missing-depth.png\n";
    std::fs::write(dir.join("rgb.txt"), rgb).unwrap();
    std::fs::write(
        dir.join("depth.txt"),
        "1341847980.723020 depth/1341847980.723020.png\n",
    )
    .unwrap();
    let gt = "# timestamp tx ty tz qx qy qz qw\n1341847980.7200 -0.6832 2.6909 1.7373 0.0003 0.8617 -0.5072 -0.0145\n";
    std::fs::write(dir.join("groundtruth.txt"), gt).unwrap();

    let Dataset::Rgbd(seq) = Dataset::open(&dir, DatasetFormat::Tum).unwrap() else {
        panic!("TUM is RGB-D");
    };
    assert_eq!(
        seq.frames.len(),
        1,
        "the second colour image has no depth within 20 ms"
    );
    assert_eq!(seq.frames[0].timestamp, 1341847980.722988);
    let k = seq.color_camera.intrinsics;
    assert_eq!(
        (k.fx, k.fy, k.cx, k.cy),
        (535.4, 539.2, 320.1, 247.6),
        "fr3 from folder name"
    );
    assert_eq!(seq.ground_truth.as_ref().unwrap().len(), 1);
    let images = seq.load(&seq.frames[0]).unwrap();
    assert_eq!((images.color.width(), images.depth_m.height()), (640, 480));
    let valid: Vec<f32> = images
        .depth_m
        .data()
        .iter()
        .copied()
        .filter(|d| *d > 0.0)
        .collect();
    let mean = valid.iter().sum::<f32>() / valid.len() as f32;
    assert!(
        (0.5..5.0).contains(&mean),
        "mean depth {mean} m at 5000 units/m"
    );

    // A looser association window and the fr1 calibration, chosen explicitly.
    let config = TumRgbdConfig {
        max_time_diff_s: 0.5,
        camera: TumCamera::Fr1,
        ..Default::default()
    };
    let seq = tum_rgbd::open(&dir, &config).unwrap();
    assert_eq!(
        seq.frames.len(),
        1,
        "still one depth image for two colour images"
    );
    assert_eq!(seq.color_camera.distortion.k1, 0.262383);
}

// ---------------------------------------------------------------------------------------------
// Hand-made broken folders: every defect is an error naming the file and line or frame.

fn write(dir: &Path, rel: &str, content: &str) {
    let path = dir.join(rel);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, content).unwrap();
}

fn gray_png(dir: &Path, rel: &str) {
    let path = dir.join(rel);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    image::GrayImage::from_pixel(8, 6, image::Luma([90]))
        .save(path)
        .unwrap();
}

fn depth_png(dir: &Path, rel: &str, value: u16) {
    let path = dir.join(rel);
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    image::ImageBuffer::from_pixel(8, 6, image::Luma([value]))
        .save(path)
        .unwrap();
}

/// The (file, line) of a parse error, or a panic naming what came instead.
fn parse_error<T: std::fmt::Debug>(r: Result<T, IoError>) -> (String, usize) {
    match r {
        Err(IoError::Parse { file, line, .. }) => (file, line),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

fn error_text<T: std::fmt::Debug>(r: Result<T, IoError>) -> String {
    r.unwrap_err().to_string()
}

#[test]
fn broken_tum_folders() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let config = TumRgbdConfig::default();
    assert!(error_text(tum_rgbd::open(dir, &config)).contains("rgb.txt"));
    gray_png(dir, "rgb/1.000.png");
    write(dir, "depth/1.010.png", "not a png");
    write(
        dir,
        "rgb.txt",
        "# list\n1.000 rgb/1.000.png\nabc rgb/x.png\n",
    );
    write(dir, "depth.txt", "1.010 depth/1.010.png\n");
    let (file, line) = parse_error(tum_rgbd::open(dir, &config));
    assert!(file.ends_with("rgb.txt") && line == 3);
    write(dir, "rgb.txt", "1.000\n");
    assert_eq!(parse_error(tum_rgbd::open(dir, &config)).1, 1);
    write(dir, "rgb.txt", "9.000 rgb/1.000.png\n");
    assert!(error_text(tum_rgbd::open(dir, &config)).contains("no colour/depth pair"));
    write(dir, "rgb.txt", "1.000 rgb/1.000.png\n");
    write(
        dir,
        "groundtruth.txt",
        "# gt\n1.0 0 0 0 0 0 0 1\n1.1 0 0 nan 0 0 0 1\n",
    );
    let (file, line) = parse_error(tum_rgbd::open(dir, &config));
    assert!(file.ends_with("groundtruth.txt") && line == 3);
    // The folder opens once the ground truth is fixed; the corrupt depth image fails at load.
    write(dir, "groundtruth.txt", "1.0 0 0 0 0 0 0 1\n");
    let seq = tum_rgbd::open(dir, &config).unwrap();
    let err = error_text(seq.load(&seq.frames[0]));
    assert!(err.contains("1.010.png"), "{err}");
}

#[test]
fn broken_kitti_folders() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let p0 = "P0: 700 0 600 0 0 700 180 0 0 0 1 0\n";
    write(
        dir,
        "calib.txt",
        &format!("{p0}P1: 700 0 600 -350 0 700 180 0 0 0 1 0\n"),
    );
    assert!(
        matches!(kitti::open(dir), Err(IoError::Io { .. })),
        "no image_0/"
    );
    for rel in [
        "image_0/000000.png",
        "image_0/000001.png",
        "image_1/000000.png",
    ] {
        gray_png(dir, rel);
    }
    // a missing right image is a frame that fails to load, not a broken dataset
    let seq = kitti::open(dir).unwrap();
    assert_eq!(seq.frames.len(), 2);
    let err = error_text(seq.load(&seq.frames[1]));
    assert!(err.contains("image_1/000001.png"), "{err}");
    gray_png(dir, "image_1/000001.png");
    write(dir, "times.txt", "0.0\n");
    let err = error_text(kitti::open(dir));
    assert!(err.contains("1 timestamps for frames 0 to 1"), "{err}");
    write(dir, "times.txt", "0.0\nx\n");
    let (file, line) = parse_error(kitti::open(dir));
    assert!(file.ends_with("times.txt") && line == 2);
    write(dir, "times.txt", "0.0\n0.25\n");
    write(
        dir,
        "poses.txt",
        "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n",
    );
    let (file, line) = parse_error(kitti::open(dir));
    assert!(file.ends_with("poses.txt") && line == 2);
    write(
        dir,
        "poses.txt",
        "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n",
    );
    let seq = kitti::open(dir).unwrap();
    assert_eq!(seq.frames[1].timestamp, 0.25);
    assert_eq!(seq.ground_truth.as_ref().unwrap().poses[1].timestamp, 0.25);
    assert_eq!(
        (seq.left_camera.intrinsics.width, seq.baseline_m()),
        (8, 0.5)
    );
    write(dir, "calib.txt", p0);
    assert!(error_text(kitti::open(dir)).contains("calib.txt"));
}

#[test]
fn broken_seven_scenes_folders() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    assert!(
        matches!(seven_scenes::open(dir), Err(IoError::Invalid { .. })),
        "empty"
    );
    let pose = "1 0 0 0.5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
    gray_png(dir, "frame-000005.color.png");
    depth_png(dir, "frame-000005.depth.png", 65535);
    write(dir, "frame-000005.pose.txt", pose);
    gray_png(dir, "frame-000006.color.png");
    let seq = seven_scenes::open(dir).unwrap();
    let err = error_text(seq.load(&seq.frames[1]));
    assert!(err.contains("frame-000006.depth.png"), "{err}");
    depth_png(dir, "frame-000006.depth.png", 1500);
    write(
        dir,
        "frame-000006.pose.txt",
        "1 0 0 0\n0 1 0 0\n0 0 1 zero\n0 0 0 1\n",
    );
    let (file, line) = parse_error(seven_scenes::open(dir));
    assert!(file.ends_with("frame-000006.pose.txt") && line == 3);
    std::fs::remove_file(dir.join("frame-000006.pose.txt")).unwrap();
    // Numbering starts at 5; frame 6 has no pose; 65535 is invalid depth.
    let seq = seven_scenes::open(dir).unwrap();
    assert_eq!(seq.frames.len(), 2);
    assert_eq!(seq.frames[0].timestamp, 5.0 / 30.0);
    assert_eq!(seq.ground_truth.as_ref().unwrap().len(), 1);
    assert_eq!(seq.depth_camera.intrinsics.fx, 585.0);
    assert_eq!(
        seq.load(&seq.frames[0]).unwrap().depth_m.get(0, 0),
        Some(&0.0)
    );
    assert_eq!(
        seq.load(&seq.frames[1]).unwrap().depth_m.get(7, 5),
        Some(&1.5)
    );
    write(dir, "camera-intrinsics.txt", "585 0 320\n0 585 240\n");
    assert!(error_text(seven_scenes::open(dir)).contains("camera-intrinsics.txt"));
}

#[test]
fn broken_redwood_folders() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    gray_png(dir, "color/00000.png");
    gray_png(dir, "color/00001.png");
    depth_png(dir, "depth/00000.png", 1000);
    let redwood = |d: &Path| slamkit_io::redwood::open(d, &Default::default());
    let seq = redwood(dir).unwrap();
    assert_eq!(seq.frames.len(), 2);
    let err = error_text(seq.load(&seq.frames[1]));
    assert!(err.contains("depth/00001.png"), "{err}");
    depth_png(dir, "depth/00001.png", 1000);
    write(
        dir,
        "trajectory.log",
        "0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n1 1 2\n1 0 0 0\n",
    );
    let (file, line) = parse_error(redwood(dir));
    assert!(file.ends_with("trajectory.log") && line == 6);
    std::fs::remove_file(dir.join("trajectory.log")).unwrap();
    write(
        dir,
        "camera_primesense.json",
        "{\"width\": 640, \"height\": 480,\n\"intrinsic_matrix\": [1]}",
    );
    let (file, line) = parse_error(redwood(dir));
    assert!(file.ends_with("camera_primesense.json") && line == 2);
    std::fs::remove_file(dir.join("camera_primesense.json")).unwrap();
    let seq = redwood(dir).unwrap();
    assert!(seq.ground_truth.is_none());
    assert_eq!(
        seq.color_camera.intrinsics.width, 8,
        "default camera at the image size"
    );
}

#[test]
fn broken_euroc_folders() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let yaml = "T_BS:\n  data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n\
                resolution: [8, 6]\nintrinsics: [400, 400, 4, 3]\n\
                distortion_coefficients: [0, 0, 0, 0]\n";
    write(dir, "mav0/cam0/sensor.yaml", yaml);
    assert!(error_text(slamkit_io::euroc::open(dir)).contains("cam1/sensor.yaml"));
    write(
        dir,
        "mav0/cam1/sensor.yaml",
        &yaml.replace("0, 0, 1, 0, 0, 0, 0, 1]", "0, 0, 1, 0.1, 0, 0, 0, 1]"),
    );
    write(
        dir,
        "mav0/cam0/data.csv",
        "#timestamp [ns],filename\n1000000000,a.png\n15e8,b.png\n",
    );
    let (file, line) = parse_error(slamkit_io::euroc::open(dir));
    assert!(file.ends_with("data.csv") && line == 3);
    write(
        dir,
        "mav0/cam0/data.csv",
        "#timestamp [ns],filename\n1000000000,a.png\n1500000000,b.png\n",
    );
    write(
        dir,
        "mav0/cam1/data.csv",
        "1000000000,a.png\n1500000000,b.png\n",
    );
    assert!(error_text(slamkit_io::euroc::open(dir)).contains("no cam0 image on disk"));
    for rel in [
        "mav0/cam0/data/a.png",
        "mav0/cam0/data/b.png",
        "mav0/cam1/data/a.png",
    ] {
        gray_png(dir, rel);
    }
    let seq = slamkit_io::euroc::open(dir).unwrap();
    assert_eq!(
        seq.frames.len(),
        2,
        "b.png's missing right image fails at load"
    );
    assert_eq!(seq.frames[0].timestamp, 1.0);
    let err = error_text(seq.load(&seq.frames[1]));
    assert!(err.contains("cam1/data/b.png"), "{err}");
    assert!((seq.baseline_m() - 0.1).abs() < 1e-12);
}

#[test]
fn dataset_format_names() {
    for (name, format) in [
        ("tum", DatasetFormat::Tum),
        ("kitti", DatasetFormat::Kitti),
        ("7scenes", DatasetFormat::SevenScenes),
        ("redwood", DatasetFormat::Redwood),
        ("euroc", DatasetFormat::Euroc),
    ] {
        assert_eq!(name.parse::<DatasetFormat>().unwrap(), format);
    }
    assert!("bag".parse::<DatasetFormat>().is_err());
}
