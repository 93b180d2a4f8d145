//! The back end of a [`super::VisualSlam`] session with `loop_closure.enabled`: keyframes,
//! their map points and covisibility graph, the place index, loop detection and the pose graph
//! that a verified loop corrects (`slamkit_vo::{covisibility, place_index, loop_closure,
//! pose_graph}`).
//!
//! A tracked frame becomes a keyframe when it is the first, when tracking restarted on it, or
//! when it moved `keyframe_distance_m` or turned `keyframe_angle_deg` from the last keyframe;
//! every other tracked frame is kept as its pose relative to the last keyframe, so it moves
//! with that keyframe when a loop closes. Each new keyframe's features are associated with the
//! previous keyframe's (map points), its descriptors query the place index (the keyframes not
//! covisible with it and at least `min_keyframes_apart` older), candidates consistent over
//! `temporal_consistency` keyframes are verified, and a verified loop adds an edge to the pose
//! graph of keyframes (consecutive keyframes joined by the odometry between them), which
//! Levenberg–Marquardt then optimises, the first keyframe fixed. The whole tracking state then
//! moves with the newest keyframe ([`slamkit_vo::Odometry::correct`]).
//!
//! The map stays bounded when the robot comes back (`cull_redundant_keyframes`): a frame due
//! to become a keyframe that lies within the keyframe spacing of an existing keyframe (so that
//! keyframe already stands for its view) is verified against it as a loop is; when the
//! measured pose agrees with odometry's to `max_localisation_correction`, the frame is
//! localised in the map instead of added. Its features re-observe that keyframe's map points
//! (no new map point, no place-index entry, no pose-graph node), the keyframe becomes the
//! reference the following frames are attached to (and the next keyframe's odometry edge
//! starts from), and the tracker is moved onto the measured pose (only the tracker moves, not
//! the map). A larger disagreement is drift: the frame becomes a keyframe and loop detection
//! deals with it. This is the alternative to ORB-SLAM's culling rule (a keyframe whose map
//! points are 90 % seen by three others) for a back end whose keyframes are linked to their
//! predecessor only: a redundant keyframe is never made, so nothing has to be unlinked from
//! the place index, the covisibility graph or the pose graph.
//!
//! When tracking is lost, each new frame is looked for among the keyframes
//! ([`LoopClosing::relocalise`], `slamkit_vo::relocalisation`); the frame it is found in
//! becomes a keyframe joined to the one it was verified against by the measured relative pose,
//! so the map stays one map in one frame.
//!
//! Poses here are `world_from_tracked` of the tracked camera (the one features are in).

use nalgebra::{Matrix6, UnitQuaternion, Vector6};
use serde::Serialize;
use slamkit_core::{Pose3, Trajectory};
use slamkit_vo::covisibility::{associate, Covisibility, PlaceFeatures};
use slamkit_vo::loop_closure::{verify, Consistency, LoopClosureConfig, VerifiedLoop};
use slamkit_vo::metrics::ClosureCheck;
use slamkit_vo::place_index::PlaceIndex;
use slamkit_vo::pose_graph::{Edge, LmConfig, PoseGraph};
use slamkit_vo::relocalisation::{relocalise, Relocalisation};
use slamkit_vo::VoError;

use super::keyframes::{Keyframe as MapKeyframe, VisualMap};

/// Odometry between keyframes across a tracking restart is a guess (the pose held over the
/// failed frames): its edge is this many times less certain.
const RESTART_SIGMA_FACTOR: f64 = 100.0;

/// `closures` scored against `ground_truth` ([`slamkit_vo::metrics::check_closures`]): a
/// closure is wrong when the truth disagrees with it by more than 0.3 m or 10°.
pub fn check_closures(closures: &[LoopClosure], ground_truth: &Trajectory) -> ClosureCheck {
    let relative: Vec<_> = closures
        .iter()
        .map(|c| {
            (
                c.query_timestamp,
                c.candidate_timestamp,
                c.candidate_from_query,
            )
        })
        .collect();
    slamkit_vo::metrics::check_closures(&relative, ground_truth)
}

/// Counts of the loop-closing back end.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct LoopStats {
    /// Keyframes taken.
    pub keyframes: usize,
    /// Map points (features of keyframes, one per scene point found again).
    pub map_points: usize,
    /// Candidates that passed the place index and temporal consistency and were verified.
    pub verified: usize,
    /// Verified candidates accepted as loops.
    pub accepted: usize,
    /// Verified candidates rejected by geometry.
    pub rejected: usize,
    /// Frames due to become keyframes that were localised against an existing keyframe
    /// instead (`cull_redundant_keyframes`): keyframes the map did not grow by.
    pub localised: usize,
    /// Looking for the camera in the map after tracking was lost.
    pub relocalisation: RelocalisationStats,
}

/// An accepted loop between two keyframes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LoopClosure {
    /// Time of the keyframe that saw the place again \[s\].
    pub query_timestamp: f64,
    /// Time of the earlier keyframe it saw \[s\].
    pub candidate_timestamp: f64,
    /// The query keyframe's camera in the candidate's, as verification measured it.
    #[serde(skip)]
    pub candidate_from_query: Pose3,
    /// Inlier matches.
    pub inliers: usize,
    /// RMS point distance of the inliers \[m\].
    pub rms_m: f64,
}

/// How the world moved for the tracker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Correction {
    /// The move of the world (applied to the tracker's whole state).
    pub(super) corrected_from_world: Pose3,
    /// A loop closed and the map moved; otherwise a frame was localised in the map and only
    /// the tracker moves onto it.
    pub(super) loop_closed: bool,
}

/// How a tracked frame follows the frames before it.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Joined {
    /// Tracked from the previous frame: odometry links them.
    Tracked,
    /// Tracking (re)started on it at the last pose: odometry is a guess.
    Restarted,
    /// Found in the map after tracking was lost: its pose is measured from a keyframe.
    Relocalised(Relocalisation),
}

/// Counts of relocalisation.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RelocalisationStats {
    /// Frames looked for in the map while tracking was lost.
    pub attempts: usize,
    /// Frames found (tracking resumed in the map's frame).
    pub found: usize,
}

#[derive(Debug)]
struct Keyframe {
    timestamp: f64,
    world_from_tracked: Pose3,
    features: PlaceFeatures,
}

/// Keyframes, place index, covisibility and pose graph.
#[derive(Debug)]
pub(super) struct LoopClosing {
    config: LoopClosureConfig,
    index: PlaceIndex,
    covisibility: Covisibility,
    keyframes: Vec<Keyframe>,
    /// The keyframe tracked frames are attached to: the last one added, or the one the last
    /// frame due to become a keyframe was localised against.
    reference: usize,
    edges: Vec<Edge>,
    consistency: Consistency,
    /// Every tracked frame: time, its keyframe, `keyframe_from_frame`.
    frames: Vec<(f64, usize, Pose3)>,
    closures: Vec<LoopClosure>,
    /// Frames localised in the map instead of becoming keyframes, as loops (the frame the
    /// query, the keyframe the candidate).
    localisations: Vec<LoopClosure>,
    stats: LoopStats,
}

impl LoopClosing {
    pub(super) fn new(config: &LoopClosureConfig) -> Result<Self, VoError> {
        config.validate()?;
        Ok(Self {
            config: config.clone(),
            index: PlaceIndex::new(config.place_index.clone())?,
            covisibility: Covisibility::default(),
            keyframes: Vec::new(),
            reference: 0,
            edges: Vec::new(),
            consistency: Consistency::default(),
            frames: Vec::new(),
            closures: Vec::new(),
            localisations: Vec::new(),
            stats: LoopStats::default(),
        })
    }

    /// Looks for a frame with features `place` among the keyframes (counted as an attempt);
    /// where found, the keyframe and the frame's `world_from_tracked`.
    pub(super) fn relocalise(&mut self, place: &PlaceFeatures) -> Option<(Relocalisation, Pose3)> {
        self.stats.relocalisation.attempts += 1;
        let found = relocalise(
            place,
            &self.index,
            |i| self.keyframes.get(i).map(|k| &k.features),
            &self.config.relocalisation,
        )?;
        let keyframe = self.keyframes.get(found.keyframe)?;
        let pose = keyframe.world_from_tracked * found.verified.candidate_from_query;
        Some((found, pose))
    }

    /// Takes a tracked frame at `world_from_tracked` with its place features, `joined` to the
    /// frames before it as it says. Returns the correction when a loop closed (the map moved)
    /// or the frame was localised in the map (the tracker moves onto it).
    pub(super) fn add_frame(
        &mut self,
        timestamp: f64,
        world_from_tracked: Pose3,
        place: Option<PlaceFeatures>,
        joined: Joined,
    ) -> Option<Correction> {
        let is_keyframe = match self.keyframes.get(self.reference) {
            None => true,
            Some(k) => {
                joined != Joined::Tracked
                    || !self.within_spacing(&(k.world_from_tracked.inverse() * world_from_tracked))
            }
        };
        let place = place.unwrap_or_default();
        if is_keyframe && joined == Joined::Tracked {
            if let Some((keyframe, verified)) = self.localise_in_map(&world_from_tracked, &place) {
                let keyframe_from_frame = verified.candidate_from_query;
                self.stats.localised += 1;
                self.localisations.push(LoopClosure {
                    query_timestamp: timestamp,
                    candidate_timestamp: self.keyframes.get(keyframe)?.timestamp,
                    candidate_from_query: keyframe_from_frame,
                    inliers: verified.inliers.len(),
                    rms_m: verified.rms_m,
                });
                self.reference = keyframe;
                self.frames.push((timestamp, keyframe, keyframe_from_frame));
                let k = self.keyframes.get(keyframe)?;
                let corrected = k.world_from_tracked * keyframe_from_frame;
                return Some(Correction {
                    corrected_from_world: moving(&world_from_tracked, &corrected),
                    loop_closed: false,
                });
            }
        }
        let correction = if is_keyframe {
            self.add_keyframe(timestamp, world_from_tracked, place, joined)
                .map(|corrected_from_world| Correction {
                    corrected_from_world,
                    loop_closed: true,
                })
        } else {
            None
        };
        let last = self.reference;
        if let Some(k) = self.keyframes.get(last) {
            // a closure moved the keyframe but not `world_from_tracked`: the frame is at the
            // keyframe either way when it is one, else where odometry put it relative to it
            let keyframe_from_frame = if is_keyframe {
                Pose3::identity()
            } else {
                k.world_from_tracked.inverse() * world_from_tracked
            };
            self.frames.push((timestamp, last, keyframe_from_frame));
        }
        correction
    }

    /// True when `step` (a pose relative to a keyframe) is within the distance and angle that
    /// make a new keyframe.
    fn within_spacing(&self, step: &Pose3) -> bool {
        step.translation.vector.norm() < self.config.keyframe_distance_m
            && step.rotation.angle() < self.config.keyframe_angle_deg.to_radians()
    }

    /// The keyframe nearest to a frame at `world_from_tracked` (due to become a keyframe)
    /// within the keyframe spacing, when the frame's features `place` verify against it with a
    /// pose within `max_localisation_correction` of the one odometry predicts: the keyframe and
    /// the verification (`candidate_from_query` is `keyframe_from_frame`). `None` when culling
    /// is off or nothing matches.
    fn localise_in_map(
        &self,
        world_from_tracked: &Pose3,
        place: &PlaceFeatures,
    ) -> Option<(usize, VerifiedLoop)> {
        if !self.config.cull_redundant_keyframes || place.is_empty() {
            return None;
        }
        let (distance_m, angle_deg) = (
            self.config.keyframe_distance_m,
            self.config.keyframe_angle_deg,
        );
        let closeness = |step: &Pose3| {
            step.translation.vector.norm() / distance_m
                + step.rotation.angle().to_degrees() / angle_deg
        };
        let (keyframe, predicted) = self
            .keyframes
            .iter()
            .enumerate()
            .map(|(i, k)| (i, k.world_from_tracked.inverse() * world_from_tracked))
            .filter(|(_, step)| self.within_spacing(step))
            .min_by(|a, b| closeness(&a.1).total_cmp(&closeness(&b.1)))?;
        let k = self.keyframes.get(keyframe)?;
        let verified = verify(place, &k.features, &self.config.verification).ok()?;
        let error = predicted.inverse() * verified.candidate_from_query;
        let (max_m, max_deg) = self.config.max_localisation_correction;
        (error.translation.vector.norm() <= max_m && error.rotation.angle() <= max_deg.to_radians())
            .then_some((keyframe, verified))
    }

    fn add_keyframe(
        &mut self,
        timestamp: f64,
        world_from_tracked: Pose3,
        features: PlaceFeatures,
        joined: Joined,
    ) -> Option<Pose3> {
        let id = self.keyframes.len();
        let mut links = Vec::new();
        if let Joined::Relocalised(found) = joined {
            // the measured pose from the keyframe it was found in; nothing from the frames
            // before the loss
            self.stats.relocalisation.found += 1;
            self.edges.push(Edge {
                from: found.keyframe,
                to: id,
                from_from_to: found.verified.candidate_from_query,
                information: self.information(1.0),
                robust_scale: None,
            });
            links.push((found.keyframe, found.verified.inliers));
            self.consistency.reset();
        } else if let Some(prev) = self.keyframes.get(self.reference) {
            let prev_from_this = prev.world_from_tracked.inverse() * world_from_tracked;
            let factor = if joined == Joined::Restarted {
                RESTART_SIGMA_FACTOR
            } else {
                1.0
            };
            self.edges.push(Edge {
                from: self.reference,
                to: id,
                from_from_to: prev_from_this,
                information: self.information(factor),
                robust_scale: None,
            });
            let pairs = associate(
                &prev.features,
                &features,
                &prev_from_this,
                &self.config.verification.matching,
                self.config.association_tolerance,
            );
            links.push((self.reference, pairs));
        }
        let added = self.covisibility.add_keyframe(features.len(), &links);
        debug_assert_eq!(added, id);
        let closure = self.detect_loop(id, timestamp, &features);
        self.index.insert(id, &features.descriptors);
        self.keyframes.push(Keyframe {
            timestamp,
            world_from_tracked,
            features,
        });
        self.reference = id;
        self.stats.keyframes = self.keyframes.len();
        let correction = closure.and_then(|(candidate, verified)| {
            self.covisibility.merge(candidate, id, &verified.inliers);
            self.close_loop(candidate, id, verified.candidate_from_query)
        });
        self.stats.map_points = self.covisibility.points();
        correction
    }

    /// The information of an odometry or loop edge, its standard deviations times `factor`.
    fn information(&self, factor: f64) -> Matrix6<f64> {
        let (st, sr) = self.config.odometry_sigma;
        let (it, ir) = ((st * factor).powi(-2), (sr * factor).powi(-2));
        Matrix6::from_diagonal(&Vector6::new(it, it, it, ir, ir, ir))
    }

    /// Candidates for keyframe `id`, consistent ones verified; the first verified loop and its
    /// candidate.
    fn detect_loop(
        &mut self,
        id: usize,
        timestamp: f64,
        features: &PlaceFeatures,
    ) -> Option<(usize, VerifiedLoop)> {
        if features.is_empty() {
            self.consistency.reset();
            return None;
        }
        let min_votes = (self.config.min_vote_fraction * features.len() as f64).ceil() as usize;
        let neighbours = self.covisibility.neighbours(id);
        let candidates: Vec<usize> = self
            .index
            .query(&features.descriptors)
            .into_iter()
            .filter(|m| m.keyframe + self.config.min_keyframes_apart <= id)
            .filter(|m| m.votes >= min_votes.max(1))
            .filter(|m| {
                neighbours.get(&m.keyframe).copied().unwrap_or(0) <= self.config.max_shared_points
            })
            .take(self.config.candidates)
            .map(|m| m.keyframe)
            .collect();
        let runs = self
            .consistency
            .update(&candidates, self.config.consistency_window);
        for (candidate, run) in runs {
            if run < self.config.temporal_consistency {
                continue;
            }
            let Some(k) = self.keyframes.get(candidate) else {
                continue;
            };
            self.stats.verified += 1;
            match verify(features, &k.features, &self.config.verification) {
                Ok(v) => {
                    self.stats.accepted += 1;
                    self.closures.push(LoopClosure {
                        query_timestamp: timestamp,
                        candidate_timestamp: k.timestamp,
                        candidate_from_query: v.candidate_from_query,
                        inliers: v.inliers.len(),
                        rms_m: v.rms_m,
                    });
                    self.consistency.reset();
                    return Some((candidate, v));
                }
                Err(_) => self.stats.rejected += 1,
            }
        }
        None
    }

    /// Adds the loop edge `candidate → query` and optimises the keyframe poses; returns how
    /// the world moved at the query keyframe.
    fn close_loop(
        &mut self,
        candidate: usize,
        query: usize,
        candidate_from_query: Pose3,
    ) -> Option<Pose3> {
        self.edges.push(Edge {
            from: candidate,
            to: query,
            from_from_to: candidate_from_query,
            information: self.information(1.0),
            robust_scale: Some(self.config.loop_robust_scale),
        });
        let mut graph = PoseGraph::new();
        for k in &self.keyframes {
            graph.add_node(k.world_from_tracked);
        }
        for e in &self.edges {
            // the edges were built between existing, distinct keyframes from finite poses
            graph.add_edge(*e).ok()?;
        }
        graph.optimize(&LmConfig::default());
        let old = self.keyframes.get(query)?.world_from_tracked;
        for (k, pose) in self.keyframes.iter_mut().zip(graph.nodes()) {
            k.world_from_tracked = *pose;
        }
        let new = self.keyframes.get(query)?.world_from_tracked;
        Some(moving(&old, &new))
    }

    /// Every tracked frame at its keyframe's current pose, moved to the rig's reference
    /// camera by `tracked_from_camera`.
    pub(super) fn trajectory(&self, tracked_from_camera: &Pose3) -> Trajectory {
        let mut t = Trajectory::new();
        for (timestamp, k, keyframe_from_frame) in &self.frames {
            if let Some(k) = self.keyframes.get(*k) {
                t.push(
                    *timestamp,
                    k.world_from_tracked * keyframe_from_frame * tracked_from_camera,
                );
            }
        }
        t
    }

    /// The keyframes as a map file holds them, where loop closure left them: poses and
    /// feature points of the rig's reference camera (moved there by `tracked_from_camera`),
    /// every point with its ORB descriptor, so that a later session can recognise the places
    /// ([`super::VisualSlam::localising_in`]).
    pub(super) fn visual_map(&self, tracked_from_camera: &Pose3) -> VisualMap {
        let camera_from_tracked = tracked_from_camera.inverse();
        VisualMap {
            keyframes: self
                .keyframes
                .iter()
                .map(|k| MapKeyframe {
                    timestamp: k.timestamp,
                    pose: k.world_from_tracked * tracked_from_camera,
                    points: k
                        .features
                        .points
                        .iter()
                        .zip(&k.features.descriptors)
                        .map(|(p, d)| (camera_from_tracked * p, Some(*d)))
                        .collect(),
                })
                .collect(),
        }
    }

    /// The accepted loops, their relative poses moved to the rig's reference camera.
    pub(super) fn closures(&self, tracked_from_camera: &Pose3) -> Vec<LoopClosure> {
        in_camera(&self.closures, tracked_from_camera)
    }

    /// The localisations in the map (frames not made keyframes), as [`Self::closures`].
    pub(super) fn localisations(&self, tracked_from_camera: &Pose3) -> Vec<LoopClosure> {
        in_camera(&self.localisations, tracked_from_camera)
    }

    pub(super) fn stats(&self) -> LoopStats {
        self.stats
    }
}

/// The move of the world `new · old⁻¹` that takes a pose from `old` to `new`, its rotation
/// renormalised: the tracker composes one per localisation in the map, and the quaternion
/// inverse is its conjugate, so a norm off by ε would grow to (1 + ε)² with every
/// correction (a tracker tilting away after a few dozen localisations).
fn moving(old: &Pose3, new: &Pose3) -> Pose3 {
    let m = new * old.inverse();
    Pose3::from_parts(
        m.translation,
        UnitQuaternion::new_normalize(m.rotation.into_inner()),
    )
}

/// `relations` with their relative poses moved from the tracked camera to the rig's reference
/// camera (`tracked_from_camera`).
fn in_camera(relations: &[LoopClosure], tracked_from_camera: &Pose3) -> Vec<LoopClosure> {
    relations
        .iter()
        .map(|c| LoopClosure {
            candidate_from_query: tracked_from_camera.inverse()
                * c.candidate_from_query
                * tracked_from_camera,
            ..*c
        })
        .collect()
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use slamkit_vision::Descriptor;

    /// Points on a cylindrical wall of radius 4 m around the origin, each with a descriptor.
    struct World {
        points: Vec<Point3<f64>>,
        descriptors: Vec<Descriptor>,
    }

    /// `n` wall points; with `aliased`, the half at negative y repeats the descriptors of the
    /// half at positive y (a repeated texture) at other heights (another geometry).
    fn world(rng: &mut ChaCha8Rng, n: usize, aliased: bool) -> World {
        let mut w = World {
            points: Vec::new(),
            descriptors: Vec::new(),
        };
        for _ in 0..n {
            let a: f64 = rng.gen_range(0.0..std::f64::consts::PI);
            let d: Descriptor = rng.gen();
            for (angle, copy) in [(a, false), (-a, true)] {
                let h = rng.gen_range(-1.5..1.5);
                w.points
                    .push(Point3::new(4.0 * angle.cos(), 4.0 * angle.sin(), h));
                w.descriptors
                    .push(if copy && !aliased { rng.gen() } else { d });
            }
        }
        w
    }

    /// The camera at angle `a` on a circle of radius 1.5 m, looking outwards (z radial,
    /// y down).
    fn camera(a: f64) -> Pose3 {
        let z = Vector3::new(a.cos(), a.sin(), 0.0);
        let y = Vector3::new(0.0, 0.0, -1.0);
        let x = y.cross(&z);
        let r = nalgebra::Rotation3::from_basis_unchecked(&[x, y, z]);
        Pose3::from_parts(
            nalgebra::Translation3::from(z * 1.5),
            nalgebra::UnitQuaternion::from_rotation_matrix(&r),
        )
    }

    /// What the camera at `world_from_camera` sees: points ahead within ±40°, 3 mm noise,
    /// one descriptor bit in 256 flipped.
    fn view(rng: &mut ChaCha8Rng, w: &World, world_from_camera: &Pose3) -> PlaceFeatures {
        let mut f = PlaceFeatures::default();
        let camera_from_world = world_from_camera.inverse();
        for (p, d) in w.points.iter().zip(&w.descriptors) {
            let c = camera_from_world * p;
            if c.z > 0.5 && c.x.abs() < 0.84 * c.z && c.y.abs() < 0.84 * c.z {
                let noise =
                    Vector3::new(rng.gen(), rng.gen(), rng.gen()) * 0.006 - Vector3::repeat(0.003);
                f.points.push(c + noise);
                let mut d = *d;
                d[rng.gen_range(0..4)] ^= 1 << rng.gen_range(0..64);
                f.descriptors.push(d);
            }
        }
        f
    }

    /// Drives 1.3 laps at 3° a frame with odometry drifting 0.15° of yaw a frame; returns
    /// the back end, the true poses and the odometry's.
    fn drive(seed: u64, aliased: bool) -> (LoopClosing, Vec<Pose3>, Vec<Pose3>) {
        let mut loops = LoopClosing::new(&LoopClosureConfig {
            enabled: true,
            ..LoopClosureConfig::default()
        })
        .unwrap();
        let (truth, odometry) = drive_with(seed, aliased, 156, |t, pose, place, joined| {
            loops
                .add_frame(t, pose, Some(place), joined)
                .map(|c| c.corrected_from_world)
        });
        (loops, truth, odometry)
    }

    /// The drive of [`drive`] (`frames` frames, 120 a lap), each frame (time, odometry pose,
    /// features, how it is joined) handed to `back_end`, which returns a correction of the
    /// world to apply to odometry; the true poses and the odometry's.
    pub(in crate::visual) fn drive_with(
        seed: u64,
        aliased: bool,
        frames: u32,
        mut back_end: impl FnMut(f64, Pose3, PlaceFeatures, Joined) -> Option<Pose3>,
    ) -> (Vec<Pose3>, Vec<Pose3>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let w = world(&mut rng, 1500, aliased);
        let (mut truth, mut odometry): (Vec<Pose3>, Vec<Pose3>) = (Vec::new(), Vec::new());
        let mut drifted = camera(0.0);
        for i in 0..frames {
            let a = f64::from(i) * 3f64.to_radians();
            let pose = camera(a);
            if let Some(previous) = truth.last() {
                let step: Pose3 = previous.inverse() * pose;
                let drift = Pose3::new(Vector3::zeros(), Vector3::y() * 0.15f64.to_radians());
                drifted = drifted * step * drift;
            }
            let place = view(&mut rng, &w, &pose);
            let joined = if i == 0 {
                Joined::Restarted
            } else {
                Joined::Tracked
            };
            if let Some(correction) = back_end(f64::from(i), drifted, place, joined) {
                drifted = correction * drifted;
            }
            truth.push(pose);
            odometry.push(drifted);
        }
        (truth, odometry)
    }

    #[test]
    fn a_loop_around_a_room_is_closed_and_removes_the_drift() {
        let (loops, truth, _) = drive(1, false);
        let stats = loops.stats();
        assert!(stats.accepted >= 1, "{stats:?}");
        assert!(stats.keyframes > 30 && stats.map_points > 1000, "{stats:?}");
        // every closure agrees with the truth (frames are 1 s apart, so time = index)
        assert_relations_right(&loops, &truth);
        // without loop closure the yaw drift is 0.15° × 155 ≈ 23° at the end; with it, the
        // corrected trajectory ends near the truth
        assert_ends_near_the_truth(&loops, &truth, 0.15);
    }

    /// The corrected trajectory of `loops` has a pose per frame of `truth` and ends within
    /// 3° and `max_m` of it.
    fn assert_ends_near_the_truth(loops: &LoopClosing, truth: &[Pose3], max_m: f64) {
        let corrected = loops.trajectory(&Pose3::identity());
        assert_eq!(corrected.len(), truth.len());
        let end = corrected.poses.last().unwrap().pose;
        let err = truth.last().unwrap().inverse() * end;
        assert!(err.rotation.angle().to_degrees() < 3.0, "{err}");
        assert!(err.translation.vector.norm() < max_m, "{err}");
    }

    /// Every closure and localisation of `loops` agrees with `truth` to 2 cm.
    fn assert_relations_right(loops: &LoopClosing, truth: &[Pose3]) {
        let relations = loops.closures(&Pose3::identity());
        for c in relations
            .iter()
            .chain(&loops.localisations(&Pose3::identity()))
        {
            let q = truth[c.query_timestamp as usize];
            let k = truth[c.candidate_timestamp as usize];
            let err = (k.inverse() * q).inverse() * c.candidate_from_query;
            assert!(err.translation.vector.norm() < 0.02, "{c:?}: {err}");
        }
    }

    #[test]
    fn three_laps_keep_the_keyframes_of_the_first() {
        let mut loops = LoopClosing::new(&LoopClosureConfig {
            enabled: true,
            ..LoopClosureConfig::default()
        })
        .unwrap();
        let mut first_lap = LoopStats::default();
        let (truth, _) = drive_with(1, false, 360, |t, pose, place, joined| {
            if t == 120.0 {
                first_lap = loops.stats();
            }
            loops
                .add_frame(t, pose, Some(place), joined)
                .map(|c| c.corrected_from_world)
        });
        let stats = loops.stats();
        // the first lap closes its loop; laps 2 and 3 come back to its keyframes' places
        // (every 6°) and are localised there, a few keyframes added where drift outgrew the
        // localisation gate before a correction
        assert!(first_lap.accepted >= 1, "{first_lap:?}");
        assert!(
            10 * stats.keyframes <= 11 * first_lap.keyframes,
            "{first_lap:?} then {stats:?}"
        );
        assert!(stats.localised >= 100, "{stats:?}");
        assert_relations_right(&loops, &truth);
        assert_ends_near_the_truth(&loops, &truth, 0.05);
        // without culling every lap adds its keyframes again
        let mut unculled = LoopClosing::new(&LoopClosureConfig {
            enabled: true,
            cull_redundant_keyframes: false,
            ..LoopClosureConfig::default()
        })
        .unwrap();
        drive_with(1, false, 360, |t, pose, place, joined| {
            unculled
                .add_frame(t, pose, Some(place), joined)
                .map(|c| c.corrected_from_world)
        });
        assert!(unculled.stats().keyframes >= 2 * first_lap.keyframes);
        assert_eq!(unculled.stats().localised, 0);
    }

    #[test]
    fn a_repeated_texture_on_another_wall_is_not_taken_for_a_loop() {
        // half a lap in, the wall repeats the first half's descriptors at other heights:
        // the place index votes for the first half, geometry must say no
        let (loops, truth, _) = drive(2, true);
        let stats = loops.stats();
        assert!(stats.rejected >= 1, "{stats:?}");
        assert_relations_right(&loops, &truth);
    }
}
