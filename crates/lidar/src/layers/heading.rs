//! Heading from the yaw-rate gyro and the scans together: a Kalman filter on the heading error
//! and the gyro's bias.
//!
//! The drone's IMU integrates its z gyro into a heading whose change between two scans is far
//! better than a weakly pinned scan match's, but whose bias (0.05 °/s left by the take-off
//! calibration of a BMI088, wandering by 0.004 °/s/√s) turns the whole map by 0.05 rad in a
//! minute when nothing corrects it. Taken as the heading prediction and overwritten by every
//! match, the gyro lost both ways in the `office` flight: a scan of one wall and a pillar
//! pinned a mixture of the position along the flight and the heading, and its corrections,
//! all of one sign while the velocity prior lagged, turned the heading 0.045 rad in 14 s; and a
//! pillar's arc, which pins the position across the line of sight once the heading is known,
//! was dropped as too weak because with the heading free it only pins a turn about itself.
//!
//! So the heading is estimated as an error-state Kalman filter over `(δθ, b)` — heading error
//! and gyro bias — (J. Solà, "Quaternion kinematics for the error-state Kalman filter", 2017,
//! sec. 5.3.3 and 6, reduced to yaw): the gyro drives the prediction (its angle random walk
//! and bias random walk are the process noise), and each accepted match measures the heading
//! with the information the scan has on it *with the translation free*, the Schur complement
//! `S = H_θθ − H_θt H_tt⁻¹ H_tθ` of its point-to-line information matrix `H`: a wall seen
//! across the view pins it, a pillar (whose arc only pins a turn about itself together with
//! a shift) does not. The filter's correction is kept; the translation is then the scan's best
//! one at that heading (the minimum of the match's quadratic with the heading held), kept
//! along the directions the scan pins ([`super::degeneracy`]). A heading held by the gyro
//! turns a pillar's arc into a position fix, and the bias, observed whenever walls pin the
//! heading, keeps the gyro from turning the maps in between.

use super::kalman::scalar_update;
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// Noise of the gyro and of the scans' heading, for [`HeadingFilter`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeadingFilterConfig {
    /// White rate noise density of the gyro (angle random walk) \[rad/s/√Hz\].
    pub gyro_noise_density_radps_per_sqrt_hz: f64,
    /// Standard deviation of the gyro's bias at the first scan \[rad/s\].
    pub gyro_bias_sigma_radps: f64,
    /// Density of the gyro bias's random walk \[rad/s/√s\].
    pub gyro_bias_walk_radps_per_sqrt_s: f64,
    /// Standard deviation of a point-to-line residual, which turns the scan's information
    /// matrix (about one unit per point pinning a direction) into an inverse variance \[m\]:
    /// ICP's kernel scale rather than the range noise, as the map a scan is matched to
    /// carries the errors of the poses it was built at.
    pub scan_sigma_m: f64,
    /// A match whose heading is further from the prediction than this many standard
    /// deviations (of the prediction and the scan's heading together) is a false match.
    pub max_innovation_sigma: f64,
}

impl Default for HeadingFilterConfig {
    /// The BMI088 (Crazyflie 2.1 IMU) datasheet's gyro: noise density 0.014 °/s/√Hz; the bias
    /// a take-off calibration leaves, 0.05 °/s; its drift while the motors warm it, 0.004
    /// °/s/√s.
    fn default() -> Self {
        Self {
            gyro_noise_density_radps_per_sqrt_hz: 0.014f64.to_radians(),
            gyro_bias_sigma_radps: 0.05f64.to_radians(),
            gyro_bias_walk_radps_per_sqrt_s: 0.004f64.to_radians(),
            scan_sigma_m: 0.05,
            max_innovation_sigma: 3.0,
        }
    }
}

impl HeadingFilterConfig {
    /// `(field, value, valid)` for every field: all finite and non-negative, the scan sigma
    /// positive.
    pub fn field_checks(&self) -> [(&'static str, f64, bool); 5] {
        let non_negative = |field, value: f64| (field, value, value >= 0.0);
        [
            non_negative(
                "heading.gyro_noise_density_radps_per_sqrt_hz",
                self.gyro_noise_density_radps_per_sqrt_hz,
            ),
            non_negative("heading.gyro_bias_sigma_radps", self.gyro_bias_sigma_radps),
            non_negative(
                "heading.gyro_bias_walk_radps_per_sqrt_s",
                self.gyro_bias_walk_radps_per_sqrt_s,
            ),
            (
                "heading.scan_sigma_m",
                self.scan_sigma_m,
                self.scan_sigma_m > 0.0,
            ),
            (
                "heading.max_innovation_sigma",
                self.max_innovation_sigma,
                self.max_innovation_sigma > 0.0,
            ),
        ]
    }
}

/// Kalman filter over the heading error and the gyro bias.
#[derive(Debug, Clone)]
pub struct HeadingFilter {
    config: HeadingFilterConfig,
    /// Estimated gyro bias \[rad/s\].
    bias_radps: f64,
    /// Covariance of `(δθ, b)`.
    covariance: Matrix2<f64>,
}

/// A filter update worked out for one match, applied with [`HeadingFilter::apply`] only if the
/// match is the one kept.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingUpdate {
    /// Correction of the predicted heading \[rad\].
    pub heading_rad: f64,
    bias_radps: f64,
    covariance: Matrix2<f64>,
}

impl HeadingFilter {
    /// A filter whose heading is exact (the world frame is the first scan's) and whose bias is
    /// zero with the configured uncertainty.
    pub fn new(config: HeadingFilterConfig) -> Self {
        let b = config.gyro_bias_sigma_radps;
        Self {
            covariance: Matrix2::new(0.0, 0.0, 0.0, b * b),
            bias_radps: 0.0,
            config,
        }
    }

    /// The gyro's heading change `gyro_turn_rad` over `dt_s` with the bias taken out; the
    /// heading error's uncertainty grows by the gyro's noise and the bias's.
    pub fn predict(&mut self, gyro_turn_rad: f64, dt_s: f64) -> f64 {
        let dt = dt_s.max(0.0);
        let c = &self.config;
        let f = Matrix2::new(1.0, -dt, 0.0, 1.0);
        let q = Matrix2::new(
            c.gyro_noise_density_radps_per_sqrt_hz.powi(2) * dt,
            0.0,
            0.0,
            c.gyro_bias_walk_radps_per_sqrt_s.powi(2) * dt,
        );
        self.covariance = f * self.covariance * f.transpose() + q;
        gyro_turn_rad - self.bias_radps * dt
    }

    /// The update for a scan match that corrects the predicted heading by `innovation_rad`,
    /// with the scan's point-to-line `information` (body frame, translation first); `None`
    /// when the correction is further from the prediction than `max_innovation_sigma`
    /// standard deviations of the two together allow (a false match: a scan that slid to a
    /// turn the walls it sees do not allow).
    pub fn update(&self, innovation_rad: f64, information: &Matrix3<f64>) -> Option<HeadingUpdate> {
        let sigma2 = self.config.scan_sigma_m.powi(2);
        let pinned = heading_information(information) / sigma2;
        let p = self.covariance;
        if !innovation_rad.is_finite() {
            return None;
        }
        if pinned <= 0.0 {
            return Some(HeadingUpdate {
                heading_rad: 0.0,
                bias_radps: self.bias_radps,
                covariance: p,
            });
        }
        // measurement of δθ with variance 1 / pinned
        let (correction, covariance) = scalar_update(
            &p,
            &Vector2::new(1.0, 0.0),
            innovation_rad,
            1.0 / pinned,
            self.config.max_innovation_sigma,
        )?;
        Some(HeadingUpdate {
            heading_rad: correction.x,
            bias_radps: self.bias_radps + correction.y,
            covariance,
        })
    }

    /// Takes the update of the match that was kept: the heading error is reset to zero (the
    /// pose carries the correction), the bias and the covariance are the update's.
    pub fn apply(&mut self, update: &HeadingUpdate) {
        self.bias_radps = update.bias_radps;
        self.covariance = update.covariance;
    }

    /// Estimated gyro bias \[rad/s\].
    pub fn bias_radps(&self) -> f64 {
        self.bias_radps
    }
}

/// The scan's information on the heading with the translation free: the Schur complement of
/// the translation block of `information` (clamped at zero).
pub fn heading_information(information: &Matrix3<f64>) -> f64 {
    let coupling = translation_coupling(information).map_or(0.0, |(inverse, t_theta)| {
        (t_theta.transpose() * inverse * t_theta).x
    });
    (information[(2, 2)] - coupling).max(0.0)
}

/// The translation part of the twist `raw` (a match's correction of the prediction, body
/// frame) moved to the scan's best translation when the heading correction is `heading_rad`
/// instead of `raw.z`: the minimum of `(ε − raw)ᵀ H (ε − raw)` over the translation with the
/// heading held.
pub fn translation_at_heading(
    raw: &Vector3<f64>,
    information: &Matrix3<f64>,
    heading_rad: f64,
) -> Vector2<f64> {
    let shift = translation_coupling(information).map_or(Vector2::zeros(), |(inverse, t_theta)| {
        inverse * t_theta * (raw.z - heading_rad)
    });
    raw.xy() + shift
}

/// The inverse of the translation block of `information` (regularised, so that a direction no
/// point pins inverts to a large number rather than failing) and the block coupling the
/// translation to the heading.
fn translation_coupling(information: &Matrix3<f64>) -> Option<(Matrix2<f64>, Vector2<f64>)> {
    let tt = information.fixed_view::<2, 2>(0, 0).into_owned() + Matrix2::identity() * 1e-9;
    let t_theta = information.fixed_view::<2, 1>(0, 2).into_owned();
    tt.try_inverse().map(|inverse| (inverse, t_theta))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layers::degeneracy::scan_information;
    use nalgebra::Point2;

    /// An arc of a pillar of radius 0.2 m centred 2 m ahead, as a scan sees it.
    fn pillar() -> (Vec<Point2<f64>>, Vec<Option<Vector2<f64>>>) {
        (-8..=8)
            .map(|i| {
                let a = std::f64::consts::PI + 0.15 * f64::from(i);
                let n = Vector2::new(a.cos(), a.sin());
                (Point2::new(2.0 + 0.2 * n.x, 0.2 * n.y), Some(n))
            })
            .unzip()
    }

    #[test]
    fn a_pillar_pins_no_heading_a_wall_across_the_view_does() {
        let (points, normals) = pillar();
        let h = scan_information(&points, &normals);
        assert!(heading_information(&h) < 1e-6 * h[(2, 2)], "{h}");
        // a wall 1 m ahead from y = -1 to 1: a turn moves its ends
        let wall: Vec<Point2<f64>> = (0..41)
            .map(|i| Point2::new(1.0, -1.0 + 0.05 * f64::from(i)))
            .collect();
        let h = scan_information(&wall, &vec![Some(Vector2::new(-1.0, 0.0)); wall.len()]);
        assert!(heading_information(&h) > 10.0, "{h}");
    }

    #[test]
    fn holding_the_heading_turns_a_slide_about_a_pillar_into_a_shift_across_it() {
        let (points, normals) = pillar();
        let h = scan_information(&points, &normals);
        // a turn by 0.1 rad about the pillar's centre, seen from the drone: the free direction
        let slide = Vector3::new(0.0, -2.0 * 0.1, 0.1);
        assert!((h * slide).norm() < 1e-6 * h.norm(), "{}", h * slide);
        // on top of it, the drone 0.05 m to the left of where the prediction put it
        let raw = slide + Vector3::new(0.0, 0.05, 0.0);
        let t = translation_at_heading(&raw, &h, 0.0);
        assert!((t - Vector2::new(0.0, 0.05)).norm() < 1e-6, "{t}");
    }

    #[test]
    fn walls_that_keep_turning_the_gyro_heading_back_reveal_its_bias() {
        let config = HeadingFilterConfig::default();
        let mut filter = HeadingFilter::new(config.clone());
        let bias = 0.001; // rad/s, 1.1 sigma of the calibration residual
        let wall: Vec<Point2<f64>> = (0..41)
            .map(|i| Point2::new(1.0, -1.0 + 0.05 * f64::from(i)))
            .collect();
        let h = scan_information(&wall, &vec![Some(Vector2::new(-1.0, 0.0)); wall.len()]);
        let mut heading_error = 0.0;
        for _ in 0..600 {
            heading_error += filter.predict(bias * 0.1, 0.1);
            // the wall measures the true heading (0) exactly
            let update = filter.update(-heading_error, &h).expect("within the gate");
            heading_error += update.heading_rad;
            filter.apply(&update);
        }
        assert!(
            (filter.bias_radps() - bias).abs() < 0.1 * bias,
            "{}",
            filter.bias_radps()
        );
        assert!(heading_error.abs() < 0.002, "{heading_error}");
        // without any heading information the filter leaves the prediction alone
        let (points, normals) = pillar();
        let none = filter.update(0.3, &scan_information(&points, &normals));
        assert!(none.is_some_and(|u| u.heading_rad.abs() < 1e-6), "{none:?}");
        // a wall that would turn the heading by 0.3 rad is a false match
        assert!(filter.update(0.3, &h).is_none());
    }
}
