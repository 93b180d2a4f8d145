//! Corrupt and missing images are skipped and counted by the run, all-zero depth and too-dark
//! frames are failed frames of the session, never a panic or an error; the pose holds over
//! them and tracking resumes after.

use std::path::Path;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slamkit_core::camera::{Distortion, Intrinsics, PinholeCamera};
use slamkit_io::{Dataset, RgbdFrame, RgbdSequence};
use slamkit_slam::visual::{self, RunOptions, VisualSlam};
use slamkit_slam::TrackingStatus;
use slamkit_vo::{FailReason, FrameStatus, TrackingMode, VoConfig};

const W: u32 = 160;
const H: u32 = 120;

/// A random texture, smoothed so corners track.
fn texture(seed: u64, brightness: f32) -> image::RgbImage {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let raw: Vec<f32> = (0..W * H).map(|_| rng.gen_range(0.0..255.0)).collect();
    image::RgbImage::from_fn(W, H, |x, y| {
        let at = |dx: i32, dy: i32| {
            let xx = (x as i32 + dx).clamp(0, W as i32 - 1) as u32;
            let yy = (y as i32 + dy).clamp(0, H as i32 - 1) as u32;
            raw[(yy * W + xx) as usize]
        };
        let v = (at(0, 0) * 4.0 + at(1, 0) + at(-1, 0) + at(0, 1) + at(0, -1)) / 8.0;
        let g = (v * brightness) as u8;
        image::Rgb([g, g, g])
    })
}

fn depth(mm: u16) -> image::ImageBuffer<image::Luma<u16>, Vec<u16>> {
    image::ImageBuffer::from_pixel(W, H, image::Luma([mm]))
}

fn frame(dir: &Path, i: usize, color: &str, depth: &str) -> RgbdFrame {
    RgbdFrame {
        index: i,
        timestamp: i as f64 / 30.0,
        color: dir.join(color),
        depth: dir.join(depth),
    }
}

#[test]
fn bad_frames_fail_without_panic_and_tracking_resumes() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    texture(1, 1.0).save(dir.join("good.png")).unwrap();
    texture(1, 0.02).save(dir.join("dark.png")).unwrap();
    depth(2000).save(dir.join("depth.png")).unwrap();
    depth(0).save(dir.join("zero.png")).unwrap();
    std::fs::write(dir.join("corrupt.png"), b"\x89PNG\r\n\x1a\n not really").unwrap();
    let frames = vec![
        frame(dir, 0, "good.png", "depth.png"),
        frame(dir, 1, "good.png", "depth.png"),
        frame(dir, 2, "corrupt.png", "depth.png"),
        frame(dir, 3, "good.png", "missing.png"),
        frame(dir, 4, "good.png", "zero.png"),
        frame(dir, 5, "dark.png", "depth.png"),
        frame(dir, 6, "good.png", "depth.png"),
    ];
    let camera = PinholeCamera::new(
        Intrinsics {
            fx: 150.0,
            fy: 150.0,
            cx: 80.0,
            cy: 60.0,
            width: W as usize,
            height: H as usize,
        },
        Distortion::default(),
    );
    let dataset = Dataset::Rgbd(RgbdSequence {
        root: dir.to_path_buf(),
        frames,
        color_camera: camera,
        depth_camera: camera,
        depth_units_per_metre: 1000.0,
        invalid_depth: Vec::new(),
        ground_truth: None,
    });
    for mode in [TrackingMode::FrameToFrame, TrackingMode::LocalMap] {
        let config = VoConfig {
            mode,
            ..VoConfig::default()
        };
        let mut session = VisualSlam::new(&config, visual::rig_of(&dataset)).unwrap();
        let mut tracking = Vec::new();
        let result = visual::run(
            &mut session,
            dataset.observations(),
            RunOptions::default(),
            |u| tracking.push(u.update.status),
        )
        .unwrap();
        // the corrupt colour image and the missing depth image never reach the session
        assert_eq!((result.stats.frames, result.stats.skipped), (7, 2));
        assert!(
            result.skipped[0].starts_with("frame 2: "),
            "{:?}",
            result.skipped
        );
        let status: Vec<(usize, &FrameStatus)> =
            result.frames.iter().map(|f| (f.index, &f.status)).collect();
        assert_eq!(status.len(), 5, "{status:?}");
        assert!(
            matches!(status[0], (0, FrameStatus::Initialised { .. })),
            "{status:?}"
        );
        assert!(
            matches!(status[1], (1, FrameStatus::Tracked { .. })),
            "{status:?}"
        );
        assert!(
            matches!(status[2], (4, FrameStatus::Failed(_))),
            "{status:?}"
        );
        assert!(
            matches!(
                status[3],
                (5, FrameStatus::Failed(FailReason::TooDark { .. }))
            ),
            "{status:?}"
        );
        assert!(
            matches!(status[4], (6, FrameStatus::Tracked { .. })),
            "{status:?}"
        );
        use TrackingStatus::{Predicted, Tracking};
        assert_eq!(
            tracking,
            [Tracking, Tracking, Predicted, Predicted, Tracking]
        );
        let output = session.finish().unwrap();
        assert_eq!((output.stats.failed, output.stats.processed), (2, 3));
        assert!(!output.point_map.unwrap().is_empty());
        // the camera did not move: every pose stays at the first
        for p in &result.trajectory.poses {
            assert!(p.pose.translation.vector.norm() < 1e-6, "{:?}", p.pose);
        }
    }
}
