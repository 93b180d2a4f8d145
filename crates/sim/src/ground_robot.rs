//! A simulated differential-drive ground robot driven by velocity commands, for closed loops
//! (`slamkit nav`): its true planar pose, the RGB-D frames its camera sees from there, moves
//! that the world's obstacles refuse, and the world rasterised into the grid on which the
//! shortest possible path is planned for scoring.
//!
//! Unlike [`crate::Simulation`]'s robots, which follow a scripted path, this one goes where it
//! is told: each step integrates a speed and yaw-rate command exactly (unicycle arcs). A move
//! that would bring the robot's body into an obstacle is refused and the robot stays put.

use nalgebra::{Point2, Point3, Vector2};
use slamkit_core::observation::RgbdFrame;
use slamkit_core::pose::{pose2_to_pose3, pose3_to_pose2};
use slamkit_core::{Pose2, Pose3};
use slamkit_map::{Occupancy, TriGrid};

use crate::camera::render_rgbd;
use crate::{RobotKind, Scene, SimConfig, SimError, Simulation, Stream, World};

/// A ground robot that drives by command through a simulated world.
#[derive(Debug, Clone)]
pub struct GroundRobot {
    sim: Simulation,
    truth: Pose2,
    base_height_m: f64,
}

impl GroundRobot {
    /// The robot at the first point of `world`'s drive path, with the sensors of `config`
    /// (its robot is always the differential-drive one) and the noise of `seed`.
    ///
    /// # Errors
    /// [`SimError`] for a world without a usable drive path or a bad sensor configuration.
    pub fn new(world: World, config: &SimConfig, seed: u64) -> Result<Self, SimError> {
        let config = SimConfig {
            robot: RobotKind::DiffDrive,
            ..config.clone()
        };
        let sim = Simulation::new(world, config, seed)?;
        let start = sim.state_at(0.0).world_from_base;
        Ok(Self {
            truth: pose3_to_pose2(&start),
            base_height_m: start.translation.z,
            sim,
        })
    }

    /// The simulation: world, scene, sensor settings, seed.
    pub fn simulation(&self) -> &Simulation {
        &self.sim
    }

    /// The true planar `world_from_base`.
    pub fn truth(&self) -> Pose2 {
        self.truth
    }

    /// Height of the base above the floor \[m\].
    pub fn base_height_m(&self) -> f64 {
        self.base_height_m
    }

    /// A planar pose as a 3D `world_from_base` at the base's height.
    pub fn at_base_height(&self, pose: &Pose2) -> Pose3 {
        let mut p = pose2_to_pose3(pose);
        p.translation.z = self.base_height_m;
        p
    }

    /// Frame number `index` (which selects its noise) of the RGB-D camera (`config.rgbd`) at
    /// the true pose, stamped `timestamp`.
    pub fn rgbd_frame(&self, index: usize, timestamp: f64) -> RgbdFrame {
        let camera = &self.sim.config.rgbd;
        let world_from_camera = self.at_base_height(&self.truth) * camera.mount.base_from_camera();
        let (color, depth_m) = render_rgbd(
            &self.sim.scene,
            camera,
            world_from_camera,
            &self.sim.rng(Stream::Image, index as u64),
            &self.sim.rng(Stream::Depth, index as u64),
        );
        RgbdFrame {
            timestamp,
            color,
            depth_m,
        }
    }

    /// Drives `dt_s` at `speed_m_s` turning at `yaw_rate_rad_s`; returns false (and stays put)
    /// when the move would bring a body of `radius_m` into an obstacle.
    pub fn drive(&mut self, speed_m_s: f64, yaw_rate_rad_s: f64, dt_s: f64, radius_m: f64) -> bool {
        let next = unicycle_step(&self.truth, speed_m_s, yaw_rate_rad_s, dt_s);
        if body_collides(&self.sim.scene, &next, self.base_height_m, radius_m) {
            return false;
        }
        self.truth = next;
        true
    }

    /// The world as a grid at `resolution_m`: a cell is occupied where a robot-body-height
    /// probe of half a cell's size touches an obstacle or the room's walls.
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] for a resolution that gives no grid (not positive, or not
    /// finite).
    pub fn rasterise_world(&self, resolution_m: f64) -> Result<TriGrid, SimError> {
        let [sx, sy] = self.sim.world.size_m;
        let (w, h) = (
            (sx / resolution_m).ceil().max(1.0) as usize,
            (sy / resolution_m).ceil().max(1.0) as usize,
        );
        let mut grid = TriGrid::new(w, h, resolution_m, Point2::origin(), Occupancy::Free)
            .ok_or_else(|| {
                SimError::InvalidConfig(format!("no grid of the world at {resolution_m} m"))
            })?;
        for y in 0..grid.height() {
            for x in 0..grid.width() {
                let c = grid.cell_center_m(x, y);
                let pose = Pose2::new(c.coords, 0.0);
                if body_collides(
                    &self.sim.scene,
                    &pose,
                    self.base_height_m,
                    resolution_m / 2.0,
                ) {
                    grid.set(x, y, Occupancy::Occupied);
                }
            }
        }
        Ok(grid)
    }
}

/// The pose after driving at `v` and turning at `w` for `dt` (exact arc).
pub fn unicycle_step(pose: &Pose2, v: f64, w: f64, dt: f64) -> Pose2 {
    let turn = w * dt;
    let local = if turn.abs() < 1e-9 {
        Vector2::new(v * dt, 0.0)
    } else {
        let r = v / w;
        Vector2::new(r * turn.sin(), r * (1.0 - turn.cos()))
    };
    pose * Pose2::new(local, turn)
}

/// True when the robot's body (a sphere of `radius_m` centred `radius_m` above the floor, at
/// least at base height) at `pose` touches an obstacle or leaves the room.
fn body_collides(scene: &Scene, pose: &Pose2, base_height_m: f64, radius_m: f64) -> bool {
    let t = pose.translation.vector;
    let z = base_height_m.max(radius_m) + 0.1;
    scene.collides(&Point3::new(t.x, t.y, z), radius_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unicycle_arcs() {
        let quarter = unicycle_step(&Pose2::identity(), 1.0, 1.0, std::f64::consts::FRAC_PI_2);
        assert!((quarter.translation.vector - Vector2::new(1.0, 1.0)).norm() < 1e-9);
        let straight = unicycle_step(&Pose2::identity(), 0.5, 0.0, 2.0);
        assert!((straight.translation.vector - Vector2::new(1.0, 0.0)).norm() < 1e-12);
    }
}
