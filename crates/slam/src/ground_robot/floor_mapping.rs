//! Localisation and mapping of a ground robot from its RGB-D camera.
//!
//! Each frame goes through [`VisualSlam`] (RGB-D visual odometry: KLT features lifted by
//! depth, RANSAC + Gauss–Newton motion against the local map), whose camera pose gives the
//! base pose through the known camera mount. The frame's depth (every `depth_step_px`-th
//! pixel) is then inserted into a floor grid ([`FloorGrid`], Bayesian log-odds with Bresenham
//! free rays, obstacles in the 0.1–1.0 m band; Hornung et al., "OctoMap", 2013).
//!
//! Floor alignment comes from the known camera mount, not from a floor-plane fit
//! ([`slamkit_map::floor`]): the robot drives on a flat floor, so only the planar part of the VO
//! pose (x, y, yaw) is kept and the camera's height, pitch and roll are the mount's. A RANSAC
//! fit would give the same frame up to noise when the floor is in view, but the mount also holds
//! when the first frames see only a wall, and it stops VO's small pitch drift from tilting the
//! map: 1° of pitch moves a point 4 m away by 7 cm in height, enough to lift floor points into
//! the obstacle band.
//!
//! The floor grid's frame has the height along −y and the floor along (x, z); the world's floor
//! is (x, y) with z up, so points go through [`map_from_world`] and the grid's cells are the
//! world's (x, y) cells.
//!
//! Mapping (and planning) pause while the camera's angular rate, from consecutive VO poses,
//! exceeds the gate's limits ([`MotionGate`]); a frame VO fails on gives no pose.

use nalgebra::{Matrix3, Point2, Rotation3, UnitQuaternion};
use serde::Serialize;
use slamkit_core::camera::Intrinsics;
use slamkit_core::observation::{Observation, RgbdFrame};
use slamkit_core::pose::{pose2_to_pose3, pose3_to_pose2};
use slamkit_core::{Pose2, Pose3, StageTimings};
use slamkit_map::floor_grid::{FloorGrid, FloorGridConfig, FloorGridMethod};
use slamkit_map::TriGrid;
use slamkit_nav::gating::angular_rate;
use slamkit_nav::{MotionGate, MotionGateConfig};
use slamkit_vo::frame::Rig;
use slamkit_vo::{FrameStatus, VoConfig};
use std::time::Instant;

use crate::session::Update;
use crate::visual::{PointMapping, VisualSlam};
use crate::SlamError;

/// `map_from_world`: the world's (x, y, z-up) axes onto the floor grid's (x, z, −y).
pub fn map_from_world() -> Pose3 {
    let r = Matrix3::new(
        1.0, 0.0, 0.0, //
        0.0, 0.0, -1.0, //
        0.0, 1.0, 0.0,
    );
    Pose3::from_parts(
        nalgebra::Translation3::identity(),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)),
    )
}

/// Frame counters of the camera.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct CameraStats {
    /// Frames received.
    pub frames: usize,
    /// Frames VO tracked (or re-initialised on).
    pub tracked: usize,
    /// Frames VO failed on (no pose).
    pub failed: usize,
    /// VO (re-)initialisations.
    pub initialisations: usize,
    /// Tracked frames not mapped because the camera turned too fast.
    pub gated: usize,
}

/// The camera of a ground robot: intrinsics (depth registered to colour) and mounting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MountedCamera {
    /// Intrinsics of the colour and (registered) depth images.
    pub intrinsics: Intrinsics,
    /// Where the camera sits on the base.
    pub base_from_camera: Pose3,
}

/// A frame's outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameOutcome {
    /// The session's answer: `map_from_base` at the base's height (the map frame is the
    /// world's, the start being known), how VO tracked, the keyframes it added.
    pub update: Update,
    /// Estimated planar `world_from_base`; `None` when VO failed on the frame.
    pub world_from_base: Option<Pose2>,
    /// What VO made of the frame.
    pub status: FrameStatus,
    /// Mapping ran, and planning may.
    pub gate_open: bool,
}

/// VO, the floor grid and the motion gate.
#[derive(Debug)]
pub(super) struct FloorMapping {
    vo: VisualSlam,
    camera: MountedCamera,
    base_height_m: f64,
    depth_step_px: usize,
    grid: FloorGrid,
    gate: MotionGate,
    previous: Option<(f64, Pose3)>,
    stats: CameraStats,
}

impl FloorMapping {
    /// Starts at the known `world_from_base` with an empty floor grid covering the floor
    /// rectangle `[min, max]` (world x, y).
    pub(super) fn new(
        camera: MountedCamera,
        vo: &VoConfig,
        (grid, gate): (&FloorGridConfig, &MotionGateConfig),
        depth_step_px: usize,
        world_from_base: &Pose3,
        [min, max]: [Point2<f64>; 2],
    ) -> Result<Self, SlamError> {
        let k = camera.intrinsics;
        let visual = VisualSlam::starting_at(
            vo,
            Rig::Rgbd { color: k, depth: k },
            world_from_base * camera.base_from_camera,
        )?
        .with_point_map(PointMapping::Off)?;
        let cells = |span: f64| (span / grid.resolution_m).ceil().max(1.0) as usize;
        let floor = FloorGrid::new(
            cells(max.x - min.x),
            cells(max.y - min.y),
            min,
            grid.clone(),
        )?;
        Ok(Self {
            vo: visual,
            camera,
            base_height_m: world_from_base.translation.z,
            depth_step_px,
            grid: floor,
            gate: MotionGate::new(gate.clone())?,
            previous: None,
            stats: CameraStats::default(),
        })
    }

    /// Localises with `frame`, then maps its depth when the gate is open; VO's time goes to
    /// `vo` in `timings`, the grid's to `map`. `None` for a frame VO does not take (not an
    /// RGB-D frame of this camera).
    pub(super) fn process(
        &mut self,
        frame: RgbdFrame,
        timings: &mut StageTimings,
    ) -> Option<FrameOutcome> {
        let t = frame.timestamp;
        let depth_m = frame.depth_m.clone();
        let started = Instant::now();
        let visual = self.vo.process(Observation::Rgbd(frame));
        timings.record_since("vo", started);
        let visual = visual?;
        self.stats.frames += 1;
        let status = visual.frame;
        let mut update = Update {
            pose: None,
            ..visual.update
        };
        let world_from_camera = match (&status, visual.update.pose) {
            (FrameStatus::Initialised { .. } | FrameStatus::Tracked { .. }, Some(pose)) => pose,
            _ => {
                self.stats.failed += 1;
                self.previous = None;
                return Some(FrameOutcome {
                    update,
                    world_from_base: None,
                    status,
                    gate_open: false,
                });
            }
        };
        if matches!(status, FrameStatus::Initialised { .. }) {
            self.stats.initialisations += 1;
        }
        self.stats.tracked += 1;
        let rate = self
            .previous
            .and_then(|(t0, p0)| angular_rate(&p0, &world_from_camera, t - t0));
        // with no previous pose (the first frame, or after a failure) the gate keeps its state
        let gate_open = match self.previous {
            Some((t0, _)) => self.gate.update(rate.as_ref(), t - t0),
            None => self.gate.is_open(),
        };
        self.previous = Some((t, world_from_camera));
        let base_from_camera = self.camera.base_from_camera;
        let world_from_base = pose3_to_pose2(&(world_from_camera * base_from_camera.inverse()));
        if gate_open {
            let started = Instant::now();
            let map_from_camera =
                map_from_world() * self.planar(&world_from_base) * base_from_camera;
            self.grid.insert_depth(
                &depth_m,
                &self.camera.intrinsics,
                &map_from_camera,
                self.depth_step_px,
            );
            timings.record_since("map", started);
        } else {
            self.stats.gated += 1;
        }
        update.pose = Some(self.planar(&world_from_base));
        Some(FrameOutcome {
            update,
            world_from_base: Some(world_from_base),
            status,
            gate_open,
        })
    }

    /// The 3D base pose of a planar one at the base's known height.
    fn planar(&self, pose: &Pose2) -> Pose3 {
        let mut p = pose2_to_pose3(pose);
        p.translation.z = self.base_height_m;
        p
    }

    /// The map so far as a tri-state grid over the world's (x, y).
    pub(super) fn grid(&self) -> TriGrid {
        self.grid.to_tri_grid(FloorGridMethod::LogOdds)
    }

    /// Frame counters.
    pub(super) fn stats(&self) -> CameraStats {
        self.stats
    }

    /// The camera session (its keyframes are the map file's).
    pub(super) fn visual(&self) -> &VisualSlam {
        &self.vo
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    #[test]
    fn map_frame_has_height_along_minus_y_and_the_floor_along_x_z() {
        let p = map_from_world() * Point3::new(1.0, 2.0, 0.3);
        assert!((p - Point3::new(1.0, -0.3, 2.0)).norm() < 1e-12);
    }
}
