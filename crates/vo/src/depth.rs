//! Depth for features of an RGB-D frame.
//!
//! A feature's depth is read at its nearest pixel of the depth image; it is rejected when the
//! pixel has no depth (0: hole, out of range) or when its 3×3 neighbourhood spans a depth edge
//! (foreground and background mixed: the corner then has no single 3D position — the
//! standard rejection of KinectFusion-era RGB-D odometry, e.g. Kerl, Sturm & Cremers, ICRA 2013).
//!
//! When colour and depth come from two unregistered cameras (Kinect v1 in 7-Scenes; see
//! `CAMERA_SOURCES.md` §7), [`register_depth`] first warps the depth image into the colour
//! camera: every depth pixel is lifted to 3D with the depth intrinsics, moved by
//! `color_from_depth` and projected with the colour intrinsics, keeping the nearest depth per
//! colour pixel (a z-buffer) and filling the one-pixel gaps the forward warp leaves.

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

/// Warps `depth_m` (seen by a camera with intrinsics `depth_k`) into the colour camera described
/// by `reg`; pixels that receive no depth are 0.
///
/// The hot loop avoids libm: a projection `u` is kept when `round(u)` lands in `0..w`, i.e.
/// when `−0.5 < u < w − 0.5`, and then `round(u)` is `⌊u + 0.5⌋`, a truncating conversion of a
/// positive number (no call to `round`, which the baseline x86-64 target cannot inline). The
/// per-column factors `fx' (x − cx)/fx` are computed once per image instead of once per pixel,
/// and one reciprocal of the depth serves both image coordinates.
pub fn register_depth(
    depth_m: &Image<f32>,
    depth_k: &Intrinsics,
    reg: &DepthRegistration,
) -> Image<f32> {
    let (w, h) = (depth_m.width(), depth_m.height());
    let color_k = reg.color_camera(w, h);
    let [tx, ty, tz] = reg.color_from_depth_m;
    // u = fx' (nx z + tx) / (z + tz) + cx' = (fx' nx · z + fx' tx) / (z + tz) + cx': the
    // factor fx' nx is per column, fy' ny per row, and one reciprocal serves both coordinates.
    let columns: Vec<f64> = (0..w)
        .map(|x| color_k.fx * (x as f64 - depth_k.cx) / depth_k.fx)
        .collect();
    let (fx_tx, fy_ty) = (color_k.fx * tx, color_k.fy * ty);
    let (u_end, v_end) = (w as f64 - 0.5, h as f64 - 0.5);
    let mut out = vec![f32::INFINITY; w * h];
    for (y, row) in depth_m.data().chunks_exact(w.max(1)).enumerate() {
        let fy_ny = color_k.fy * (y as f64 - depth_k.cy) / depth_k.fy;
        for (&d, &fx_nx) in row.iter().zip(&columns) {
            if !(d > 0.0 && d.is_finite()) {
                continue;
            }
            let z = f64::from(d);
            let pz = z + tz;
            if pz <= 0.0 {
                continue;
            }
            let inverse = pz.recip();
            let u = (fx_nx * z + fx_tx) * inverse + color_k.cx;
            let v = (fy_ny * z + fy_ty) * inverse + color_k.cy;
            if !(u > -0.5 && u < u_end && v > -0.5 && v < v_end) {
                continue;
            }
            let (col, line) = (((u + 0.5) as usize).min(w - 1), (v + 0.5) as usize);
            if let Some(o) = out.get_mut(line * w + col) {
                *o = o.min(pz as f32);
            }
        }
    }
    fill_gaps(&mut out, w);
    for v in &mut out {
        if !v.is_finite() {
            *v = 0.0;
        }
    }
    Image::from_vec(w, h, out).unwrap_or_else(|| Image::filled(w, h, 0.0))
}

/// Fills isolated empty pixels (a forward warp that magnifies leaves one-pixel cracks) with the
/// nearer of their left/right or up/down neighbours when those agree within 5 %. Decisions use
/// the unfilled values: the row above and the current row are read from copies taken before
/// they were filled (the row below is not filled yet), so no full copy of the image is needed.
fn fill_gaps(z: &mut [f32], w: usize) {
    if w < 3 || z.len() < 3 * w {
        return;
    }
    let h = z.len() / w;
    let (mut above, mut here) = (z[..w].to_vec(), vec![0f32; w]);
    for y in 1..h - 1 {
        here.copy_from_slice(&z[y * w..(y + 1) * w]);
        let (row, below) = z[y * w..].split_at_mut(w);
        for x in 1..w - 1 {
            if here[x].is_finite() {
                continue;
            }
            for (a, b) in [(here[x - 1], here[x + 1]), (above[x], below[x])] {
                if a.is_finite() && b.is_finite() && (a - b).abs() <= 0.05 * a.min(b) {
                    row[x] = a.min(b);
                    break;
                }
            }
        }
        std::mem::swap(&mut above, &mut here);
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
    let centre = f64::from(*depth_m.get(x, y)?);
    if !(centre >= config.min_depth_m && centre <= config.max_depth_m) {
        return None;
    }
    let (mut lo, mut hi) = (centre, centre);
    for yy in y - 1..=y + 1 {
        for xx in x - 1..=x + 1 {
            let d = f64::from(*depth_m.get(xx, yy)?);
            if d <= 0.0 {
                continue;
            }
            lo = lo.min(d);
            hi = hi.max(d);
        }
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
    fn registration_moves_a_plane_by_the_baseline() {
        let depth = Image::filled(40, 30, 2.0f32);
        let reg = DepthRegistration {
            color_intrinsics: [100.0, 100.0, 20.0, 15.0],
            color_from_depth_m: [-0.2, 0.0, 0.0],
        };
        let out = register_depth(&depth, &k(), &reg);
        // a shift of −0.2 m at 2 m is −10 px: the right 10 columns receive nothing
        assert_eq!(*out.get(35, 10).unwrap(), 0.0);
        assert_eq!(*out.get(10, 10).unwrap(), 2.0);
        let all_zero = register_depth(&Image::filled(40, 30, 0.0f32), &k(), &reg);
        assert!(all_zero.data().iter().all(|&v| v == 0.0));
    }

    /// The textbook forward warp, pixel by pixel with `f64::round`, before gap filling.
    fn warp_reference(depth: &Image<f32>, dk: &Intrinsics, reg: &DepthRegistration) -> Vec<f32> {
        let (w, h) = (depth.width(), depth.height());
        let ck = reg.color_camera(w, h);
        let t = nalgebra::Vector3::from(reg.color_from_depth_m);
        let mut out = vec![f32::INFINITY; w * h];
        for y in 0..h {
            for x in 0..w {
                let z = f64::from(*depth.get(x, y).unwrap());
                if z <= 0.0 {
                    continue;
                }
                let p = nalgebra::Vector3::new(
                    (x as f64 - dk.cx) / dk.fx * z,
                    (y as f64 - dk.cy) / dk.fy * z,
                    z,
                ) + t;
                let u = (ck.fx * p.x / p.z + ck.cx).round();
                let v = (ck.fy * p.y / p.z + ck.cy).round();
                if u >= 0.0 && v >= 0.0 && u < w as f64 && v < h as f64 {
                    let o = &mut out[v as usize * w + u as usize];
                    *o = o.min(p.z as f32);
                }
            }
        }
        out
    }

    #[test]
    fn registration_matches_the_per_pixel_formula() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let data = (0..40 * 30)
            .map(|_| {
                if rng.gen_bool(0.1) {
                    0.0
                } else {
                    rng.gen_range(0.4f32..5.0)
                }
            })
            .collect();
        let depth = Image::from_vec(40, 30, data).unwrap();
        let reg = DepthRegistration {
            color_intrinsics: [97.3, 101.1, 19.7, 15.2],
            color_from_depth_m: [-0.025, 0.01, 0.003],
        };
        let mut want = warp_reference(&depth, &k(), &reg);
        fill_gaps(&mut want, 40);
        let got = register_depth(&depth, &k(), &reg);
        for (g, w) in got.data().iter().zip(&want) {
            assert_eq!(*g, if w.is_finite() { *w } else { 0.0 });
        }
    }

    #[test]
    fn gap_filling_decides_on_the_unfilled_image() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let (w, h) = (23, 17);
        let z: Vec<f32> = (0..w * h)
            .map(|_| {
                if rng.gen_bool(0.3) {
                    f32::INFINITY
                } else {
                    rng.gen_range(1.0f32..1.1)
                }
            })
            .collect();
        // reference: every decision on a copy of the input
        let mut want = z.clone();
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let i = y * w + x;
                if z[i].is_finite() {
                    continue;
                }
                for (a, b) in [(z[i - 1], z[i + 1]), (z[i - w], z[i + w])] {
                    if a.is_finite() && b.is_finite() && (a - b).abs() <= 0.05 * a.min(b) {
                        want[i] = a.min(b);
                        break;
                    }
                }
            }
        }
        let mut got = z.clone();
        fill_gaps(&mut got, w);
        assert_eq!(got, want);
        assert_ne!(got, z);
        fill_gaps(&mut [], w);
    }

    #[test]
    fn lift_inverts_projection() {
        let p = lift(&k(), Point2::new(30.0, 5.0), 2.0);
        assert!((p - Point3::new(0.2, -0.2, 2.0)).norm() < 1e-12);
    }
}
