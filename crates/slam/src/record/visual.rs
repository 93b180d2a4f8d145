//! A camera run recorded: every frame's image as Foxglove's `CompressedImage` (JPEG), the pose
//! it got (`/pose`, `map → camera` on `/tf`), the path so far on `/path`
//! [`MAP_SNAPSHOTS`] times over the run, and at the end the final path (after loop
//! closure's corrections) and the point map on `/map` (`foxglove.PointCloud`, coloured).
//!
//! Images are encoded where the frames are decoded (the pipeline's reading thread, through
//! [`VisualRecording::tap`]), and written when the tracker reaches their frame, so the file's
//! messages stay in time order while encoding stays off the tracking thread.

use super::{Recorder, MAP_SNAPSHOTS};
use crate::visual::VisualUpdate;
use crate::SlamError;
use crossbeam_channel::{unbounded, Receiver, Sender};
use slamkit_core::{Observation, PointCloud, Pose3, Trajectory};
use std::collections::{BTreeMap, VecDeque};
use std::path::Path;

/// Topic of the camera's images: the colour image of an RGB-D camera, the left one of a
/// stereo pair.
pub const IMAGE_TOPIC: &str = "/camera/image";

/// JPEG quality of the recorded images: a 640×480 colour frame in about 40 KB, artefacts
/// below what a viewer shows.
const JPEG_QUALITY: u8 = 85;

/// Frames between two recordings of the path in a live run ([`VisualRecording::live`]): the
/// whole path is written each time, so not at every frame (100 frames: 3 s of a 30 Hz camera).
pub const LIVE_PATH_FRAMES: usize = 100;

/// An encoded image and the time of its frame \[s\].
pub(crate) type EncodedImage = (f64, Vec<u8>);

/// A [`VisualSlam`](crate::VisualSlam) run being recorded to an MCAP file.
pub struct VisualRecording {
    recorder: Recorder,
    sender: Sender<EncodedImage>,
    images: Receiver<EncodedImage>,
    /// Images received from the tap that belong to frames the tracker has not reached.
    pending: VecDeque<EncodedImage>,
    every: usize,
    updates: usize,
    path: Vec<Pose3>,
    last_t: f64,
}

impl VisualRecording {
    /// Starts recording a run of `frames` frames to `path`.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be created.
    pub fn create(path: &Path, frames: usize) -> Result<Self, SlamError> {
        Self::recording_path_every(path, frames.div_ceil(MAP_SNAPSHOTS).max(1))
    }

    /// Starts recording a live run (a ROS 2 node's), whose length is not known: the path
    /// every [`LIVE_PATH_FRAMES`] frames and at the end.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be created.
    pub fn live(path: &Path) -> Result<Self, SlamError> {
        Self::recording_path_every(path, LIVE_PATH_FRAMES)
    }

    fn recording_path_every(path: &Path, every: usize) -> Result<Self, SlamError> {
        let (sender, images) = unbounded();
        Ok(Self {
            recorder: Recorder::create(path)?,
            sender,
            images,
            pending: VecDeque::new(),
            every,
            updates: 0,
            path: Vec::new(),
            last_t: 0.0,
        })
    }

    /// `source` with each decoded frame's image also encoded for the recording, on whichever
    /// thread iterates it. Frames that fail to decode pass through unrecorded.
    pub fn tap<'a, E: 'a>(
        &self,
        source: impl Iterator<Item = Result<Observation, E>> + Send + 'a,
    ) -> impl Iterator<Item = Result<Observation, E>> + Send + 'a {
        let sender = self.sender.clone();
        source.inspect(move |item| {
            if let Some(jpeg) = item.as_ref().ok().and_then(encode_jpeg) {
                // The recording may be gone when the run failed: nothing left to record then.
                let _ = sender.send(jpeg);
            }
        })
    }

    /// Records a tracked (or failed) frame: the images up to its time, then its pose when it
    /// has one.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be written.
    pub fn push(&mut self, update: &VisualUpdate) -> Result<(), SlamError> {
        let t = update.update.timestamp;
        self.pending.extend(self.images.try_iter());
        while self.pending.front().is_some_and(|(ti, _)| *ti <= t) {
            if let Some((ti, jpeg)) = self.pending.pop_front() {
                self.image(ti, &jpeg)?;
            }
        }
        let tracked = !matches!(update.frame, slamkit_vo::FrameStatus::Failed(_));
        if let Some(pose) = update.update.pose.filter(|_| tracked) {
            self.recorder.pose("/pose", "map", t, &pose)?;
            self.recorder.transform(t, "map", "camera", &pose)?;
            self.path.push(pose);
        }
        self.last_t = self.last_t.max(t);
        self.updates += 1;
        if self.updates % self.every == 0 {
            self.recorder.poses("/path", "map", t, &self.path)?;
        }
        Ok(())
    }

    /// Records the images left, the run's final `trajectory` and its point `map`, and ends the
    /// recording; returns the messages written per topic.
    ///
    /// # Errors
    /// [`SlamError::Recording`] when the file cannot be completed.
    pub fn finish(
        mut self,
        trajectory: &Trajectory,
        map: Option<&PointCloud>,
    ) -> Result<BTreeMap<String, u64>, SlamError> {
        self.pending.extend(self.images.try_iter());
        for (t, jpeg) in std::mem::take(&mut self.pending) {
            self.image(t, &jpeg)?;
        }
        let t = trajectory
            .poses
            .last()
            .map_or(self.last_t, |p| p.timestamp.max(self.last_t));
        let poses: Vec<Pose3> = trajectory.poses.iter().map(|p| p.pose).collect();
        self.recorder.poses("/path", "map", t, &poses)?;
        if let Some(cloud) = map {
            self.recorder.point_cloud("/map", "map", t, cloud)?;
        }
        self.recorder.finish()
    }

    fn image(&mut self, t: f64, jpeg: &[u8]) -> Result<(), SlamError> {
        self.recorder
            .compressed_image(IMAGE_TOPIC, "camera", t, "jpeg", jpeg)
    }
}

/// The frame's colour image (RGB-D) or left image (stereo) as JPEG, with its time; `None` for
/// other observations or an image the encoder refuses.
pub(crate) fn encode_jpeg(observation: &Observation) -> Option<EncodedImage> {
    use image::codecs::jpeg::JpegEncoder;
    use image::ExtendedColorType;
    let mut bytes = Vec::new();
    let mut encoder = JpegEncoder::new_with_quality(&mut bytes, JPEG_QUALITY);
    let encoded = match observation {
        Observation::Rgbd(frame) => {
            let c = &frame.color;
            let pixels: Vec<u8> = c.data().iter().flatten().copied().collect();
            encoder.encode(
                &pixels,
                c.width() as u32,
                c.height() as u32,
                ExtendedColorType::Rgb8,
            )
        }
        Observation::Stereo(frame) => {
            let l = &frame.left;
            encoder.encode(
                l.data(),
                l.width() as u32,
                l.height() as u32,
                ExtendedColorType::L8,
            )
        }
        _ => return None,
    };
    encoded.ok().map(|()| (observation.timestamp(), bytes))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::session::{MapChange, TrackingStatus, Update};
    use nalgebra::Point3;
    use slamkit_core::image::Image;
    use slamkit_core::observation::RgbdFrame;
    use slamkit_core::StampedPose;
    use slamkit_vo::FrameStatus;

    fn frame(t: f64) -> Observation {
        let color = Image::from_vec(16, 8, (0..128).map(|i| [i as u8, 0, 255]).collect()).unwrap();
        Observation::Rgbd(RgbdFrame {
            timestamp: t,
            color,
            depth_m: Image::filled(16, 8, 1.0),
        })
    }

    fn update(index: usize, t: f64, frame: FrameStatus) -> VisualUpdate {
        VisualUpdate {
            update: Update {
                timestamp: t,
                pose: Some(Pose3::translation(t, 0.0, 0.0)),
                status: TrackingStatus::Tracking,
                map: MapChange::default(),
            },
            index,
            frame,
        }
    }

    #[test]
    fn images_poses_path_and_map_in_time_order() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("vo.mcap");
        let mut recording = VisualRecording::create(&path, 3).unwrap();
        // The reader runs ahead of the tracker: all three images are encoded first, and one
        // frame fails to decode.
        let source = vec![Ok(frame(1.0)), Err("damaged"), Ok(frame(3.0))].into_iter();
        let read: Vec<_> = recording.tap(source).collect();
        assert_eq!(read.len(), 3);
        recording
            .push(&update(0, 1.0, FrameStatus::Initialised { features: 9 }))
            .unwrap();
        let failed = FrameStatus::Failed(slamkit_vo::FailReason::SizeMismatch);
        recording.push(&update(1, 2.0, failed)).unwrap();
        let tracked = FrameStatus::Tracked {
            inliers: 5,
            correspondences: 6,
        };
        recording.push(&update(2, 3.0, tracked)).unwrap();
        let trajectory = Trajectory {
            poses: vec![
                StampedPose {
                    timestamp: 1.0,
                    pose: Pose3::identity(),
                },
                StampedPose {
                    timestamp: 3.0,
                    pose: Pose3::translation(0.5, 0.0, 0.0),
                },
            ],
        };
        let cloud = PointCloud {
            points: vec![Point3::new(1.0, 2.0, 3.0), Point3::new(-1.0, 0.5, 2.0)],
            colors: Some(vec![[10, 20, 30], [40, 50, 60]]),
        };
        let counts = recording.finish(&trajectory, Some(&cloud)).unwrap();
        assert_eq!(counts[IMAGE_TOPIC], 2);
        assert_eq!((counts["/pose"], counts["/tf"], counts["/map"]), (2, 2, 1));

        let bytes = std::fs::read(&path).unwrap();
        let messages: Vec<_> = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap())
            .collect();
        let topics: Vec<&str> = messages.iter().map(|m| m.channel.topic.as_str()).collect();
        assert_eq!(
            topics,
            [
                IMAGE_TOPIC,
                "/pose",
                "/tf",
                "/path", // frame 0
                "/path", // frame 1 failed: no image (damaged), no pose
                IMAGE_TOPIC,
                "/pose",
                "/tf",
                "/path", // frame 2
                "/path",
                "/map", // the end
            ]
        );
        assert!(messages.windows(2).all(|w| w[0].log_time <= w[1].log_time));
        let image: serde_json::Value = serde_json::from_slice(&messages[0].data).unwrap();
        assert_eq!(image["format"], "jpeg");
        let last_path: serde_json::Value = serde_json::from_slice(&messages[9].data).unwrap();
        assert_eq!(last_path["poses"][1]["position"]["x"], 0.5);
        let map: serde_json::Value = serde_json::from_slice(&messages[10].data).unwrap();
        assert_eq!(map["point_stride"], 16);
        assert_eq!(map["fields"].as_array().unwrap().len(), 7);
    }
}
