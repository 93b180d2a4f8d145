//! A drone session's map file: the header ([`Rig::Drone`]), then
//!
//! * `DCFG`: the session's settings as JSON (layer height and range-finder offsets say which
//!   height each layer is);
//! * one `LAYR` section per height layer, lowest first: `i32` layer index, `u32` keyframe
//!   count, then per keyframe `f64` time \[s\], `f64` x, y \[m\] and yaw \[rad\] of
//!   `map_from_base`, `u32` point count and the points' `f64` x, y in the keyframe's base
//!   frame \[m\]. Normals and grids are rebuilt from the points.

use super::DroneSlamConfig;
use crate::lidar::grid_of_scans;
use crate::map_file::codec::{Reader, Writer};
use crate::map_file::{MapFile, MapFileError, MapHeader, Rig, Section};
use crate::SlamError;
use nalgebra::{Point2, Point3};
use slamkit_core::pose::pose2_to_pose3;
use slamkit_core::{LaserScan, Pose2, Pose3, Trajectory};
use slamkit_map::{OccupancyGrid, OccupancyGridConfig};
use std::collections::BTreeMap;

/// Tag of the settings section.
pub const CONFIG_TAG: [u8; 4] = *b"DCFG";
/// Tag of a layer's keyframes.
pub const LAYER_TAG: [u8; 4] = *b"LAYR";

/// One keyframe of a saved layer.
#[derive(Debug, Clone, PartialEq)]
pub struct SavedKeyframe {
    /// Time of its scan \[s\].
    pub time_s: f64,
    /// `map_from_base` when the scan was taken.
    pub map_from_base: Pose2,
    /// Scan points in the base frame \[m\].
    pub points: Vec<Point2<f64>>,
}

impl DroneMap {
    /// The map as a map file.
    ///
    /// # Errors
    /// [`MapFileError::Malformed`] for a layer index or a count beyond the format's range.
    pub fn to_map_file(&self) -> Result<MapFile, MapFileError> {
        let layers = &self.layers;
        let mut sections = vec![Section {
            tag: CONFIG_TAG,
            data: serde_json::to_vec(&self.config)
                .map_err(|e| MapFileError::Malformed(format!("settings as JSON: {e}")))?,
        }];
        let mut extent: Option<[f64; 4]> = None;
        let mut keyframes = 0;
        for (layer, saved) in layers {
            let layer = i32::try_from(*layer).map_err(|_| {
                MapFileError::Malformed(format!("layer {layer} beyond the file's range"))
            })?;
            let mut w = Writer::new();
            w.i32(layer);
            w.len(saved.len())?;
            for k in saved {
                let t = k.map_from_base.translation.vector;
                for v in [k.time_s, t.x, t.y, k.map_from_base.rotation.angle()] {
                    w.f64(v);
                }
                w.len(k.points.len())?;
                for p in &k.points {
                    w.f64(p.x);
                    w.f64(p.y);
                    grow(&mut extent, &(k.map_from_base * p));
                }
                grow(&mut extent, &Point2::from(t));
            }
            keyframes += saved.len();
            sections.push(Section {
                tag: LAYER_TAG,
                data: w.into_bytes(),
            });
        }
        Ok(MapFile {
            header: MapHeader::new(Rig::Drone, keyframes, extent),
            sections,
        })
    }
}

/// Beams per turn of the scans rebuilt from keyframe points (1°). A keyframe keeps the points
/// its scan matched with (a few hundred), not the beams that found nothing, so a rebuilt scan
/// clears free space only towards its points: the grid of a drone map is sparser than the
/// grids of the run that made it (`slamkit lidar`'s `maps/`), which insert every scan.
const REBUILT_BEAMS: usize = 360;

impl SavedKeyframe {
    /// The keyframe's points as a scan from its base (one beam per degree, the nearest point
    /// where several fall in one beam, no return elsewhere): what a grid inserts, with free
    /// space along each beam, to draw the map.
    pub fn scan(&self) -> LaserScan {
        let increment = std::f64::consts::TAU / REBUILT_BEAMS as f64;
        let mut ranges_m = vec![f64::NAN; REBUILT_BEAMS];
        let mut max_range_m: f64 = 0.0;
        for p in &self.points {
            let range = p.coords.norm();
            let beam = ((p.y.atan2(p.x) + std::f64::consts::PI) / increment) as usize;
            let slot = &mut ranges_m[beam.min(REBUILT_BEAMS - 1)];
            if slot.is_nan() || range < *slot {
                *slot = range;
            }
            max_range_m = max_range_m.max(range);
        }
        LaserScan {
            timestamp: self.time_s,
            angle_min_rad: -std::f64::consts::PI + increment / 2.0,
            angle_increment_rad: increment,
            ranges_m,
            max_range_m: max_range_m + 1.0,
            odometry: None,
            base_from_laser: Pose2::identity(),
        }
    }
}

/// A drone map as saved: the session's settings and every layer's keyframes.
#[derive(Debug, Clone, PartialEq)]
pub struct DroneMap {
    /// The settings of the session that made the map (the layer height says where each layer
    /// is).
    pub config: DroneSlamConfig,
    /// Keyframes by layer index, each layer's in the order they were taken.
    pub layers: BTreeMap<i64, Vec<SavedKeyframe>>,
}

impl DroneMap {
    /// Reads a map file and checks it holds a drone map.
    ///
    /// # Errors
    /// [`SlamError::MapFile`] naming `path` for a file that cannot be read, is damaged or holds
    /// another rig's map.
    pub fn load(path: &std::path::Path) -> Result<Self, SlamError> {
        let wrap = |source| SlamError::MapFile {
            path: path.to_path_buf(),
            source,
        };
        Self::from_file(&MapFile::load(path).map_err(wrap)?).map_err(wrap)
    }

    /// Reads a drone map file.
    ///
    /// # Errors
    /// [`MapFileError`] for another rig, a missing or malformed section.
    pub fn from_file(file: &MapFile) -> Result<Self, MapFileError> {
        let layers = layer_keyframes(file)?;
        let config = serde_json::from_slice(file.section(&CONFIG_TAG)?)
            .map_err(|e| MapFileError::Malformed(format!("the drone settings: {e}")))?;
        Ok(Self { config, layers })
    }

    /// Bottom and top of layer `layer` \[m\].
    pub fn z_range_m(&self, layer: i64) -> [f64; 2] {
        let h = self.config.layers.height.layer_height_m;
        [layer as f64 * h, (layer + 1) as f64 * h]
    }

    /// Every keyframe's point at its layer's middle height, in the map frame.
    pub fn cloud(&self) -> Vec<Point3<f64>> {
        let mut cloud = Vec::new();
        for (layer, keyframes) in &self.layers {
            let [bottom, top] = self.z_range_m(*layer);
            let z = 0.5 * (bottom + top);
            for k in keyframes {
                cloud.extend(k.points.iter().map(|p| {
                    let q = k.map_from_base * p;
                    Point3::new(q.x, q.y, z)
                }));
            }
        }
        cloud
    }

    /// The keyframes' poses in time order, at their layers' middle heights.
    pub fn trajectory(&self) -> Trajectory {
        let mut posed: Vec<(f64, Pose3)> = Vec::new();
        for (layer, keyframes) in &self.layers {
            let [bottom, top] = self.z_range_m(*layer);
            for k in keyframes {
                let mut pose = pose2_to_pose3(&k.map_from_base);
                pose.translation.z = 0.5 * (bottom + top);
                posed.push((k.time_s, pose));
            }
        }
        posed.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut trajectory = Trajectory::new();
        for (t, pose) in posed {
            trajectory.push(t, pose);
        }
        trajectory
    }

    /// An occupancy grid of every layer's keyframes (their points as scans, [`SavedKeyframe::scan`]).
    ///
    /// # Errors
    /// [`SlamError::Grid`] for a map larger than a grid may be.
    pub fn grid(&self, config: OccupancyGridConfig) -> Result<OccupancyGrid, SlamError> {
        let scans: Vec<(LaserScan, Pose2)> = self
            .layers
            .values()
            .flatten()
            .map(|k| (k.scan(), k.map_from_base))
            .collect();
        grid_of_scans(scans.iter().map(|(s, p)| (s, *p)), config)
    }
}

/// The keyframes of every layer in a drone map file, by layer.
pub fn layer_keyframes(file: &MapFile) -> Result<BTreeMap<i64, Vec<SavedKeyframe>>, MapFileError> {
    file.expect_rig(Rig::Drone)?;
    let mut layers = BTreeMap::new();
    for section in file.sections.iter().filter(|s| s.tag == LAYER_TAG) {
        let mut r = Reader::new(&section.data, "a layer section");
        let layer = i64::from(r.i32()?);
        let count = r.len(36)?;
        let mut saved = Vec::with_capacity(count);
        for _ in 0..count {
            let [time_s, x, y, yaw] = [r.f64()?, r.f64()?, r.f64()?, r.f64()?];
            let n = r.len(16)?;
            let mut points = Vec::with_capacity(n);
            for _ in 0..n {
                points.push(Point2::new(r.f64()?, r.f64()?));
            }
            saved.push(SavedKeyframe {
                time_s,
                map_from_base: Pose2::new([x, y].into(), yaw),
                points,
            });
        }
        r.finish()?;
        if layers.insert(layer, saved).is_some() {
            return Err(MapFileError::Malformed(format!(
                "layer {layer} saved twice"
            )));
        }
    }
    Ok(layers)
}

fn grow(extent: &mut Option<[f64; 4]>, p: &Point2<f64>) {
    let e = extent.get_or_insert([p.x, p.y, p.x, p.y]);
    *e = [e[0].min(p.x), e[1].min(p.y), e[2].max(p.x), e[3].max(p.y)];
}
