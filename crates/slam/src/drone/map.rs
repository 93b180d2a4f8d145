//! A drone session's map file: the header ([`Rig::Drone`]), then
//!
//! * `DCFG`: the session's settings as JSON (layer height and range-finder offsets say which
//!   height each layer is);
//! * one `LAYR` section per height layer, lowest first: `i32` layer index, `u32` keyframe
//!   count, then per keyframe `f64` time \[s\], `f64` x, y \[m\] and yaw \[rad\] of
//!   `map_from_base`, `u32` point count and the points' `f64` x, y in the keyframe's base
//!   frame \[m\]. Normals and grids are rebuilt from the points.

use super::DroneSlam;
use crate::map_file::codec::{Reader, Writer};
use crate::map_file::{MapFile, MapFileError, MapHeader, Rig, Section};
use nalgebra::Point2;
use slamkit_core::Pose2;
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

/// The map file of `session`'s layers as they stand.
pub(crate) fn to_map_file(session: &DroneSlam) -> Result<MapFile, MapFileError> {
    let mut layers: BTreeMap<i64, Vec<SavedKeyframe>> = BTreeMap::new();
    for k in session.layered().keyframes() {
        layers.entry(k.layer).or_default().push(SavedKeyframe {
            time_s: k.time_s,
            map_from_base: session.map_from_world * k.keyframe.world_from_base,
            points: k.keyframe.points.clone(),
        });
    }
    let mut sections = vec![Section {
        tag: CONFIG_TAG,
        data: serde_json::to_vec(session.config())
            .map_err(|e| MapFileError::Malformed(format!("settings as JSON: {e}")))?,
    }];
    let mut extent: Option<[f64; 4]> = None;
    let mut keyframes = 0;
    for (layer, saved) in &layers {
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
