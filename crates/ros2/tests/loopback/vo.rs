//! `slamkit ros2 vo` live on loopback (issue 21): the 7-Scenes RedKitchen bag of
//! `crates/cli/tests/cli/vo_bags.rs` (60 frames, rgb8 colour, 16UC1 depth, one CameraInfo, written
//! by PyPI `rosbags` through `scripts/make_ros2_bags.sh`) is played message by message from a
//! plain RustDDS writer in this test into the node (colour raw, depth as `image_transport`'s
//! `compressedDepth` PNG), with a RealSense-like `/tf_static` (`camera_link → <optical
//! frame>`). Both sides discover each other by unicast on
//! `127.0.0.1` only (`ROS_LOCALHOST_ONLY`, [`crate::loopback_discovery`]; loopback carries no multicast), on a
//! domain of their own, so nothing leaves the machine and concurrent runs do not meet.
//!
//! The poses received on `/pose` must be the trajectory `slamkit vo BAG --profile kinect-v1`
//! computes (the same session through the same pipeline, run here on the bag), moved into the
//! map frame by the mounting: `map_from_base = B · world_from_camera · B⁻¹`. Images that DDS
//! drops (best effort) are counted; the reference then runs on the frames that came. The node
//! records what it processed (`--record`, issue 23): read back, the file holds every frame's
//! image, every published pose and transform, and the final path.

use crate::{loopback_discovery, typed_topic, wait_until_matched, Peer};
use ros2_client::dds::rustdds::StatusEvented;
use slamkit_core::{Pose3, Trajectory};
use slamkit_io::bag::messages::{is_type, CameraInfoMsg, ImageMsg, RosMessage};
use slamkit_io::bag::RgbdTopics;
use slamkit_io::{Dataset, DatasetFormat};
use slamkit_ros2::dds::{reliable_qos, topic};
use slamkit_ros2::msgs::{self, Header, Time};
use slamkit_ros2::vo_node::optical_mounting;
use slamkit_ros2::{run_vo_node, VoNodeRequest};
use slamkit_slam::visual::{self, PointMapping, RunOptions, VisualSlam};
use slamkit_vo::FrontendKind;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

const RGB: &str = "/camera/color/image_raw";
const DEPTH: &str = "/camera/aligned_depth_to_color/image_raw";
/// The depth images go out as `image_transport`'s `compressedDepth` plugin sends them (PNG,
/// lossless), so the node's raw and compressed paths both run.
const DEPTH_PNG: &str = "/camera/aligned_depth_to_color/image_raw/compressedDepth";
const INFO: &str = "/camera/color/camera_info";

/// The bag, or `None` (skipped) when it is absent and `SLAMKIT_DATA` is unset.
fn bag(test: &str) -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/ros2-bags/redkitchen_mcap");
    if dir.join("metadata.yaml").exists() {
        return Some(dir);
    }
    slamkit_testdata::data(test, "")?;
    panic!(
        "{}: missing although SLAMKIT_DATA is set; run scripts/make_ros2_bags.sh",
        dir.display()
    );
}

fn header(h: &slamkit_io::bag::messages::Header) -> Header {
    Header {
        stamp: Time {
            sec: h.stamp.sec as i32,
            nanosec: h.stamp.nsec,
        },
        frame_id: h.frame_id.clone(),
    }
}

fn image(m: ImageMsg) -> msgs::Image {
    msgs::Image {
        header: header(&m.header),
        height: m.height,
        width: m.width,
        encoding: m.encoding,
        is_bigendian: m.is_bigendian,
        step: m.step,
        data: m.data,
    }
}

fn camera_info(m: CameraInfoMsg) -> msgs::CameraInfo {
    msgs::CameraInfo {
        header: header(&m.header),
        height: m.height,
        width: m.width,
        distortion_model: m.distortion_model,
        d: m.d,
        k: m.k,
        r: m.r,
        p: m.p,
        binning_x: m.binning_x,
        binning_y: m.binning_y,
        roi: msgs::RegionOfInterest {
            x_offset: m.roi[0],
            y_offset: m.roi[1],
            height: m.roi[2],
            width: m.roi[3],
            do_rectify: m.roi_do_rectify,
        },
    }
}

/// A 16UC1 depth image as the `compressedDepth` plugin writes it: a 12-byte header (format,
/// two quantisation parameters unused for 16UC1), then a 16-bit grey PNG.
fn compressed_depth(m: &msgs::Image) -> msgs::CompressedImage {
    let mm: Vec<u16> = m
        .data
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    let png = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(m.width, m.height, mm).unwrap();
    let mut data = vec![0u8; 12];
    let mut after_header = std::io::Cursor::new(&mut data);
    after_header.set_position(12);
    png.write_to(&mut after_header, image::ImageFormat::Png)
        .unwrap();
    msgs::CompressedImage {
        header: m.header.clone(),
        format: "16UC1; compressedDepth png".into(),
        data,
    }
}

/// The bag's messages on the three topics, in storage order: (topic, colour or depth image).
type Played = (Vec<(bool, msgs::Image)>, msgs::CameraInfo);

fn read_bag(path: &Path) -> Played {
    let mut bag = slamkit_io::bag::open(path).unwrap();
    bag.find_connections().unwrap();
    let (mut images, mut info) = (Vec::new(), None);
    bag.read_stored(&mut |conn, msg| {
        if is_type::<ImageMsg>(conn) && (conn.topic == RGB || conn.topic == DEPTH) {
            let m = ImageMsg::decode_from(conn, msg.data).unwrap();
            images.push((conn.topic == RGB, image(m)));
        } else if is_type::<CameraInfoMsg>(conn) && conn.topic == INFO {
            info.get_or_insert_with(|| {
                camera_info(CameraInfoMsg::decode_from(conn, msg.data).unwrap())
            });
        }
    })
    .unwrap();
    (images, info.unwrap())
}

/// What `slamkit vo BAG --profile kinect-v1` computes, on the frames stamped `keep`.
fn reference(path: &Path, keep: &[f64]) -> Trajectory {
    let dataset = Dataset::open_bag(path, &RgbdTopics::default()).unwrap();
    let config = visual::session_settings(
        FrontendKind::Klt,
        DatasetFormat::RosBag,
        Some("kinect-v1"),
        None,
        false,
    )
    .unwrap();
    let mut session = VisualSlam::new(&config, visual::rig_of(&dataset))
        .unwrap()
        .with_point_map(PointMapping::EveryFrame)
        .unwrap();
    let frames = dataset.observations().filter(|o| {
        let t = o.as_ref().map_or(f64::NAN, |o| o.timestamp());
        keep.iter().any(|k| (k - t).abs() < 1e-9)
    });
    let run = visual::run(&mut session, frames, RunOptions::default(), |_| {}).unwrap();
    run.trajectory
}

#[test]
fn the_camera_node_on_loopback_gives_the_bag_runs_trajectory() {
    let test = "the_camera_node_on_loopback_gives_the_bag_runs_trajectory";
    let Some(path) = bag(test) else {
        return;
    };
    let started = Instant::now();
    let out = tempfile::tempdir().unwrap();
    let recording = out.path().join("node.mcap");
    let (images, info) = read_bag(&path);
    let optical = info.header.frame_id.clone();
    let discovery = loopback_discovery(4);
    let request = VoNodeRequest {
        rgb_topic: Some(RGB.into()),
        depth_topic: Some(DEPTH_PNG.into()),
        camera_info_topic: Some(INFO.into()),
        profile: Some("kinect-v1".into()),
        // every frame waits for the session: the test checks the trajectory, not the pace
        frame_queue: Some(1000),
        idle_exit_s: Some(1.5),
        record: Some(recording.clone()),
        discovery,
        ..VoNodeRequest::default()
    };
    let setup = request.setup().unwrap();
    // the node stops at its idle timeout once the bag has played
    let stop = AtomicBool::new(false);
    // camera_link → optical frame as the RealSense driver publishes it (15 mm to the side)
    let mut base_from_camera = optical_mounting();
    base_from_camera.translation.vector.y = -0.015;
    std::thread::scope(|scope| {
        let node = scope.spawn(|| run_vo_node(&setup.node, |c| setup.session(c), &stop));
        // the player: plain RustDDS writers, so the test can see them matched
        let Peer {
            mut ros,
            publisher,
            subscriber,
            ..
        } = Peer::new(&discovery, "player");
        let qos = reliable_qos(100);
        let mut writer = |name: &str, ty: &str| typed_topic(&mut ros, name, ty, &qos);
        let (rgb_t, depth_t, info_t) = (
            writer(RGB, "sensor_msgs/Image"),
            writer(DEPTH_PNG, "sensor_msgs/CompressedImage"),
            writer(INFO, "sensor_msgs/CameraInfo"),
        );
        let tf_t = topic(
            &mut ros,
            "/tf_static",
            "tf2_msgs",
            "TFMessage",
            &slamkit_ros2::dds::latched_qos(),
        )
        .unwrap();
        let pose_t = topic(
            &mut ros,
            "/pose",
            "geometry_msgs",
            "PoseWithCovarianceStamped",
            &reliable_qos(1000),
        )
        .unwrap();
        let rgb_w = publisher
            .create_datawriter_no_key_cdr::<msgs::Image>(&rgb_t, None)
            .unwrap();
        let depth_w = publisher
            .create_datawriter_no_key_cdr::<msgs::CompressedImage>(&depth_t, None)
            .unwrap();
        let info_w = publisher
            .create_datawriter_no_key_cdr::<msgs::CameraInfo>(&info_t, None)
            .unwrap();
        let tf_w = publisher
            .create_datawriter_no_key_cdr::<msgs::TfMessage>(&tf_t, None)
            .unwrap();
        let mut pose_r = subscriber
            .create_datareader_no_key_cdr::<msgs::PoseWithCovarianceStamped>(&pose_t, None)
            .unwrap();
        // wait until the node's readers are matched (discovery over 127.0.0.1)
        wait_until_matched(&[
            &|| rgb_w.try_recv_status(),
            &|| depth_w.try_recv_status(),
            &|| info_w.try_recv_status(),
            &|| tf_w.try_recv_status(),
        ]);
        let discovered_s = started.elapsed().as_secs_f64();
        let tf = msgs::TfMessage {
            transforms: vec![msgs::TransformStamped {
                header: Header {
                    stamp: info.header.stamp,
                    frame_id: "camera_link".into(),
                },
                child_frame_id: optical.clone(),
                transform: msgs::Pose::from_isometry(&base_from_camera),
            }],
        };
        tf_w.write(tf, None).unwrap();
        info_w.write(info.clone(), None).unwrap();
        std::thread::sleep(Duration::from_millis(100));
        // 30 images a second: 15 frames a second of colour and depth
        let sent = images.len();
        for (is_rgb, m) in images.iter().cloned() {
            if is_rgb {
                info_w.write(info.clone(), None).unwrap();
                rgb_w.write(m, None).unwrap();
            } else {
                depth_w.write(compressed_depth(&m), None).unwrap();
            }
            std::thread::sleep(Duration::from_millis(33));
        }
        // the poses are taken while the node runs (its writer goes when it stops)
        let mut poses = Vec::new();
        let mut take = || {
            while let Ok(Some(sample)) = pose_r.take_next_sample() {
                poses.push(sample.into_value());
            }
        };
        while !node.is_finished() {
            take();
            std::thread::sleep(Duration::from_millis(20));
        }
        take();
        let run = node.join().unwrap().unwrap();
        let stats = &run.stats;
        println!(
            "discovered in {discovered_s:.2} s; {sent} images sent, {} colour and {} depth \
             received, {} frames queued, {} dropped, unpaired {:?}, {} poses published, {} \
             received; mounting {:?}",
            stats.colour_received,
            stats.depth_received,
            stats.frames_queued,
            stats.frames_dropped,
            stats.unpaired,
            stats.poses_published,
            poses.len(),
            stats.mounting
        );
        assert_eq!(stats.frames_dropped, 0);
        assert!(run.run.skipped.is_empty(), "{:?}", run.run.skipped);
        assert_eq!(run.run.frames.len(), stats.frames_queued);
        assert!(stats.undecodable.count == 0, "{:?}", stats.undecodable);
        // DDS is best effort: at most a tenth of the frames lost on loopback
        assert!(stats.frames_queued >= 54, "{} frames", stats.frames_queued);
        assert_eq!(poses.len(), stats.poses_published);
        assert_eq!(poses.len(), run.run.trajectory.poses.len());
        assert!(poses.len() >= 54, "{} poses", poses.len());
        let stamps: Vec<f64> = run.run.frames.iter().map(|f| f.timestamp).collect();
        let expected = reference(&path, &stamps);
        assert_eq!(expected.poses.len(), poses.len());
        let b = base_from_camera;
        let mut worst = (0.0f64, 0.0f64);
        for (got, want) in poses.iter().zip(&expected.poses) {
            let p = got.pose.pose;
            let map_from_base = Pose3::from_parts(
                nalgebra::Translation3::new(p.position.x, p.position.y, p.position.z),
                nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                    p.orientation.w,
                    p.orientation.x,
                    p.orientation.y,
                    p.orientation.z,
                )),
            );
            let world_from_camera = b.inverse() * map_from_base * b;
            let d = world_from_camera.inverse() * want.pose;
            worst.0 = worst.0.max(d.translation.vector.norm());
            worst.1 = worst
                .1
                .max((got.header.stamp.as_secs_f64() - want.timestamp).abs());
        }
        println!(
            "{} poses: largest difference {:.3e} m, {:.3e} s; {:.1} s in all",
            poses.len(),
            worst.0,
            worst.1,
            started.elapsed().as_secs_f64()
        );
        assert!(worst.0 <= 1e-9, "{} m", worst.0);
        assert!(worst.1 <= 1e-6, "{} s", worst.1);
        let (frames, published) = (stats.frames_queued as u64, poses.len() as u64);
        let report = run.finish(&setup, out.path()).unwrap();
        let bytes = std::fs::read(&recording).unwrap();
        let mut read = std::collections::BTreeMap::<String, u64>::new();
        for message in mcap::MessageStream::new(&bytes).unwrap() {
            *read
                .entry(message.unwrap().channel.topic.clone())
                .or_default() += 1;
        }
        println!("recorded {read:?}");
        assert_eq!(
            serde_json::to_value(&read).unwrap(),
            report["recording"]["messages"]
        );
        assert_eq!(read["/camera/image"], frames);
        assert_eq!((read["/pose"], read["/tf"]), (published, published));
        assert!(read["/path"] >= 1);
    });
}
