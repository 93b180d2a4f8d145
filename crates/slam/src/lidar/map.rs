//! The content of a 2D lidar map file: keyframe scans at their optimised poses and the pose
//! graph that joins them.
//!
//! Sections (see [`crate::map_file`] for the container):
//! * `KEYF`: per keyframe, its time, `map_from_base` (x, y, cos θ, sin θ: every pose in the
//!   file is stored so), `base_from_laser`, the scan's first bearing, bearing step and maximum
//!   range, and its ranges in whole millimetres (`u32`; `u32::MAX` for a reading that was not a number or negative). Ranges, not points:
//!   the grid's free space, the no-return beams and the points any configuration needs are
//!   all rebuilt from them, and four bytes a beam compress to about two.
//! * `EDGE`: pose-graph edges (`from`, `to`, the measured relative pose, the upper triangle of
//!   the information matrix, the robust kernel's scale if any).
//! * `SCAN`: every scan of the runs that built the map: its time, the keyframe it follows
//!   (`u32::MAX`: none) and its pose relative to that keyframe, so the trajectory follows the
//!   keyframes when a later run corrects them (a continued map's whole trajectory).

use crate::map_file::codec::{Reader, Writer};
use crate::map_file::{MapFile, MapFileError, MapHeader, Rig, Section};
use crate::SlamError;
use nalgebra::{Matrix3, Point3, Vector2};
use slamkit_core::{LaserScan, Pose2, Trajectory};
use slamkit_lidar::icp_slam::IcpSlamConfig;
use slamkit_lidar::point_map::Keyframe;
use slamkit_lidar::pose_graph::Edge;
use slamkit_map::{OccupancyGrid, OccupancyGridConfig};
use std::path::Path;

const KEYFRAMES: [u8; 4] = *b"KEYF";
const EDGES: [u8; 4] = *b"EDGE";
const SCANS: [u8; 4] = *b"SCAN";
/// A scan that follows no keyframe.
const NO_KEYFRAME: u32 = u32::MAX;
/// A range that was not a non-negative number.
pub(crate) const INVALID_RANGE: u32 = u32::MAX;

/// One keyframe: a scan and where the robot was when it took it.
#[derive(Debug, Clone, PartialEq)]
pub struct MapKeyframe {
    /// `map_from_base`, optimised.
    pub world_from_base: Pose2,
    /// The scan (its odometry is not kept).
    pub scan: LaserScan,
}

/// Where one scan of a mapping run was, relative to the keyframe it follows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapScan {
    /// Time of the scan \[s\].
    pub timestamp: f64,
    /// The keyframe it follows (`None`: the map frame itself).
    pub keyframe: Option<usize>,
    /// `keyframe_from_base`.
    pub keyframe_from_base: Pose2,
}

/// A 2D lidar map: keyframes, the pose graph over them, and the scans of the runs that made
/// it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LidarMap {
    /// Keyframes, in the order they were made (the pose graph's node order).
    pub keyframes: Vec<MapKeyframe>,
    /// Pose-graph edges between keyframes.
    pub edges: Vec<Edge>,
    /// Every scan of the runs that built the map, in time order.
    pub scans: Vec<MapScan>,
}

impl LidarMap {
    /// Reads a map file and checks it holds a 2D lidar map.
    pub fn load(path: &Path) -> Result<(Self, MapHeader), SlamError> {
        let wrap = |source| SlamError::MapFile {
            path: path.to_path_buf(),
            source,
        };
        let file = MapFile::load(path).map_err(wrap)?;
        let map = Self::from_file(&file).map_err(wrap)?;
        Ok((map, file.header))
    }

    /// Writes the map with a new header carrying `notes`.
    pub fn save(&self, path: &Path, notes: serde_json::Value) -> Result<(), SlamError> {
        self.to_new_file(notes)
            .and_then(|f| f.save(path))
            .map_err(|source| SlamError::MapFile {
                path: path.to_path_buf(),
                source,
            })
    }

    /// The map as a map file with a new header carrying `notes`.
    pub fn to_new_file(&self, notes: serde_json::Value) -> Result<MapFile, MapFileError> {
        let mut header = MapHeader::new(Rig::Lidar2d, self.keyframes.len(), self.extent_m());
        header.notes = notes;
        self.to_file(header)
    }

    /// The map as a map file with `header`.
    pub fn to_file(&self, header: MapHeader) -> Result<MapFile, MapFileError> {
        let mut w = Writer::new();
        w.len(self.keyframes.len())?;
        for kf in &self.keyframes {
            let s = &kf.scan;
            w.f64(s.timestamp);
            put_pose(&mut w, &kf.world_from_base);
            put_pose(&mut w, &s.base_from_laser);
            w.f64(s.angle_min_rad);
            w.f64(s.angle_increment_rad);
            w.f64(s.max_range_m);
            w.len(s.ranges_m.len())?;
            for r in &s.ranges_m {
                w.u32(quantise_range(*r));
            }
        }
        let keyframes = w.into_bytes();
        let mut w = Writer::new();
        w.len(self.edges.len())?;
        for e in &self.edges {
            w.len(e.from)?;
            w.len(e.to)?;
            put_pose(&mut w, &e.from_from_to);
            put_edge_weights(&mut w, e);
        }
        let edges = w.into_bytes();
        let mut w = Writer::new();
        w.len(self.scans.len())?;
        for scan in &self.scans {
            w.f64(scan.timestamp);
            match scan.keyframe {
                Some(k) => w.len(k)?,
                None => w.u32(NO_KEYFRAME),
            }
            put_pose(&mut w, &scan.keyframe_from_base);
        }
        Ok(MapFile {
            header,
            sections: vec![
                Section {
                    tag: KEYFRAMES,
                    data: keyframes,
                },
                Section {
                    tag: EDGES,
                    data: edges,
                },
                Section {
                    tag: SCANS,
                    data: w.into_bytes(),
                },
            ],
        })
    }

    /// The map in a map file, which must be a 2D lidar map.
    pub fn from_file(file: &MapFile) -> Result<Self, MapFileError> {
        file.expect_rig(Rig::Lidar2d)?;
        let mut r = Reader::new(file.section(&KEYFRAMES)?, "the KEYF section");
        let n = r.len(11 * 8 + 4)?;
        let mut keyframes = Vec::with_capacity(n);
        for _ in 0..n {
            let timestamp = r.f64()?;
            let world_from_base = get_pose(&mut r)?;
            let base_from_laser = get_pose(&mut r)?;
            let angle_min_rad = r.f64()?;
            let angle_increment_rad = r.f64()?;
            let max_range_m = r.f64()?;
            let beams = r.len(4)?;
            let ranges_m = (0..beams)
                .map(|_| r.u32().map(range_from_mm))
                .collect::<Result<Vec<f64>, _>>()?;
            keyframes.push(MapKeyframe {
                world_from_base,
                scan: LaserScan {
                    timestamp,
                    angle_min_rad,
                    angle_increment_rad,
                    ranges_m,
                    max_range_m,
                    odometry: None,
                    base_from_laser,
                },
            });
        }
        r.finish()?;
        let mut r = Reader::new(file.section(&EDGES)?, "the EDGE section");
        let n = r.len(2 * 4 + 10 * 8 + 1)?;
        let mut edges = Vec::with_capacity(n);
        for _ in 0..n {
            let from = r.u32()? as usize;
            let to = r.u32()? as usize;
            if from >= keyframes.len() || to >= keyframes.len() || from == to {
                return Err(MapFileError::Malformed(format!(
                    "edge {from}-{to} does not join two of the {} keyframes",
                    keyframes.len()
                )));
            }
            let from_from_to = get_pose(&mut r)?;
            let (information, robust_scale) = get_edge_weights(&mut r, from, to)?;
            edges.push(Edge {
                from,
                to,
                from_from_to,
                information,
                robust_scale,
            });
        }
        r.finish()?;
        let mut r = Reader::new(file.section(&SCANS)?, "the SCAN section");
        let n = r.len(8 + 4 + 4 * 8)?;
        let mut scans = Vec::with_capacity(n);
        for _ in 0..n {
            let timestamp = r.f64()?;
            let keyframe = match r.u32()? {
                NO_KEYFRAME => None,
                k if (k as usize) < keyframes.len() => Some(k as usize),
                k => {
                    return Err(MapFileError::Malformed(format!(
                        "a scan follows keyframe {k} of {}",
                        keyframes.len()
                    )))
                }
            };
            scans.push(MapScan {
                timestamp,
                keyframe,
                keyframe_from_base: get_pose(&mut r)?,
            });
        }
        r.finish()?;
        Ok(Self {
            keyframes,
            edges,
            scans,
        })
    }

    /// The keyframes' beam end points in the map frame, at height 0 (a point cloud of the map).
    pub fn cloud(&self) -> Vec<Point3<f64>> {
        self.keyframes
            .iter()
            .flat_map(|kf| {
                let world_from_laser = kf.world_from_base * kf.scan.base_from_laser;
                kf.scan
                    .hit_points()
                    .into_iter()
                    .map(move |p| world_from_laser * p)
            })
            .map(|p| Point3::new(p.x, p.y, 0.0))
            .collect()
    }

    /// Every scan of the runs that built the map at its current pose (following its keyframe).
    pub fn trajectory(&self) -> Trajectory {
        let mut trajectory = Trajectory::new();
        for scan in &self.scans {
            let keyframe = scan
                .keyframe
                .and_then(|k| self.keyframes.get(k))
                .map_or(Pose2::identity(), |kf| kf.world_from_base);
            let pose = keyframe * scan.keyframe_from_base;
            trajectory.push(scan.timestamp, slamkit_core::pose::pose2_to_pose3(&pose));
        }
        trajectory
    }

    /// The keyframes as the matchers use them: points within `config`'s ranges with normals.
    pub fn matcher_keyframes(&self, config: &IcpSlamConfig) -> Vec<Keyframe> {
        let scans: Vec<(&LaserScan, Pose2)> = self
            .keyframes
            .iter()
            .map(|kf| (&kf.scan, kf.world_from_base))
            .collect();
        config.scan_keyframes(&scans)
    }

    /// An occupancy grid of every keyframe scan at its pose (free space, hits, no-returns).
    pub fn grid(&self, config: OccupancyGridConfig) -> Result<OccupancyGrid, SlamError> {
        let scans = self
            .keyframes
            .iter()
            .map(|kf| (&kf.scan, kf.world_from_base));
        super::grid_of_scans(scans, config)
    }

    /// Bounding box `[min x, min y, max x, max y]` of the keyframe poses and their scans' hits
    /// \[m\].
    pub fn extent_m(&self) -> Option<[f64; 4]> {
        let mut extent: Option<[f64; 4]> = None;
        let mut grow = |p: Vector2<f64>| {
            let e = extent.get_or_insert([p.x, p.y, p.x, p.y]);
            *e = [e[0].min(p.x), e[1].min(p.y), e[2].max(p.x), e[3].max(p.y)];
        };
        for kf in &self.keyframes {
            grow(kf.world_from_base.translation.vector);
            let world_from_laser = kf.world_from_base * kf.scan.base_from_laser;
            for p in kf.scan.hit_points() {
                grow((world_from_laser * p).coords);
            }
        }
        extent
    }
}

/// The upper triangle of a 3 × 3 matrix, row by row.
/// Writes an edge's information matrix (its upper triangle) and robust scale, as the map
/// file and the map updates both store them.
pub(crate) fn put_edge_weights(w: &mut Writer, e: &Edge) {
    for (i, j) in UPPER {
        w.f64(e.information[(i, j)]);
    }
    match e.robust_scale {
        Some(scale) => {
            w.u8(1);
            w.f64(scale);
        }
        None => w.u8(0),
    }
}

/// Reads what [`put_edge_weights`] wrote for the edge `from`–`to`.
pub(crate) fn get_edge_weights(
    r: &mut Reader,
    from: usize,
    to: usize,
) -> Result<(Matrix3<f64>, Option<f64>), MapFileError> {
    let mut information = Matrix3::zeros();
    for (i, j) in UPPER {
        let v = r.f64()?;
        information[(i, j)] = v;
        information[(j, i)] = v;
    }
    let robust_scale = match r.u8()? {
        0 => None,
        1 => Some(r.f64()?),
        flag => {
            return Err(MapFileError::Malformed(format!(
                "edge {from}-{to}: robust flag {flag}"
            )))
        }
    };
    Ok((information, robust_scale))
}

const UPPER: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];

/// Writes a pose as `x, y, cos θ, sin θ`: the rotation's own numbers, so a map read back and
/// written again gives the same bytes (an angle would go through `atan2` and `sin`/`cos`,
/// which need not return the last bit). A rotation that drifted off unit length in memory
/// (products of many rotations) is brought back to it.
fn put_pose(w: &mut Writer, pose: &Pose2) {
    let (mut c, mut s) = (pose.rotation.re, pose.rotation.im);
    let norm2 = c * c + s * s;
    if (norm2 - 1.0).abs() > 1e-12 {
        let norm = norm2.sqrt();
        (c, s) = (c / norm, s / norm);
    }
    w.f64(pose.translation.vector.x);
    w.f64(pose.translation.vector.y);
    w.f64(c);
    w.f64(s);
}

fn get_pose(r: &mut Reader<'_>) -> Result<Pose2, MapFileError> {
    let (x, y, c, s) = (r.f64()?, r.f64()?, r.f64()?, r.f64()?);
    if ((c * c + s * s) - 1.0).abs() > 1e-9 {
        return Err(MapFileError::Malformed(format!(
            "a rotation ({c}, {s}) is not of unit length"
        )));
    }
    Ok(Pose2::from_parts(
        nalgebra::Translation2::new(x, y),
        nalgebra::UnitComplex::from_cos_sin_unchecked(c, s),
    ))
}

/// A range in whole millimetres, or [`INVALID_RANGE`].
pub(crate) fn quantise_range(r: f64) -> u32 {
    if r.is_finite() && r >= 0.0 && r * 1000.0 < f64::from(INVALID_RANGE - 1) {
        (r * 1000.0).round() as u32
    } else {
        INVALID_RANGE
    }
}

pub(crate) fn range_from_mm(mm: u32) -> f64 {
    if mm == INVALID_RANGE {
        f64::NAN
    } else {
        f64::from(mm) / 1000.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> LidarMap {
        let scan = |t: f64| LaserScan {
            timestamp: t,
            angle_min_rad: -1.5,
            angle_increment_rad: 0.01,
            ranges_m: vec![1.0, 2.5, f64::NAN, -1.0, 81.9, 3.0],
            max_range_m: 81.9,
            odometry: None,
            base_from_laser: Pose2::new(Vector2::new(0.1, 0.0), 0.0),
        };
        LidarMap {
            keyframes: vec![
                MapKeyframe {
                    world_from_base: Pose2::identity(),
                    scan: scan(1.0),
                },
                MapKeyframe {
                    world_from_base: Pose2::new(Vector2::new(0.5, -0.25), 0.125),
                    scan: scan(2.0),
                },
            ],
            edges: vec![Edge {
                from: 0,
                to: 1,
                from_from_to: Pose2::new(Vector2::new(0.5, -0.25), 0.125),
                information: Matrix3::from_diagonal(&nalgebra::Vector3::new(100.0, 100.0, 400.0)),
                robust_scale: Some(1.5),
            }],
            scans: vec![
                MapScan {
                    timestamp: 1.0,
                    keyframe: None,
                    keyframe_from_base: Pose2::identity(),
                },
                MapScan {
                    timestamp: 1.5,
                    keyframe: Some(1),
                    keyframe_from_base: Pose2::new(Vector2::new(0.1, 0.0), 0.0),
                },
            ],
        }
    }

    #[test]
    fn round_trip_keeps_everything_to_the_millimetre() {
        let map = sample();
        let header = MapHeader::new(Rig::Lidar2d, 2, map.extent_m());
        let bytes = map.to_file(header.clone()).unwrap().to_bytes().unwrap();
        let file = MapFile::from_bytes(&bytes).unwrap();
        assert_eq!(file.header, header);
        let back = LidarMap::from_file(&file).unwrap();
        assert_eq!(back.edges, map.edges);
        assert_eq!(back.scans, map.scans);
        assert_eq!(back.trajectory().len(), 2);
        for (a, b) in back.keyframes.iter().zip(&map.keyframes) {
            assert_eq!(a.world_from_base, b.world_from_base);
            let (ra, rb) = (&a.scan.ranges_m, &b.scan.ranges_m);
            assert!(ra[..2] == rb[..2] && ra[2].is_nan() && ra[3].is_nan());
            assert_eq!(ra[4..], rb[4..]);
        }
        // a loaded map saves to the same bytes
        let again = back.to_file(file.header).unwrap().to_bytes().unwrap();
        assert_eq!(again, bytes);
    }

    #[test]
    fn other_rigs_and_broken_edges_are_refused() {
        let map = sample();
        let file = map.to_file(MapHeader::new(Rig::Rgbd, 2, None)).unwrap();
        let err = LidarMap::from_file(&file).unwrap_err();
        assert!(err.to_string().contains("rgbd"), "{err}");
        let mut bad = map.clone();
        bad.edges[0].to = 7;
        let file = bad.to_file(MapHeader::new(Rig::Lidar2d, 2, None)).unwrap();
        let err = LidarMap::from_file(&file).unwrap_err();
        assert!(err.to_string().contains("does not join"), "{err}");
    }
}
