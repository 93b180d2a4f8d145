//! Localisation in a saved visual map (`slamkit vo --localize MAP.skmap`): the map's keyframes
//! (their poses, and their features with ORB descriptors, as a `--slam` run saves them) in a
//! place index, and a frame looked for among them ([`slamkit_vo::relocalisation`]).
//!
//! A [`super::VisualSlam`] built with [`super::VisualSlam::localising_in`] has no pose until a
//! frame is found in the map; from then on odometry tracks, and the map is searched again
//! whenever tracking is lost. Each tracked frame is then measured against the map's points
//! ([`MapLocaliser::track`], `slamkit_vo::map_tracking`: the points of the keyframes nearest
//! the odometry's pose, projected, matched and refined on), and odometry carries on from
//! where the map put it; where the map has too few points in view (a part of the scene it
//! lacks), odometry alone, until the map's points match again. The map is never changed.
//!
//! Poses here are `map_from_tracked` of the tracked camera (the one features are in).

use slamkit_core::Pose3;
use slamkit_vo::covisibility::PlaceFeatures;
use slamkit_vo::map_tracking::{nearest_keyframes, track_in_map, MapPoint, MapTrackingConfig};
use slamkit_vo::motion::{MotionConfig, StereoCamera};
use slamkit_vo::place_index::PlaceIndex;
use slamkit_vo::relocalisation::{relocalise, RelocalisationConfig};
use slamkit_vo::VoConfig;

use crate::SlamError;

use super::keyframes::VisualMap;

/// The keyframes of a saved map, indexed for relocalisation.
#[derive(Debug)]
pub(super) struct MapLocaliser {
    config: RelocalisationConfig,
    tracking: MapTrackingConfig,
    motion: MotionConfig,
    index: PlaceIndex,
    /// Per keyframe: `map_from_tracked` and its features in the tracked camera.
    keyframes: Vec<(Pose3, PlaceFeatures)>,
    /// The keyframes' `map_from_tracked` alone, to find the nearest.
    poses: Vec<Pose3>,
}

impl MapLocaliser {
    /// Indexes the keyframes of `map`, whose points are in the rig's reference camera;
    /// `tracked_from_camera` moves them into the tracked one.
    ///
    /// # Errors
    /// [`SlamError::Vo`] for bad settings, [`SlamError::Map`] for a map without descriptors
    /// (saved by a run of the KLT front end without `--slam`: nothing to recognise places by).
    pub(super) fn new(
        config: &VoConfig,
        map: &VisualMap,
        tracked_from_camera: &Pose3,
    ) -> Result<Self, SlamError> {
        let mut index = PlaceIndex::new(config.loop_closure.place_index.clone())?;
        let camera_from_tracked = tracked_from_camera.inverse();
        let mut keyframes = Vec::with_capacity(map.keyframes.len());
        for (id, k) in map.keyframes.iter().enumerate() {
            let mut features = PlaceFeatures::default();
            for (p, d) in &k.points {
                if let Some(d) = d {
                    features.points.push(tracked_from_camera * p);
                    features.descriptors.push(*d);
                }
            }
            index.insert(id, &features.descriptors);
            keyframes.push((k.pose * camera_from_tracked, features));
        }
        if index.is_empty() {
            return Err(SlamError::Map(
                "the map holds no ORB descriptors to recognise places by (save it with --slam)"
                    .into(),
            ));
        }
        Ok(Self {
            config: config.loop_closure.relocalisation.clone(),
            tracking: config.loop_closure.map_tracking.clone(),
            motion: config.motion.clone(),
            index,
            poses: keyframes.iter().map(|k| k.0).collect(),
            keyframes,
        })
    }

    /// `map_from_tracked` of a frame with features `place`, where found in the map.
    pub(super) fn locate(&self, place: &PlaceFeatures) -> Option<Pose3> {
        let found = relocalise(
            place,
            &self.index,
            |i| self.keyframes.get(i).map(|k| &k.1),
            &self.config,
        )?;
        let (map_from_keyframe, _) = self.keyframes.get(found.keyframe)?;
        Some(map_from_keyframe * found.verified.candidate_from_query)
    }

    /// `map_from_tracked` of a frame with features `place` seen by `camera`, measured from
    /// the points of the keyframes nearest its odometry pose `map_from_predicted`; `None`
    /// where they do not match it (or map tracking is off).
    pub(super) fn track(
        &self,
        place: &PlaceFeatures,
        camera: &StereoCamera,
        map_from_predicted: &Pose3,
    ) -> Option<Pose3> {
        if !self.tracking.enabled {
            return None;
        }
        let points: Vec<MapPoint> =
            nearest_keyframes(&self.poses, map_from_predicted, &self.tracking)
                .into_iter()
                .filter_map(|i| self.keyframes.get(i))
                .flat_map(|(map_from_keyframe, features)| {
                    features
                        .points
                        .iter()
                        .zip(&features.descriptors)
                        .map(move |(p, d)| MapPoint {
                            position: map_from_keyframe * p,
                            descriptor: *d,
                        })
                })
                .collect();
        let fix = track_in_map(
            &points,
            place,
            camera,
            map_from_predicted,
            &self.tracking,
            &self.motion,
        )?;
        Some(fix.map_from_camera)
    }
}
