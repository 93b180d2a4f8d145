//! Pinhole cameras with Brown–Conrady lens distortion, in OpenCV's conventions.
//!
//! A point `(X, Y, Z)` in the camera frame (x right, y down, z forward) projects to normalised
//! coordinates `(x, y) = (X/Z, Y/Z)`, is distorted, then mapped to pixels by
//! `u = fx·x_d + cx`, `v = fy·y_d + cy`. Pixel centres lie at integer coordinates.
//!
//! The distortion is the Brown–Conrady model (D. C. Brown, "Decentering distortion of lenses",
//! Photogrammetric Engineering 32(3):444–462, 1966) with OpenCV's coefficient order
//! `k1 k2 p1 p2 k3`, as TUM RGB-D, EuRoC (radial-tangential) and ORB-SLAM calibrations give them:
//!
//! ```text
//! r² = x² + y²,  radial = 1 + k1 r² + k2 r⁴ + k3 r⁶
//! x_d = x·radial + 2 p1 x y + p2 (r² + 2x²)
//! y_d = y·radial + p1 (r² + 2y²) + 2 p2 x y
//! ```
//!
//! The model has no closed-form inverse; [`Distortion::undistort`] uses the fixed-point
//! iteration of OpenCV's `undistortPoints`, run until it converges.

use crate::GeometryError;
use nalgebra::{Matrix3, Point2, Point3, Vector2};
use serde::{Deserialize, Serialize};

/// Linear camera parameters and image size.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Intrinsics {
    /// Focal length along x \[px\].
    pub fx: f64,
    /// Focal length along y \[px\].
    pub fy: f64,
    /// Principal point x \[px\].
    pub cx: f64,
    /// Principal point y \[px\].
    pub cy: f64,
    /// Image width \[px\].
    pub width: usize,
    /// Image height \[px\].
    pub height: usize,
}

impl Intrinsics {
    /// Intrinsics from `[fx, fy, cx, cy]` \[px\] and the image size \[px\], the order in which
    /// calibration files list them.
    pub fn from_array(k: [f64; 4], width: usize, height: usize) -> Self {
        let [fx, fy, cx, cy] = k;
        Self {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
        }
    }

    /// The calibration matrix `K = [fx 0 cx; 0 fy cy; 0 0 1]`.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// Normalised image coordinates → pixel: `(fx x + cx, fy y + cy)`.
    pub fn to_pixel(&self, normalised: &Point2<f64>) -> Point2<f64> {
        Point2::new(
            self.fx * normalised.x + self.cx,
            self.fy * normalised.y + self.cy,
        )
    }

    /// Pixel → normalised image coordinates, the inverse of [`Self::to_pixel`].
    pub fn to_normalised(&self, pixel: &Point2<f64>) -> Point2<f64> {
        Point2::new((pixel.x - self.cx) / self.fx, (pixel.y - self.cy) / self.fy)
    }

    /// True when `pixel` falls on the image: within half a pixel of a pixel centre.
    pub fn contains(&self, pixel: &Point2<f64>) -> bool {
        (-0.5..self.width as f64 - 0.5).contains(&pixel.x)
            && (-0.5..self.height as f64 - 0.5).contains(&pixel.y)
    }

    /// Checks that focal lengths are positive and everything is finite, so that calibration
    /// files can be rejected when read rather than producing NaN pixels later.
    ///
    /// # Errors
    /// [`GeometryError::InvalidConfig`] naming the bad field.
    pub fn validate(&self) -> Result<(), GeometryError> {
        let invalid = |field, reason| Err(GeometryError::InvalidConfig { field, reason });
        if !(self.fx.is_finite() && self.fx > 0.0) {
            return invalid("fx", "must be positive and finite");
        }
        if !(self.fy.is_finite() && self.fy > 0.0) {
            return invalid("fy", "must be positive and finite");
        }
        if !(self.cx.is_finite() && self.cy.is_finite()) {
            return invalid("cx/cy", "must be finite");
        }
        if self.width == 0 || self.height == 0 {
            return invalid("width/height", "must be positive");
        }
        Ok(())
    }
}

/// Brown–Conrady distortion coefficients in OpenCV order; all zero means an ideal lens.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Distortion {
    /// Radial coefficient of r².
    pub k1: f64,
    /// Radial coefficient of r⁴.
    pub k2: f64,
    /// First tangential (decentering) coefficient.
    pub p1: f64,
    /// Second tangential (decentering) coefficient.
    pub p2: f64,
    /// Radial coefficient of r⁶.
    pub k3: f64,
}

/// Most fixed-point steps [`Distortion::undistort`] takes; OpenCV stops after 5, which is not
/// enough for sub-nanopixel round trips near image corners.
const MAX_UNDISTORT_ITERATIONS: usize = 100;

/// Undistortion has converged when a step moves the point by less than this, relative to its
/// distance from the optical axis (about 1e-11 px for a 500 px focal length).
const UNDISTORT_TOLERANCE: f64 = 1e-14;

impl Distortion {
    /// Builds from OpenCV's coefficient vector `[k1, k2, p1, p2, k3]`.
    pub fn from_opencv(d: [f64; 5]) -> Self {
        let [k1, k2, p1, p2, k3] = d;
        Self { k1, k2, p1, p2, k3 }
    }

    /// True when every coefficient is zero: distortion is then the identity.
    pub fn is_zero(&self) -> bool {
        *self == Self::default()
    }

    /// Radial factor and tangential offset at normalised point `p`.
    fn terms(&self, p: &Vector2<f64>) -> (f64, Vector2<f64>) {
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let tangential = Vector2::new(
            2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        );
        (radial, tangential)
    }

    /// Applies the lens distortion to an ideal normalised point (the module's equations).
    pub fn distort(&self, undistorted: &Point2<f64>) -> Point2<f64> {
        let (radial, tangential) = self.terms(&undistorted.coords);
        Point2::from(undistorted.coords * radial + tangential)
    }

    /// Removes the lens distortion from a normalised point: OpenCV's fixed-point iteration
    /// `x ← (x_d − tangential(x)) / radial(x)` from `x = x_d`.
    ///
    /// Returns `None` for non-finite input, or when the iteration diverges or does not settle:
    /// far outside the calibrated field of view the polynomial model may have no inverse.
    pub fn undistort(&self, distorted: &Point2<f64>) -> Option<Point2<f64>> {
        if !(distorted.x.is_finite() && distorted.y.is_finite()) {
            return None;
        }
        let mut p = distorted.coords;
        for _ in 0..MAX_UNDISTORT_ITERATIONS {
            let (radial, tangential) = self.terms(&p);
            let next = (distorted.coords - tangential) / radial;
            if !(next.x.is_finite() && next.y.is_finite()) {
                return None;
            }
            let step = (next - p).norm();
            p = next;
            if step <= UNDISTORT_TOLERANCE * (1.0 + p.norm()) {
                return Some(Point2::from(p));
            }
        }
        None
    }
}

/// A pinhole camera with lens distortion: everything needed to map between camera-frame
/// points and pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinholeCamera {
    /// Focal lengths, principal point and image size.
    pub intrinsics: Intrinsics,
    /// Lens distortion (zero by default).
    #[serde(default)]
    pub distortion: Distortion,
}

impl PinholeCamera {
    /// A camera with the given intrinsics and distortion.
    pub fn new(intrinsics: Intrinsics, distortion: Distortion) -> Self {
        Self {
            intrinsics,
            distortion,
        }
    }

    /// Projects a camera-frame point \[m\] to a pixel.
    ///
    /// Returns `None` when the point is not strictly in front of the camera (`Z ≤ 0`) or not
    /// finite. The pixel may lie outside the image; check with [`Intrinsics::contains`].
    pub fn project(&self, p_camera: &Point3<f64>) -> Option<Point2<f64>> {
        if !(p_camera.z > 0.0 && p_camera.x.is_finite() && p_camera.y.is_finite()) {
            return None;
        }
        let normalised = Point2::new(p_camera.x / p_camera.z, p_camera.y / p_camera.z);
        let pixel = self
            .intrinsics
            .to_pixel(&self.distortion.distort(&normalised));
        (pixel.x.is_finite() && pixel.y.is_finite()).then_some(pixel)
    }

    /// Back-projects a pixel with its depth \[m\] (the Z coordinate, as depth cameras report
    /// it, not the distance along the ray) to a camera-frame point.
    ///
    /// Returns `None` for a non-positive or non-finite depth, or when undistortion fails.
    pub fn unproject(&self, pixel: &Point2<f64>, depth_m: f64) -> Option<Point3<f64>> {
        if !(depth_m.is_finite() && depth_m > 0.0) {
            return None;
        }
        let distorted = self.intrinsics.to_normalised(pixel);
        let ray = self.distortion.undistort(&distorted)?;
        Some(Point3::new(ray.x * depth_m, ray.y * depth_m, depth_m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// TUM RGB-D freiburg1 colour camera, as calibrated in ORB-SLAM2 `Examples/RGB-D/TUM1.yaml`.
    fn tum_fr1() -> PinholeCamera {
        PinholeCamera::new(
            Intrinsics {
                fx: 517.306408,
                fy: 516.469215,
                cx: 318.643040,
                cy: 255.313989,
                width: 640,
                height: 480,
            },
            Distortion::from_opencv([0.262383, -0.953104, -0.005358, 0.002628, 1.163314]),
        )
    }

    #[test]
    fn from_array_reads_fx_fy_cx_cy_in_order() {
        let k = [517.306408, 516.469215, 318.643040, 255.313989];
        assert_eq!(Intrinsics::from_array(k, 640, 480), tum_fr1().intrinsics);
    }

    /// EuRoC MAV cam0 (radial-tangential model, k3 = 0), from the dataset's `sensor.yaml`.
    fn euroc_cam0() -> PinholeCamera {
        PinholeCamera::new(
            Intrinsics {
                fx: 458.654,
                fy: 457.296,
                cx: 367.215,
                cy: 248.375,
                width: 752,
                height: 480,
            },
            Distortion::from_opencv([-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05, 0.0]),
        )
    }

    /// Every 8th pixel of the image, corners included.
    fn pixel_grid(k: &Intrinsics) -> impl Iterator<Item = Point2<f64>> + '_ {
        let xs = (0..k.width).step_by(8).chain([k.width - 1]);
        xs.flat_map(move |u| {
            (0..k.height)
                .step_by(8)
                .chain([k.height - 1])
                .map(move |v| Point2::new(u as f64, v as f64))
        })
    }

    #[test]
    fn distortion_matches_hand_computed_values() {
        let d = Distortion::from_opencv([0.1, 0.01, 0.001, 0.002, 0.0001]);
        let p = d.distort(&Point2::new(0.3, -0.2));
        assert!(
            (p - Point2::new(0.30445076591, -0.20266384394)).norm() < 1e-14,
            "{p}"
        );
        assert_eq!(
            Distortion::default().distort(&Point2::new(0.3, -0.2)),
            Point2::new(0.3, -0.2)
        );
    }

    #[test]
    fn undistort_inverts_distort_over_the_image() {
        for cam in [tum_fr1(), euroc_cam0()] {
            let k = &cam.intrinsics;
            let mut worst_px: f64 = 0.0;
            for pixel in pixel_grid(k) {
                let ideal = cam.distortion.undistort(&k.to_normalised(&pixel)).unwrap();
                let back = k.to_pixel(&cam.distortion.distort(&ideal));
                worst_px = worst_px.max((back - pixel).norm());
            }
            assert!(worst_px < 1e-9, "{worst_px:e} px");
        }
    }

    #[test]
    fn distort_inverts_undistort_within_the_image() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for cam in [tum_fr1(), euroc_cam0()] {
            let k = &cam.intrinsics;
            let mut tested = 0;
            while tested < 1000 {
                let ideal = Point2::new(rng.gen_range(-0.8..0.8), rng.gen_range(-0.6..0.6));
                let distorted = cam.distortion.distort(&ideal);
                if !k.contains(&k.to_pixel(&distorted)) {
                    continue;
                }
                let back = cam.distortion.undistort(&distorted).unwrap();
                assert!((back - ideal).norm() < 1e-9, "{ideal} -> {back}");
                tested += 1;
            }
        }
    }

    #[test]
    fn unproject_inverts_project() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let cam = tum_fr1();
        for pixel in pixel_grid(&cam.intrinsics) {
            let depth = rng.gen_range(0.3..8.0);
            let p = cam.unproject(&pixel, depth).unwrap();
            assert!((p.z - depth).abs() < 1e-12);
            let back = cam.project(&p).unwrap();
            assert!((back - pixel).norm() < 1e-9, "{pixel} -> {back}");
        }
    }

    #[test]
    fn project_without_distortion_is_k_times_point() {
        let cam = PinholeCamera::new(euroc_cam0().intrinsics, Distortion::default());
        let p = Point3::new(0.5, -0.25, 2.0);
        let expected = cam.intrinsics.matrix() * p.coords;
        let pixel = cam.project(&p).unwrap();
        assert!((pixel.coords - expected.xy() / expected.z).norm() < 1e-12);
    }

    #[test]
    fn bad_points_do_not_project() {
        let cam = tum_fr1();
        assert_eq!(cam.project(&Point3::new(0.1, 0.1, 0.0)), None);
        assert_eq!(cam.project(&Point3::new(0.1, 0.1, -1.0)), None);
        assert_eq!(cam.project(&Point3::new(f64::NAN, 0.1, 1.0)), None);
        let centre = Point2::new(320.0, 240.0);
        for depth in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(cam.unproject(&centre, depth), None, "{depth}");
        }
        assert_eq!(cam.distortion.undistort(&Point2::new(f64::NAN, 0.0)), None);
    }

    #[test]
    fn intrinsics_are_validated_and_serialised() {
        let cam = tum_fr1();
        assert_eq!(cam.intrinsics.validate(), Ok(()));
        let bad = Intrinsics {
            fx: 0.0,
            ..cam.intrinsics
        };
        assert!(matches!(
            bad.validate(),
            Err(GeometryError::InvalidConfig { field: "fx", .. })
        ));
        let json = serde_json::to_string(&cam).unwrap();
        assert_eq!(serde_json::from_str::<PinholeCamera>(&json).unwrap(), cam);
        let no_lens = r#"{"intrinsics":{"fx":1,"fy":1,"cx":0,"cy":0,"width":2,"height":2}}"#;
        assert!(serde_json::from_str::<PinholeCamera>(no_lens)
            .unwrap()
            .distortion
            .is_zero());
        assert!(cam.intrinsics.contains(&Point2::new(-0.5, 479.4)));
        assert!(!cam.intrinsics.contains(&Point2::new(639.5, 0.0)));
    }
}
