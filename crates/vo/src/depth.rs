//! Depth for features of an RGB-D frame.
//!
//! A feature's depth is read at its nearest pixel of the depth image; it is rejected when the
//! pixel has no depth (0: hole, out of range) or when its 3×3 neighbourhood spans a depth edge
//! (foreground and background mixed: the corner then has no single 3D position — the
//! standard rejection of KinectFusion-era RGB-D odometry, e.g. Kerl, Sturm & Cremers, ICRA 2013).
//!
//! When colour and depth come from two unregistered cameras (Kinect v1 in 7-Scenes; see
//! `CAMERA_SOURCES.md` §7), the depth is read in the colour camera through
//! [`crate::registration`], which warps only the depth pixels that can land near each feature.

use nalgebra::{Point2, Point3};
use serde::{Deserialize, Serialize};
use slamkit_core::camera::Intrinsics;
use slamkit_core::image::Image;
use slamkit_core::Pose3;

/// Depth-lookup settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DepthConfig {
    /// Nearest usable depth \[m\].
    pub min_depth_m: f64,
    /// Farthest usable depth \[m\] (RGB-D depth noise grows with the square of depth).
    pub max_depth_m: f64,
    /// Largest depth spread in a feature's 3×3 neighbourhood, as a fraction of its depth.
    pub max_edge_ratio: f64,
    /// Virtual stereo baseline of the depth sensor \[m\]: motion refinement treats depth z as
    /// a disparity `fx · baseline / z` (Kinect v1: 7.5 cm between projector and IR camera);
    /// 0 uses pixels only.
    pub virtual_baseline_m: f64,
}

impl Default for DepthConfig {
    fn default() -> Self {
        Self {
            min_depth_m: 0.3,
            max_depth_m: 6.0,
            max_edge_ratio: 0.05,
            virtual_baseline_m: 0.075,
        }
    }
}

/// How the depth camera sits relative to the colour camera of an unregistered RGB-D sensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DepthRegistration {
    /// Colour camera focal lengths and principal point `[fx, fy, cx, cy]` \[px\].
    pub color_intrinsics: [f64; 4],
    /// Translation of `color_from_depth` \[m\] (the cameras are taken to be parallel).
    pub color_from_depth_m: [f64; 3],
}

impl Default for DepthRegistration {
    /// A Kinect v1: colour f = 525 px at the image centre, the colour camera 2.5 cm beside the
    /// depth (IR) camera (`CAMERA_SOURCES.md` §7 measured f ≈ 525–540 px for 7-Scenes).
    fn default() -> Self {
        Self {
            color_intrinsics: [525.0, 525.0, 319.5, 239.5],
            color_from_depth_m: [-0.025, 0.0, 0.0],
        }
    }
}

impl DepthRegistration {
    /// `color_from_depth` as a pose.
    pub fn color_from_depth(&self) -> Pose3 {
        let [x, y, z] = self.color_from_depth_m;
        Pose3::translation(x, y, z)
    }

    /// The colour camera intrinsics, with the size of the depth image.
    pub fn color_camera(&self, width: usize, height: usize) -> Intrinsics {
        Intrinsics::from_array(self.color_intrinsics, width, height)
    }
}

/// Depth \[m\] of the feature at `px`, or `None` (hole, out of range, depth edge).
pub fn depth_at(depth_m: &Image<f32>, px: Point2<f64>, config: &DepthConfig) -> Option<f64> {
    if !(px.x.is_finite() && px.y.is_finite()) {
        return None;
    }
    let (x, y) = (px.x.round(), px.y.round());
    if x < 1.0 || y < 1.0 || x >= depth_m.width() as f64 - 1.0 || y >= depth_m.height() as f64 - 1.0
    {
        return None;
    }
    let (x, y) = (x as usize, y as usize);
    let mut patch = [[0f32; 3]; 3];
    for (line, yy) in patch.iter_mut().zip(y - 1..) {
        line.copy_from_slice(depth_m.row(yy)?.get(x - 1..=x + 1)?);
    }
    depth_of_patch(&patch, config)
}

/// Depth \[m\] at the centre of a feature's 3×3 depth neighbourhood (0: no depth), or `None`
/// when the centre has none, is out of range, or the neighbourhood spans a depth edge.
pub(crate) fn depth_of_patch(patch: &[[f32; 3]; 3], config: &DepthConfig) -> Option<f64> {
    let centre = f64::from(patch[1][1]);
    if !(centre >= config.min_depth_m && centre <= config.max_depth_m) {
        return None;
    }
    let (mut lo, mut hi) = (centre, centre);
    for &d in patch.iter().flatten() {
        let d = f64::from(d);
        if d <= 0.0 {
            continue;
        }
        lo = lo.min(d);
        hi = hi.max(d);
    }
    (hi - lo <= config.max_edge_ratio * centre).then_some(centre)
}

/// The camera-frame point of the feature at `px` with depth `z` \[m\] (undistorted pinhole).
pub fn lift(k: &Intrinsics, px: Point2<f64>, z: f64) -> Point3<f64> {
    Point3::new((px.x - k.cx) / k.fx * z, (px.y - k.cy) / k.fy * z, z)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k() -> Intrinsics {
        Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: 20.0,
            cy: 15.0,
            width: 40,
            height: 30,
        }
    }

    #[test]
    fn holes_edges_and_range_are_rejected() {
        let mut img = Image::filled(40, 30, 2.0f32);
        let c = DepthConfig::default();
        assert_eq!(depth_at(&img, Point2::new(10.2, 10.4), &c), Some(2.0));
        *img.get_mut(10, 10).unwrap() = 0.0;
        assert_eq!(depth_at(&img, Point2::new(10.0, 10.0), &c), None);
        *img.get_mut(21, 20).unwrap() = 3.0;
        assert_eq!(depth_at(&img, Point2::new(20.0, 20.0), &c), None);
        assert_eq!(depth_at(&img, Point2::new(0.0, 5.0), &c), None);
        assert_eq!(depth_at(&img, Point2::new(f64::NAN, 5.0), &c), None);
        let far = Image::filled(40, 30, 9.0f32);
        assert_eq!(depth_at(&far, Point2::new(10.0, 10.0), &c), None);
    }

    #[test]
    fn lift_inverts_projection() {
        let p = lift(&k(), Point2::new(30.0, 5.0), 2.0);
        assert!((p - Point3::new(0.2, -0.2, 2.0)).norm() < 1e-12);
    }
}
