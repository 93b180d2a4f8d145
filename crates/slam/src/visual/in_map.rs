//! Localisation in a saved visual map (`slamkit vo --localize MAP.skmap`): the map's keyframes
//! (their poses, and their features with ORB descriptors, as a `--slam` run saves them) in a
//! place index, and a frame looked for among them ([`slamkit_vo::relocalisation`]).
//!
//! A [`super::VisualSlam`] built with [`super::VisualSlam::localising_in`] has no pose until a
//! frame is found in the map; from then on odometry tracks, and the map is searched again
//! whenever tracking is lost. The map is never changed. Not yet done (issue 20, item 6):
//! tracking against the map's points. Putting every tracked frame back where a 3D–3D match
//! with a keyframe says it is was tried and made things worse on 7-Scenes (0.19 m against
//! the map's trajectory instead of 0.031 m): one such match is far noisier than odometry.
//!
//! Poses here are `map_from_tracked` of the tracked camera (the one features are in).

use slamkit_core::Pose3;
use slamkit_vo::covisibility::PlaceFeatures;
use slamkit_vo::place_index::PlaceIndex;
use slamkit_vo::relocalisation::{relocalise, RelocalisationConfig};
use slamkit_vo::VoConfig;

use crate::SlamError;

use super::keyframes::VisualMap;

/// The keyframes of a saved map, indexed for relocalisation.
#[derive(Debug)]
pub(super) struct MapLocaliser {
    config: RelocalisationConfig,
    index: PlaceIndex,
    /// Per keyframe: `map_from_tracked` and its features in the tracked camera.
    keyframes: Vec<(Pose3, PlaceFeatures)>,
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
            index,
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
}
