//! Simulated rectified stereo pair: two identical pinhole cameras side by side, the right one
//! `baseline_m` along the left camera's x axis, rendered by the same ray caster as the RGB-D
//! camera ([`crate::camera::View`]), as 8-bit grey images.
//!
//! Being rectified by construction, the pair is what KITTI's odometry benchmark stores (Geiger
//! et al., CVPR 2012): both cameras share K and `P1 = K [I | (−b, 0, 0)ᵀ]`, so a point at depth
//! z appears `fx·b / z` pixels further left in the right image. Grey is the Rec. 601 luma of the
//! shaded colour plus Gaussian noise.

use crate::camera::{noisy_level, validate_intrinsics, CameraMount, View, TUM_FR1_INTRINSICS};
use crate::scene::Scene;
use crate::SimError;
use nalgebra::Translation3;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use slamkit_core::camera::Intrinsics;
use slamkit_core::image::GrayImage;
use slamkit_core::Pose3;

/// The simulated stereo camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StereoCameraConfig {
    /// Intrinsics and image size of both (rectified) cameras.
    pub intrinsics: Intrinsics,
    /// Distance between the optical centres, right camera along the left's +x \[m\].
    pub baseline_m: f64,
    /// Frame pairs per second \[Hz\] (KITTI: 10).
    pub rate_hz: f64,
    /// Pose of the left camera on the robot.
    pub mount: CameraMount,
    /// Standard deviation of the pixel noise \[8-bit levels\].
    pub noise_sigma: f64,
}

impl Default for StereoCameraConfig {
    fn default() -> Self {
        Self {
            intrinsics: Intrinsics::from_array(TUM_FR1_INTRINSICS, 640, 480),
            baseline_m: 0.12,
            rate_hz: 10.0,
            mount: CameraMount::default(),
            noise_sigma: 2.0,
        }
    }
}

impl StereoCameraConfig {
    /// Fails on values no sensor can have.
    pub fn validate(&self) -> Result<(), SimError> {
        let ok = validate_intrinsics(&self.intrinsics)
            && self.baseline_m > 0.0
            && self.baseline_m.is_finite()
            && self.rate_hz > 0.0
            && self.noise_sigma >= 0.0;
        if ok {
            Ok(())
        } else {
            Err(SimError::InvalidConfig(format!("stereo camera: {self:?}")))
        }
    }

    /// `right_from_left`: maps points from the left camera frame into the right one.
    pub fn right_from_left(&self) -> Pose3 {
        Pose3::from_parts(
            Translation3::new(-self.baseline_m, 0.0, 0.0),
            Default::default(),
        )
    }
}

/// One frame of the stereo pair, with its ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoFrame {
    /// Frame number (selects the noise).
    pub index: usize,
    /// Time \[s\].
    pub timestamp: f64,
    /// Left image.
    pub left: GrayImage,
    /// Right image.
    pub right: GrayImage,
    /// True pose of the left camera (x right, y down, z forward) in the world.
    pub world_from_left: Pose3,
}

/// Renders the left and right images of a pair whose left camera is at `world_from_left`; the
/// noise comes from `rng` (the frame's stream; the right image uses the rows after the left's).
pub fn render_stereo(
    scene: &Scene,
    config: &StereoCameraConfig,
    world_from_left: Pose3,
    rng: &ChaCha8Rng,
) -> (GrayImage, GrayImage) {
    let world_from_right = world_from_left * config.right_from_left().inverse();
    let grey = |world_from_camera: Pose3, row_offset: usize| {
        let view = View {
            scene,
            world_from_camera,
            intrinsics: &config.intrinsics,
            max_range_m: f64::INFINITY,
        };
        view.render([rng], row_offset, |ray, [noise]| {
            let [r, g, b] = ray.hit.map_or([0.0; 3], |h| scene.shade(&h));
            let luma = 0.299 * r + 0.587 * g + 0.114 * b;
            noisy_level(luma, config.noise_sigma, noise)
        })
    };
    (
        grey(world_from_left, 0),
        grey(world_from_right, config.intrinsics.height),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::tests::{looking_along_x, scene};
    use rand::SeedableRng;

    fn noiseless() -> StereoCameraConfig {
        StereoCameraConfig {
            noise_sigma: 0.0,
            ..StereoCameraConfig::default()
        }
    }

    /// Shift (in pixels) that best maps the left row onto the right one: `right(u − d) = left(u)`.
    fn disparity(left: &GrayImage, right: &GrayImage, v: usize) -> usize {
        let (l, r) = (left.row(v).unwrap(), right.row(v).unwrap());
        let sad =
            |d: usize| -> u32 { (200..440).map(|u| u32::from(l[u].abs_diff(r[u - d]))).sum() };
        (0..100).min_by_key(|&d| sad(d)).unwrap()
    }

    #[test]
    fn disparity_is_focal_length_times_baseline_over_depth() {
        let config = noiseless();
        let scene = scene();
        let rng = ChaCha8Rng::seed_from_u64(0);
        // the box face is 2 m ahead: disparity 517.3 · 0.12 / 2 = 31.0 px
        let pose = looking_along_x([1.5, 4.0, 1.5], 0.0);
        let (left, right) = render_stereo(&scene, &config, pose, &rng);
        let expected = config.intrinsics.fx * config.baseline_m / 2.0;
        for v in [100, 240, 400] {
            let d = disparity(&left, &right, v) as f64;
            assert!(
                (d - expected).abs() <= 1.0,
                "row {v}: {d} px, expected {expected}"
            );
        }
        // the right image is the left camera moved along +x: same as rendering the left there
        let moved = pose * config.right_from_left().inverse();
        let (right_as_left, _) = render_stereo(&scene, &config, moved, &rng);
        assert!(right == right_as_left);
    }

    #[test]
    fn same_seed_same_bytes_and_bad_configs_rejected() {
        let (config, scene) = (StereoCameraConfig::default(), scene());
        let pose = looking_along_x([1.0, 3.0, 1.0], 0.1);
        let rng = |s| ChaCha8Rng::seed_from_u64(s);
        let a = render_stereo(&scene, &config, pose, &rng(1));
        assert!(a == render_stereo(&scene, &config, pose, &rng(1)));
        assert!(a.0 != render_stereo(&scene, &config, pose, &rng(2)).0);
        assert!(a.0 != a.1);
        for bad in [0.0, -0.1, f64::INFINITY] {
            let c = StereoCameraConfig {
                baseline_m: bad,
                ..StereoCameraConfig::default()
            };
            assert!(c.validate().is_err());
        }
    }
}
