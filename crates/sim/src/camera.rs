//! Simulated cameras: a ray-casting renderer shared by the RGB-D camera (here) and the stereo
//! pair ([`crate::stereo`]).
//!
//! Every pixel `(u, v)` (integer coordinates at pixel centres, as in OpenCV and TUM) casts one
//! ray through the undistorted pinhole `((u − cx)/fx, (v − cy)/fy, 1)` into the world
//! ([`Scene::cast`]); rows are rendered in parallel with rayon. Colour is [`Scene::shade`] of
//! the surface hit, in 8-bit sRGB levels, plus Gaussian pixel noise. The textures are fixed to
//! the world, so a surface point keeps its brightness from every viewpoint.
//!
//! Depth is the z coordinate of the hit in the camera frame (what TUM and OpenNI store), with
//! the axial noise model of a Kinect v1 measured by Nguyen, Izadi and Lovell ("Modeling Kinect
//! Sensor Noise for Improved 3D Reconstruction and Tracking", 3DIMPVT 2012, eq. 6):
//!
//! ```text
//! σ_z(z, θ) = 0.0012 + 0.0019 (z − 0.4)² + 0.0001/√z · θ² / (π/2 − θ)²     [m]
//! ```
//!
//! (`θ` the angle between the ray and the surface normal), then rounded to the 1/5000 m unit of
//! TUM's depth PNGs. Like the sensor, it gives no depth (0.0) nearer than its minimum range,
//! beyond its maximum range, at grazing angles (beyond `max_incidence_rad`, where Nguyen et al.
//! saw the returns vanish) and, rarely, at random. Not modelled: the projector's shadow beside
//! near edges, lateral noise, motion blur, rolling shutter, lens distortion, exposure changes.
//!
//! Noise is drawn per row from the frame's ChaCha8 stream at a fixed word offset, so a frame's
//! bytes depend only on (seed, frame index), never on the thread schedule.

use crate::scene::{Hit, Scene};
use crate::SimError;
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use slamkit_core::camera::Intrinsics;
use slamkit_core::image::{Image, RgbImage};
use slamkit_core::Pose3;

/// TUM RGB-D Freiburg 1 intrinsics `[fx, fy, cx, cy]` \[px\] (ORB-SLAM2 `TUM1.yaml`), 640×480.
pub const TUM_FR1_INTRINSICS: [f64; 4] = [517.306408, 516.469215, 318.643040, 255.313989];

/// Random words reserved for each image row of a frame's noise stream (far more than a row of
/// 640 pixels draws), so each row can seek to its own part of the stream.
const ROW_WORDS: u128 = 1 << 20;

/// Where a camera sits on the robot: a position on the base and a downward tilt of a camera
/// looking along the base's x axis (camera z = base x, camera x = −base y, camera y = −base z
/// when the tilt is 0).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraMount {
    /// Optical centre in the base frame `\[x, y, z\]` \[m\].
    pub xyz_m: [f64; 3],
    /// Rotation of the optical axis below the base's x–y plane \[rad\].
    pub tilt_down_rad: f64,
}

impl Default for CameraMount {
    fn default() -> Self {
        Self {
            xyz_m: [0.05, 0.0, 0.2],
            tilt_down_rad: 0.0,
        }
    }
}

impl CameraMount {
    /// `base_from_camera`: maps points in the camera frame (x right, y down, z forward) into
    /// the robot base frame.
    pub fn base_from_camera(&self) -> Pose3 {
        let forward = Rotation3::from_matrix_unchecked(Matrix3::new(
            0.0, 0.0, 1.0, //
            -1.0, 0.0, 0.0, //
            0.0, -1.0, 0.0,
        ));
        let tilt = Rotation3::from_axis_angle(&Vector3::x_axis(), -self.tilt_down_rad);
        Isometry3::from_parts(
            Translation3::from(Vector3::from(self.xyz_m)),
            UnitQuaternion::from_rotation_matrix(&(forward * tilt)),
        )
    }
}

/// The simulated RGB-D camera: a Kinect v1 / Xtion as in the TUM RGB-D benchmark, depth
/// registered to colour (one set of intrinsics for both).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RgbdCameraConfig {
    /// Pinhole intrinsics and image size (no lens distortion is rendered).
    pub intrinsics: Intrinsics,
    /// Frames per second \[Hz\].
    pub rate_hz: f64,
    /// Pose of the camera on the robot.
    pub mount: CameraMount,
    /// No depth nearer than this \[m\].
    pub min_range_m: f64,
    /// No depth beyond this \[m\].
    pub max_range_m: f64,
    /// No depth where the ray meets the surface further than this from its normal \[rad\].
    pub max_incidence_rad: f64,
    /// Probability that a pixel has no depth although everything else allows it.
    pub dropout_probability: f64,
    /// Axial noise: constant term of Nguyen et al. \[m\].
    pub depth_sigma_base_m: f64,
    /// Axial noise: coefficient of `(z − depth_sigma_offset_m)²` \[1/m\].
    pub depth_sigma_quadratic_per_m: f64,
    /// Axial noise: depth at which the quadratic term vanishes \[m\].
    pub depth_sigma_offset_m: f64,
    /// Axial noise: coefficient of the angular term `θ²/(π/2 − θ)² / √z` \[m^1.5\].
    pub depth_sigma_angular: f64,
    /// Depth values are rounded to multiples of `1 / depth_units_per_metre` \[1/m\] (TUM: 5000).
    pub depth_units_per_metre: f64,
    /// Standard deviation of the colour noise, per channel \[8-bit levels\].
    pub color_noise_sigma: f64,
}

impl Default for RgbdCameraConfig {
    fn default() -> Self {
        Self {
            intrinsics: Intrinsics::from_array(TUM_FR1_INTRINSICS, 640, 480),
            rate_hz: 30.0,
            mount: CameraMount::default(),
            min_range_m: 0.5,
            max_range_m: 4.5,
            max_incidence_rad: 75f64.to_radians(),
            dropout_probability: 0.002,
            depth_sigma_base_m: 0.0012,
            depth_sigma_quadratic_per_m: 0.0019,
            depth_sigma_offset_m: 0.4,
            depth_sigma_angular: 0.0001,
            depth_units_per_metre: 5000.0,
            color_noise_sigma: 2.0,
        }
    }
}

impl RgbdCameraConfig {
    /// Fails on values no sensor can have.
    pub fn validate(&self) -> Result<(), SimError> {
        let ok = validate_intrinsics(&self.intrinsics)
            && self.rate_hz > 0.0
            && self.min_range_m >= 0.0
            && self.max_range_m > self.min_range_m
            && self.max_range_m * self.depth_units_per_metre < f64::from(u16::MAX)
            && self.max_incidence_rad > 0.0
            && self.max_incidence_rad <= std::f64::consts::FRAC_PI_2
            && (0.0..=1.0).contains(&self.dropout_probability)
            && [
                self.depth_sigma_base_m,
                self.depth_sigma_quadratic_per_m,
                self.depth_sigma_angular,
                self.color_noise_sigma,
            ]
            .iter()
            .all(|v| *v >= 0.0)
            && self.depth_sigma_offset_m.is_finite()
            && self.depth_units_per_metre > 0.0;
        if ok {
            Ok(())
        } else {
            Err(SimError::InvalidConfig(format!("rgbd camera: {self:?}")))
        }
    }

    /// Standard deviation of a depth reading at depth `z_m` seen at incidence `theta_rad`
    /// (Nguyen et al. 2012) \[m\].
    pub fn depth_sigma_m(&self, z_m: f64, theta_rad: f64) -> f64 {
        let grazing = theta_rad / (std::f64::consts::FRAC_PI_2 - theta_rad).max(1e-6);
        self.depth_sigma_base_m
            + self.depth_sigma_quadratic_per_m * (z_m - self.depth_sigma_offset_m).powi(2)
            + self.depth_sigma_angular / z_m.max(1e-6).sqrt() * grazing * grazing
    }

    /// One depth reading \[m\] of a ray (unit direction `ray_camera` in the camera frame,
    /// `ray_world` in the world) that met `hit`, or 0.0 for no depth.
    fn depth_reading(
        &self,
        hit: &Hit,
        ray_camera: &Vector3<f64>,
        ray_world: &Vector3<f64>,
        rng: &mut ChaCha8Rng,
    ) -> f32 {
        let z = hit.distance_m * ray_camera.z;
        let theta = (-hit.normal.dot(ray_world)).clamp(-1.0, 1.0).acos();
        let noise: f64 = rng.sample(StandardNormal);
        let dropped = rng.gen::<f64>() < self.dropout_probability;
        if dropped || hit.distance_m <= 0.0 || theta > self.max_incidence_rad {
            return 0.0;
        }
        let measured = z + self.depth_sigma_m(z, theta) * noise;
        let units = (measured * self.depth_units_per_metre).round();
        let quantised = units / self.depth_units_per_metre;
        if quantised < self.min_range_m || quantised > self.max_range_m {
            0.0
        } else {
            quantised as f32
        }
    }
}

/// True for intrinsics a renderer can use.
pub(crate) fn validate_intrinsics(k: &Intrinsics) -> bool {
    k.validate().is_ok() && k.width > 0 && k.height > 0
}

/// One frame of the RGB-D camera, with its ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdFrame {
    /// Frame number (selects the noise).
    pub index: usize,
    /// Time \[s\].
    pub timestamp: f64,
    /// Colour image (sRGB, 8 bit per channel).
    pub color: RgbImage,
    /// Depth registered to the colour image: z in the camera frame \[m\], 0.0 for no depth.
    pub depth_m: Image<f32>,
    /// True pose of the camera (x right, y down, z forward) in the world.
    pub world_from_camera: Pose3,
}

/// A camera placed in a scene: casts the ray of every pixel.
#[derive(Debug, Clone, Copy)]
pub struct View<'a> {
    /// What is seen.
    pub scene: &'a Scene,
    /// Where the camera is.
    pub world_from_camera: Pose3,
    /// Its pinhole intrinsics and image size.
    pub intrinsics: &'a Intrinsics,
    /// Rays stop here \[m\].
    pub max_range_m: f64,
}

/// What a pixel's ray met.
#[derive(Debug, Clone, Copy)]
pub struct PixelRay {
    /// The unit ray in the camera frame.
    pub camera: Vector3<f64>,
    /// The unit ray in the world frame.
    pub world: Vector3<f64>,
    /// The first surface within range, if any.
    pub hit: Option<Hit>,
}

/// Where an obstacle can appear in the image: the pixel columns and rows its bounding box
/// covers (with a one-pixel margin).
#[derive(Debug, Clone, Copy)]
struct ScreenBox {
    index: usize,
    u: [f64; 2],
    v: [f64; 2],
}

impl ScreenBox {
    fn covers_row(&self, v: f64) -> bool {
        self.v[0] <= v && v <= self.v[1]
    }

    fn covers_column(&self, u: f64) -> bool {
        self.u[0] <= u && u <= self.u[1]
    }
}

impl View<'_> {
    /// Renders every pixel, rows in parallel. `pixel` gets the pixel's ray and one random
    /// stream per entry of `noise`, each private to the row: stream `i` seeked to row
    /// `row_offset + v` of `noise[i]`.
    ///
    /// Obstacles whose bounding box projects outside a pixel's neighbourhood are not tested
    /// for that pixel (the image is the same as casting against every obstacle, only faster).
    pub fn render<T, const N: usize>(
        &self,
        noise: [&ChaCha8Rng; N],
        row_offset: usize,
        pixel: impl Fn(&PixelRay, &mut [ChaCha8Rng; N]) -> T + Sync,
    ) -> Image<T>
    where
        T: Clone + Default + Send,
    {
        let k = self.intrinsics;
        let origin = Point3::from(self.world_from_camera.translation.vector);
        let rotation = self.world_from_camera.rotation;
        let boxes = self.screen_boxes();
        let mut image = Image::filled(k.width, k.height, T::default());
        let rows = image.data_mut().par_chunks_mut(k.width.max(1));
        rows.enumerate().for_each(|(v, row)| {
            let mut rngs = noise.map(|base| {
                let mut rng = base.clone();
                rng.set_word_pos((row_offset + v) as u128 * ROW_WORDS);
                rng
            });
            let row_boxes: Vec<ScreenBox> = boxes
                .iter()
                .filter(|b| b.covers_row(v as f64))
                .copied()
                .collect();
            let y = (v as f64 - k.cy) / k.fy;
            for (u, out) in row.iter_mut().enumerate() {
                let camera = Vector3::new((u as f64 - k.cx) / k.fx, y, 1.0).normalize();
                let world = rotation * camera;
                let candidates = row_boxes
                    .iter()
                    .filter(|b| b.covers_column(u as f64))
                    .map(|b| b.index);
                let hit = self
                    .scene
                    .cast_among(&origin, &world, self.max_range_m, candidates);
                *out = pixel(&PixelRay { camera, world, hit }, &mut rngs);
            }
        });
        image
    }

    /// The image area of every obstacle that can be in view: the box around its projected
    /// bounding-box corners, or the whole image when the box reaches behind the camera.
    fn screen_boxes(&self) -> Vec<ScreenBox> {
        /// Corners nearer than this to the image plane's depth count as behind \[m\].
        const NEAR_M: f64 = 1e-3;
        let k = self.intrinsics;
        let camera_from_world = self.world_from_camera.inverse();
        let whole = [f64::NEG_INFINITY, f64::INFINITY];
        let mut boxes = Vec::new();
        for (index, (min, max)) in self.scene.obstacle_bounds().enumerate() {
            let corners = (0..8).map(|c| {
                let pick = |axis: usize| {
                    if c >> axis & 1 == 0 {
                        min[axis]
                    } else {
                        max[axis]
                    }
                };
                camera_from_world * Point3::new(pick(0), pick(1), pick(2))
            });
            let corners: Vec<Point3<f64>> = corners.collect();
            if corners.iter().all(|p| p.z <= 0.0) {
                continue;
            }
            let (u, v) = if corners.iter().any(|p| p.z <= NEAR_M) {
                (whole, whole)
            } else {
                let us = corners.iter().map(|p| k.fx * p.x / p.z + k.cx);
                let vs = corners.iter().map(|p| k.fy * p.y / p.z + k.cy);
                (span(us), span(vs))
            };
            let visible = u[1] >= 0.0
                && u[0] <= (k.width - 1) as f64
                && v[1] >= 0.0
                && v[0] <= (k.height - 1) as f64;
            if visible {
                boxes.push(ScreenBox { index, u, v });
            }
        }
        boxes
    }
}

/// `[min − 1, max + 1]` of the values.
fn span(values: impl Iterator<Item = f64>) -> [f64; 2] {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
        (lo.min(x), hi.max(x))
    });
    [lo - 1.0, hi + 1.0]
}

/// An 8-bit level with Gaussian noise: `value` in `\[0, 1\]` scaled to 0–255.
pub(crate) fn noisy_level(value: f32, sigma: f64, rng: &mut ChaCha8Rng) -> u8 {
    let noise: f64 = rng.sample(StandardNormal);
    // rounds: + 0.5, then the cast truncates the (non-negative) value
    (f64::from(value) * 255.0 + sigma * noise + 0.5).clamp(0.0, 255.0) as u8
}

/// Renders the RGB-D frame of a camera at `world_from_camera`: colour noise from `image_rng`,
/// depth noise and holes from `depth_rng` (each the frame's own stream).
pub fn render_rgbd(
    scene: &Scene,
    config: &RgbdCameraConfig,
    world_from_camera: Pose3,
    image_rng: &ChaCha8Rng,
    depth_rng: &ChaCha8Rng,
) -> (RgbImage, Image<f32>) {
    let view = View {
        scene,
        world_from_camera,
        intrinsics: &config.intrinsics,
        // beyond the depth range the colour camera still sees
        max_range_m: f64::INFINITY,
    };
    let pixels = view.render([image_rng, depth_rng], 0, |ray, [image, depth]| {
        let Some(hit) = ray.hit else {
            return ([0; 3], 0.0);
        };
        let color = scene
            .shade(&hit)
            .map(|c| noisy_level(c, config.color_noise_sigma, image));
        let z = config.depth_reading(&hit, &ray.camera, &ray.world, depth);
        (color, z)
    });
    (pixels.map(|p| p.0), pixels.map(|p| p.1))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::world::World;
    use nalgebra::Point2;
    use rand::SeedableRng;

    /// A 10 × 8 × 3 m room with a box whose face at x = 3.5 m faces the origin.
    pub(crate) fn scene() -> Scene {
        let text = "name = \"t\"\nsize_m = [10.0, 8.0]\nheight_m = 3.0\n\
             flight_path = [[1, 1, 1, 0], [2, 1, 1, 0]]\ndrive_path = [[1, 1], [2, 1]]\n\
             nav_goal = [2, 2]\n\
             [[boxes]]\ncenter = [4.0, 4.0]\nsize_m = [1.0, 6.0]\nz_m = [0.0, 3.0]\n";
        Scene::new(&World::from_toml(text, "t").unwrap())
    }

    /// A camera at `xyz` looking along world +x, tilted down by `tilt`.
    pub(crate) fn looking_along_x(xyz: [f64; 3], tilt: f64) -> Pose3 {
        CameraMount {
            xyz_m: xyz,
            tilt_down_rad: tilt,
        }
        .base_from_camera()
    }

    fn noiseless() -> RgbdCameraConfig {
        RgbdCameraConfig {
            dropout_probability: 0.0,
            depth_sigma_base_m: 0.0,
            depth_sigma_quadratic_per_m: 0.0,
            depth_sigma_angular: 0.0,
            color_noise_sigma: 0.0,
            ..RgbdCameraConfig::default()
        }
    }

    fn render(config: &RgbdCameraConfig, pose: Pose3, seed: u64) -> (RgbImage, Image<f32>) {
        let rng = |s| ChaCha8Rng::seed_from_u64(seed * 2 + s);
        render_rgbd(&scene(), config, pose, &rng(0), &rng(1))
    }

    #[test]
    fn mount_points_the_optical_axis_forward_and_down() {
        let level = looking_along_x([0.0; 3], 0.0);
        assert!((level * Vector3::z() - Vector3::x()).norm() < 1e-12);
        assert!((level * Vector3::x() + Vector3::y()).norm() < 1e-12);
        assert!((level * Vector3::y() + Vector3::z()).norm() < 1e-12);
        let tilted = looking_along_x([0.0; 3], 0.3) * Vector3::z();
        assert!((tilted - Vector3::new(0.3f64.cos(), 0.0, -0.3f64.sin())).norm() < 1e-12);
    }

    #[test]
    fn wall_at_known_distance_gives_that_depth() {
        let pose = looking_along_x([1.5, 4.0, 1.5], 0.0);
        let (color, depth) = render(&noiseless(), pose, 1);
        // every pixel sees the face at x = 3.5 m, 2 m ahead: depth exactly 2.0 (z, not range)
        assert!(depth.data().iter().all(|&z| z == 2.0));
        assert!(color.data().iter().any(|c| c != &[0, 0, 0]));
        // with noise: mean 2 m, spread near the model's σ at 2 m and normal incidence
        let config = RgbdCameraConfig::default();
        let (_, noisy) = render(&config, pose, 1);
        let valid: Vec<f64> = noisy
            .data()
            .iter()
            .filter(|&&z| z > 0.0)
            .map(|&z| f64::from(z))
            .collect();
        let n = valid.len() as f64;
        let mean = valid.iter().sum::<f64>() / n;
        let std = (valid.iter().map(|z| (z - mean).powi(2)).sum::<f64>() / n).sqrt();
        let sigma = config.depth_sigma_m(2.0, 0.0);
        assert!((mean - 2.0).abs() < 1e-3, "{mean}");
        // the corners see the face at up to 40° incidence, which adds a little
        assert!(std > sigma && std < 1.3 * sigma, "std {std}, model {sigma}");
        let holes = 640.0 * 480.0 - n;
        assert!(holes > 300.0 && holes < 1000.0, "{holes} holes"); // 0.2 % dropouts
                                                                   // quantised to 1/5000 m
        assert!(valid
            .iter()
            .all(|z| (z * 5000.0 - (z * 5000.0).round()).abs() < 1e-3));
    }

    #[test]
    fn back_projected_pixels_land_on_the_surface() {
        let config = noiseless();
        let pose = looking_along_x([1.5, 4.0, 1.2], 0.5);
        let (_, depth) = render(&config, pose, 2);
        let k = config.intrinsics;
        let (mut floor, mut face) = (0, 0);
        for v in (0..480).step_by(7) {
            for u in (0..640).step_by(11) {
                let z = f64::from(*depth.get(u, v).unwrap());
                if z == 0.0 {
                    continue;
                }
                let n = k.to_normalised(&Point2::new(u as f64, v as f64));
                let p = pose * Point3::new(n.x * z, n.y * z, z);
                // on the floor (z = 0) or on the box face (x = 3.5), to the quantisation step
                let tolerance = 2e-4 * (1.0 + n.coords.norm()) * 2.0;
                if p.z.abs() < tolerance {
                    floor += 1;
                } else {
                    assert!((p.x - 3.5).abs() < tolerance, "pixel {u},{v}: {p}");
                    face += 1;
                }
            }
        }
        assert!(floor > 500 && face > 500, "{floor} floor, {face} face");
    }

    #[test]
    fn no_depth_at_grazing_angles_and_beyond_range() {
        let config = noiseless();
        let pose = looking_along_x([1.5, 1.0, 1.0], 0.0);
        let (_, depth) = render(&config, pose, 3);
        let k = config.intrinsics;
        let row_below_horizon = |deg: f64| (k.cy + k.fy * deg.to_radians().tan()).round() as usize;
        // looking along y = 1 at the floor: 20° below the horizon the floor is 2.9 m away at
        // 70° incidence (valid), 14° below it is 4.1 m away at 76° (no depth)
        let u = k.cx.round() as usize;
        assert!(*depth.get(u, row_below_horizon(20.0)).unwrap() > 0.0);
        assert_eq!(*depth.get(u, row_below_horizon(14.0)).unwrap(), 0.0);
        // the room wall at x = 10 is 8.5 m away: beyond the 4.5 m range
        let look_past = looking_along_x([1.5, 7.5, 1.5], 0.0);
        let (color, far) = render(&config, look_past, 3);
        let centre = (k.cx.round() as usize, k.cy.round() as usize);
        assert_eq!(*far.get(centre.0, centre.1).unwrap(), 0.0);
        assert_ne!(*color.get(centre.0, centre.1).unwrap(), [0, 0, 0]);
    }

    #[test]
    fn same_seed_same_bytes_other_seed_other_noise() {
        let config = RgbdCameraConfig::default();
        let pose = looking_along_x([1.0, 3.0, 1.0], 0.2);
        let (a, b, c) = (
            render(&config, pose, 5),
            render(&config, pose, 5),
            render(&config, pose, 6),
        );
        assert!(a == b);
        assert!(a.0 != c.0 && a.1 != c.1);
    }

    #[test]
    fn culled_rendering_equals_casting_against_every_obstacle() {
        let scene = Scene::new(&World::builtin("office").unwrap());
        let k = Intrinsics::from_array(TUM_FR1_INTRINSICS, 64, 48);
        let k = Intrinsics {
            fx: k.fx / 10.0,
            fy: k.fy / 10.0,
            cx: 31.8,
            cy: 25.5,
            ..k
        };
        let rng = ChaCha8Rng::seed_from_u64(0);
        let poses = [
            looking_along_x([0.8, 3.85, 0.3], 0.0),
            looking_along_x([4.0, 3.0, 1.5], 0.6),
            looking_along_x([6.9, 1.2, 1.0], -0.4),
            Pose3::from_parts(
                Translation3::new(11.0, 1.3, 0.3),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 2.5)
                    * looking_along_x([0.0; 3], 0.1).rotation,
            ),
        ];
        for pose in poses {
            let view = View {
                scene: &scene,
                world_from_camera: pose,
                intrinsics: &k,
                max_range_m: 20.0,
            };
            let fast = view.render([&rng], 0, |ray, _| {
                ray.hit.map(|h| (h.distance_m, h.surface))
            });
            for v in 0..k.height {
                for u in 0..k.width {
                    let d = Vector3::new((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy, 1.0);
                    let world = pose.rotation * d.normalize();
                    let origin = Point3::from(pose.translation.vector);
                    let slow = scene
                        .cast(&origin, &world, 20.0)
                        .map(|h| (h.distance_m, h.surface));
                    assert_eq!(fast.get(u, v), Some(&slow), "pixel {u},{v} of {pose}");
                }
            }
        }
    }

    #[test]
    fn bad_configs_are_rejected() {
        assert!(RgbdCameraConfig::default().validate().is_ok());
        let bad = [
            RgbdCameraConfig {
                max_range_m: 0.1,
                ..Default::default()
            },
            RgbdCameraConfig {
                max_range_m: 20.0,
                ..Default::default()
            },
            RgbdCameraConfig {
                rate_hz: f64::NAN,
                ..Default::default()
            },
            RgbdCameraConfig {
                dropout_probability: 2.0,
                ..Default::default()
            },
            RgbdCameraConfig {
                intrinsics: Intrinsics::from_array([0.0, 1.0, 1.0, 1.0], 4, 4),
                ..Default::default()
            },
        ];
        for config in bad {
            assert!(config.validate().is_err(), "{config:?}");
        }
    }
}
