//! A visual session's map file holds its keyframes (poses, points, descriptors) exactly: saved
//! through [`Session::save`] and read back, it equals the session's map.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slamkit_core::camera::Intrinsics;
use slamkit_core::image::{Image, RgbImage};
use slamkit_core::observation::{Observation, RgbdFrame};
use slamkit_slam::map_file::{MapFile, Rig};
use slamkit_slam::visual::{PointMapping, VisualMap, VisualSlam};
use slamkit_slam::Session;
use slamkit_vo::{frame, FrontendKind, TrackingMode, VoConfig};

const W: usize = 320;
const H: usize = 240;

/// `n` frames of a static camera 2 m from a wall of smoothed noise (corners for KLT, distinct
/// descriptors for ORB).
fn frames(n: usize) -> impl Iterator<Item = Observation> {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let raw: Vec<f32> = (0..W * H).map(|_| rng.gen_range(0.0..255.0)).collect();
    let at = |x: usize, y: usize| raw[y.min(H - 1) * W + x.min(W - 1)];
    let texture: Vec<[u8; 3]> = (0..W * H)
        .map(|i| {
            let (x, y) = (i % W, i / W);
            let v = (4.0 * at(x, y)
                + at(x + 1, y)
                + at(x.saturating_sub(1), y)
                + at(x, y + 1)
                + at(x, y.saturating_sub(1)))
                / 8.0;
            [v as u8; 3]
        })
        .collect();
    (0..n).map(move |i| {
        Observation::Rgbd(RgbdFrame {
            timestamp: i as f64 / 30.0,
            color: RgbImage::from_vec(W, H, texture.clone()).unwrap(),
            depth_m: Image::filled(W, H, 2.0f32),
        })
    })
}

#[test]
fn saved_keyframes_read_back_identical() {
    let k = Intrinsics::from_array([300.0, 300.0, 159.5, 119.5], W, H);
    let dir = tempfile::tempdir().unwrap();
    for (frontend, mode) in [
        (FrontendKind::Klt, TrackingMode::LocalMap),
        (FrontendKind::Orb, TrackingMode::FrameToFrame),
    ] {
        let config = VoConfig {
            frontend,
            mode,
            ..VoConfig::default()
        };
        let rig = frame::Rig::Rgbd { color: k, depth: k };
        let mut session = VisualSlam::new(&config, rig)
            .unwrap()
            .with_point_map(PointMapping::Off)
            .unwrap();
        let mut added = 0;
        for observation in frames(5) {
            added += session.push(observation).unwrap().map.keyframes_added;
        }
        // every second tracked frame: 0, 2 and 4
        assert_eq!((added, session.map().keyframes.len()), (3, 3));
        let keyframe = &session.map().keyframes[1];
        assert!(keyframe.points.len() > 20, "{}", keyframe.points.len());
        assert!(keyframe
            .points
            .iter()
            .all(|(p, _)| (p.z - 2.0).abs() < 1e-6));
        let with_descriptors = keyframe.points.iter().all(|(_, d)| d.is_some());
        assert_eq!(with_descriptors, frontend == FrontendKind::Orb);

        let path = dir.path().join("visual.skmap");
        session.save(&path).unwrap();
        let file = MapFile::load(&path).unwrap();
        assert_eq!(file.header.keyframes, 3);
        assert_eq!(
            VisualMap::from_map_file(&file, Rig::Rgbd).unwrap(),
            session.map()
        );
    }
}
