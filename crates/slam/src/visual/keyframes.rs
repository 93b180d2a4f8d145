//! The keyframes a [`super::VisualSlam`] session keeps for its map file: each keyframe's pose
//! and the 3D points (with ORB descriptors, for the ORB front end) it tracked from, so that a
//! later session can relocalise in the map or continue it.
//!
//! With loop closure on (`--slam`), the keyframes are loop closing's, where it left them, and
//! every point has its ORB descriptor (the KLT front end's keyframes too): a map to localise
//! in (`--localize`). Otherwise a keyframe is a frame that became a key frame of the local map
//! (with frame-to-frame tracking, no local map, every `local_map.keyframe_every`-th tracked
//! frame, the same spacing), with the tracked features (KLT corners carry no descriptor).
//!
//! Sections of a visual `.skmap` (little endian, [`crate::map_file::codec`]):
//!
//! ```text
//! KPOS  u32 count, then per keyframe: f64 timestamp [s], f64 tx ty tz [m], f64 qx qy qz qw
//!       (map_from_camera of the rig's reference camera)
//! KPTS  u32 count (= keyframes), then per keyframe: u32 points, then per point: f64 x y z
//!       [m] in the keyframe's camera frame, u8 1 + 4 × u64 ORB descriptor, or u8 0
//! ```

use nalgebra::{Point3, Quaternion, Translation3, UnitQuaternion};
use slamkit_core::Pose3;
use slamkit_vision::Descriptor;

use crate::map_file::codec::{Reader, Writer};
use crate::map_file::{MapFile, MapFileError, MapHeader, Rig, Section};

/// Tag of the keyframe poses section.
pub const POSES_TAG: [u8; 4] = *b"KPOS";
/// Tag of the keyframe points section.
pub const POINTS_TAG: [u8; 4] = *b"KPTS";

/// One keyframe of a visual map.
#[derive(Debug, Clone, PartialEq)]
pub struct Keyframe {
    /// Time of the frame \[s\].
    pub timestamp: f64,
    /// `map_from_camera` of the rig's reference camera.
    pub pose: Pose3,
    /// Points seen from the keyframe, in its camera frame \[m\], with their ORB descriptors.
    pub points: Vec<(Point3<f64>, Option<Descriptor>)>,
}

/// The keyframes of a visual session.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VisualMap {
    /// Keyframes in the order they were taken.
    pub keyframes: Vec<Keyframe>,
}

impl VisualMap {
    /// The map as a map file of `rig` (`Rgbd` or `Stereo`).
    ///
    /// # Errors
    /// [`MapFileError::Malformed`] for more than 2^32 keyframes or points in one.
    pub fn to_map_file(&self, rig: Rig) -> Result<MapFile, MapFileError> {
        let mut poses = Writer::new();
        let mut points = Writer::new();
        poses.len(self.keyframes.len())?;
        points.len(self.keyframes.len())?;
        for k in &self.keyframes {
            poses.f64(k.timestamp);
            let t = k.pose.translation.vector;
            let q = k.pose.rotation.coords;
            for v in [t.x, t.y, t.z, q.x, q.y, q.z, q.w] {
                poses.f64(v);
            }
            points.len(k.points.len())?;
            for (p, descriptor) in &k.points {
                for v in [p.x, p.y, p.z] {
                    points.f64(v);
                }
                match descriptor {
                    Some(d) => {
                        points.u8(1);
                        d.iter().for_each(|&w| points.u64(w));
                    }
                    None => points.u8(0),
                }
            }
        }
        Ok(MapFile {
            header: MapHeader::new(rig, self.keyframes.len(), self.extent_m()),
            sections: vec![
                Section {
                    tag: POSES_TAG,
                    data: poses.into_bytes(),
                },
                Section {
                    tag: POINTS_TAG,
                    data: points.into_bytes(),
                },
            ],
        })
    }

    /// Reads the keyframes of a visual map file of `rig`.
    ///
    /// # Errors
    /// [`MapFileError`] for another rig, a missing section or content the format does not
    /// allow.
    pub fn from_map_file(file: &MapFile, rig: Rig) -> Result<Self, MapFileError> {
        file.expect_rig(rig)?;
        let mut poses = Reader::new(file.section(&POSES_TAG)?, "the keyframe poses");
        let mut points = Reader::new(file.section(&POINTS_TAG)?, "the keyframe points");
        let count = poses.len(8 * 8)?;
        if points.len(4)? != count {
            return Err(MapFileError::Malformed(
                "the keyframe points do not match the keyframe poses".into(),
            ));
        }
        let mut keyframes = Vec::with_capacity(count);
        for _ in 0..count {
            let timestamp = poses.f64()?;
            let mut v = [0.0; 7];
            for x in &mut v {
                *x = poses.f64()?;
            }
            let [tx, ty, tz, qx, qy, qz, qw] = v;
            let pose = Pose3::from_parts(
                Translation3::new(tx, ty, tz),
                UnitQuaternion::from_quaternion(Quaternion::new(qw, qx, qy, qz)),
            );
            let n = points.len(3 * 8 + 1)?;
            let mut kf_points = Vec::with_capacity(n);
            for _ in 0..n {
                let p = Point3::new(points.f64()?, points.f64()?, points.f64()?);
                let descriptor = match points.u8()? {
                    0 => None,
                    1 => Some([points.u64()?, points.u64()?, points.u64()?, points.u64()?]),
                    flag => {
                        return Err(MapFileError::Malformed(format!(
                            "descriptor flag {flag} (0 or 1)"
                        )))
                    }
                };
                kf_points.push((p, descriptor));
            }
            keyframes.push(Keyframe {
                timestamp,
                pose,
                points: kf_points,
            });
        }
        poses.finish()?;
        points.finish()?;
        Ok(Self { keyframes })
    }

    /// `[min x, min y, max x, max y]` of the keyframe positions and points in the map frame.
    fn extent_m(&self) -> Option<[f64; 4]> {
        self.keyframes
            .iter()
            .flat_map(|k| {
                std::iter::once(Point3::from(k.pose.translation.vector))
                    .chain(k.points.iter().map(|(p, _)| k.pose * p))
            })
            .fold(None, |acc: Option<[f64; 4]>, p| {
                Some(match acc {
                    None => [p.x, p.y, p.x, p.y],
                    Some([a, b, c, d]) => [a.min(p.x), b.min(p.y), c.max(p.x), d.max(p.y)],
                })
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn map() -> VisualMap {
        let pose = Pose3::new(Vector3::new(1.0, -2.0, 0.5), Vector3::new(0.1, 0.2, -0.3));
        VisualMap {
            keyframes: vec![
                Keyframe {
                    timestamp: 0.5,
                    pose,
                    points: vec![
                        (Point3::new(0.1, 0.2, 2.0), Some([1, 2, 3, u64::MAX])),
                        (Point3::new(-0.4, 0.0, 3.5), None),
                    ],
                },
                Keyframe {
                    timestamp: 1.0,
                    pose: Pose3::identity(),
                    points: Vec::new(),
                },
            ],
        }
    }

    #[test]
    fn keyframes_round_trip_through_the_file_bytes() {
        let file = map().to_map_file(Rig::Rgbd).unwrap();
        assert_eq!(file.header.keyframes, 2);
        let read = MapFile::from_bytes(&file.to_bytes().unwrap()).unwrap();
        assert_eq!(VisualMap::from_map_file(&read, Rig::Rgbd).unwrap(), map());
        let [x0, y0, x1, y1] = file.header.extent_m.unwrap();
        assert!(x0 <= 0.0 && y0 <= -2.0 && x1 >= 1.0 && y1 >= 0.0);
    }

    #[test]
    fn another_rig_or_a_bad_flag_is_an_error() {
        let mut file = map().to_map_file(Rig::Stereo).unwrap();
        assert!(matches!(
            VisualMap::from_map_file(&file, Rig::Rgbd),
            Err(MapFileError::WrongRig { .. })
        ));
        // the first point's descriptor flag: count, points, 3 coordinates, then the flag
        let points = &mut file.sections[1].data;
        points[4 + 4 + 24] = 7;
        assert!(matches!(
            VisualMap::from_map_file(&file, Rig::Stereo),
            Err(MapFileError::Malformed(_))
        ));
    }
}
