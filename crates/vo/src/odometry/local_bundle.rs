//! The tracker's side of the local bundle adjustment ([`crate::local_ba`]): the recent key
//! frames with what they observed, the bundle handed out after each key frame, and its result
//! taken back into the tracking state.
//!
//! The adjustment may run on another thread while tracking goes on ([`Odometry::take_bundle`],
//! [`LocalBundle::adjust`], [`Odometry::apply_bundle`]), so its result is applied as a change:
//! each landmark moves by what the adjustment moved it (observations averaged in meanwhile
//! stay), each key frame by its own pose correction, and the current pose, the reference and
//! key frames newer than the bundle by the correction of the bundle's newest key frame — the
//! motion tracked since is kept, as a loop closure's correction keeps it. A bundle taken before
//! a correction of the map frame ([`Odometry::correct`]) is dropped.

use std::collections::HashMap;

use nalgebra::{Point2, Point3};
use slamkit_core::Pose3;

use super::{renormalised, Odometry, RefFeature};
use crate::local_ba::{adjust, Bundle, BundleObservation, BundleSummary, LocalBaConfig};
use crate::motion::{MeasurementNoise, StereoCamera};

/// A key frame as the local bundle adjustment sees it: its number, its pose and, per landmark
/// it observed, the pixel and the measured depth.
#[derive(Debug, Clone)]
pub(super) struct KeyframeView {
    serial: usize,
    pub(super) world_from_camera: Pose3,
    seen: Vec<(u64, Point2<f64>, f64)>,
}

/// The recent key frames and the landmarks two or more of them observe, as they were when
/// taken, to be adjusted ([`LocalBundle::adjust`]) and applied ([`Odometry::apply_bundle`]).
#[derive(Debug, Clone)]
pub struct LocalBundle {
    bundle: Bundle,
    start: Bundle,
    landmarks: Vec<u64>,
    keyframes: Vec<usize>,
    epoch: usize,
    cam: StereoCamera,
    noise: MeasurementNoise,
    config: LocalBaConfig,
}

impl LocalBundle {
    /// Runs the adjustment.
    pub fn adjust(&mut self) -> BundleSummary {
        adjust(&mut self.bundle, &self.cam, &self.noise, &self.config)
    }

    /// Key frames (free and held) and points in the bundle.
    pub fn size(&self) -> (usize, usize) {
        (
            self.bundle.camera_from_world.len(),
            self.bundle.points.len(),
        )
    }
}

impl Odometry {
    /// Hands the local bundle adjustment to the caller: [`Odometry::track`] then no longer runs
    /// it, and the caller runs each bundle [`Odometry::take_bundle`] gives (on a thread of its
    /// own) and applies it ([`Odometry::apply_bundle`]).
    pub fn hand_off_bundles(&mut self) {
        self.bundle_inline = false;
    }

    /// Adds the key frame just made (at the current pose, with `features`) to the recent ones;
    /// a bundle adjustment is due.
    pub(super) fn add_recent_keyframe(&mut self, features: &[RefFeature], cam: StereoCamera) {
        let config = &self.config.local_map.bundle;
        self.recent.push_back(KeyframeView {
            serial: self.keyframes,
            world_from_camera: self.world_from_camera,
            seen: features
                .iter()
                .filter_map(|f| Some((f.landmark?, f.pixel, f.point.z)))
                .collect(),
        });
        while self.recent.len() > config.window_keyframes {
            self.recent.pop_front();
        }
        self.bundle_due = Some(cam);
    }

    /// True when a key frame was made since the last [`Odometry::take_bundle`].
    pub fn bundle_due(&self) -> bool {
        self.bundle_due.is_some()
    }

    /// Runs the due bundle adjustment now, when it is not handed off.
    pub(super) fn adjust_inline(&mut self) {
        if self.bundle_inline {
            if let Some(mut bundle) = self.take_bundle() {
                bundle.adjust();
                self.apply_bundle(&bundle);
            }
        }
    }

    /// The bundle due after the last key frame (once): the recent key frames, the oldest
    /// `fixed_keyframes` held, and the landmarks two or more of them observe; `None` when none
    /// is due or too few key frames are recent.
    pub fn take_bundle(&mut self) -> Option<LocalBundle> {
        let cam = self.bundle_due.take()?;
        let config = &self.config.local_map.bundle;
        if self.recent.len() <= config.fixed_keyframes {
            return None;
        }
        let mut seen_by: HashMap<u64, usize> = HashMap::new();
        for k in &self.recent {
            for (id, _, _) in &k.seen {
                *seen_by.entry(*id).or_default() += 1;
            }
        }
        let mut bundle = Bundle {
            camera_from_world: self
                .recent
                .iter()
                .map(|k| k.world_from_camera.inverse())
                .collect(),
            fixed: (0..self.recent.len())
                .map(|i| i < config.fixed_keyframes)
                .collect(),
            ..Bundle::default()
        };
        let mut index: HashMap<u64, usize> = HashMap::new();
        let mut landmarks = Vec::new();
        for (keyframe, k) in self.recent.iter().enumerate() {
            for &(id, pixel, depth_m) in &k.seen {
                if seen_by.get(&id).map_or(true, |&n| n < 2) {
                    continue;
                }
                let point = match index.get(&id) {
                    Some(&i) => i,
                    None => {
                        let Some(l) = self.map.get(id) else { continue };
                        index.insert(id, bundle.points.len());
                        landmarks.push(id);
                        bundle.points.push(l.position());
                        bundle.points.len() - 1
                    }
                };
                bundle.observations.push(BundleObservation {
                    keyframe,
                    point,
                    pixel,
                    depth_m,
                });
            }
        }
        Some(LocalBundle {
            start: bundle.clone(),
            bundle,
            landmarks,
            keyframes: self.recent.iter().map(|k| k.serial).collect(),
            epoch: self.epoch,
            cam,
            noise: self.config.motion.noise.clone(),
            config: config.clone(),
        })
    }

    /// Applies an adjusted bundle (see the module documentation); false when it was taken
    /// before a correction of the map frame, and dropped.
    pub fn apply_bundle(&mut self, b: &LocalBundle) -> bool {
        if b.epoch != self.epoch {
            return false;
        }
        // world_new_from_world_old of a key frame: its refined pose over its pose when taken
        let change = |i: usize| -> Option<Pose3> {
            let after = b.bundle.camera_from_world.get(i)?;
            let before = b.start.camera_from_world.get(i)?;
            Some(after.inverse() * before)
        };
        for k in &mut self.recent {
            if let Some(i) = b.keyframes.iter().position(|&s| s == k.serial) {
                if let Some(c) = change(i) {
                    k.world_from_camera = renormalised(c * k.world_from_camera);
                }
            }
        }
        let newest = b.keyframes.last().copied();
        let Some(c) = b.keyframes.len().checked_sub(1).and_then(change) else {
            return true;
        };
        for k in &mut self.recent {
            if newest.is_some_and(|n| k.serial > n) {
                k.world_from_camera = renormalised(c * k.world_from_camera);
            }
        }
        self.world_from_camera = renormalised(c * self.world_from_camera);
        if let Some(r) = &mut self.reference {
            r.world_from_camera = renormalised(c * r.world_from_camera);
        }
        for ((id, after), before) in b
            .landmarks
            .iter()
            .zip(&b.bundle.points)
            .zip(&b.start.points)
        {
            if let Some(l) = self.map.get(*id) {
                let moved: Point3<f64> = l.position() + (after - before);
                self.map.set_position(*id, &moved);
            }
        }
        true
    }
}
