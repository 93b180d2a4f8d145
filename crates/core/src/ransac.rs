//! RANSAC: robust model fitting when many data are outliers.
//!
//! M. A. Fischler and R. C. Bolles, "Random sample consensus", CACM 24(6):381–395, 1981. Draw a
//! minimal random sample, fit a model to it, count the data it explains (residual ≤ threshold),
//! keep the best; finally refit on all its inliers. The number of draws adapts to the best inlier
//! ratio `P` seen so far (Hartley & Zisserman, *Multiple View Geometry*, 2nd ed., §4.7.1,
//! eq. 4.18): `N = log(1 − Z) / log(1 − Pᵐ)` draws give probability `Z` that at least one sample
//! of size `m` was outlier-free. Sampling uses a seeded ChaCha8 generator, so a run is
//! reproducible.
//!
//! [`RigidTransformEstimator`] plugs Horn's method ([`crate::absolute_orientation`]) into the
//! driver, for 3D–3D motion estimation in visual odometry.

use crate::absolute_orientation::horn;
use crate::{GeometryError, Pose3};
use nalgebra::Point3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// A model RANSAC can fit: how to fit it from a sample and how well it explains a datum.
///
/// Fits take the whole data set plus the indices to use, so samples are never copied.
pub trait Estimator {
    /// One observation, e.g. a pair of matched points.
    type Datum;
    /// The fitted model, e.g. a pose.
    type Model: Clone;

    /// Size `m` of a minimal sample: the fewest data that fix a model.
    fn sample_size(&self) -> usize;

    /// Fits a model to a minimal sample of `sample_size()` indices.
    ///
    /// # Errors
    /// When the sample is degenerate; RANSAC then simply draws again.
    fn fit_sample(
        &self,
        data: &[Self::Datum],
        sample: &[usize],
    ) -> Result<Self::Model, GeometryError>;

    /// Fits a model to all inliers (least squares over the consensus set).
    ///
    /// # Errors
    /// When the inliers do not fix a model.
    fn fit_inliers(
        &self,
        data: &[Self::Datum],
        inliers: &[usize],
    ) -> Result<Self::Model, GeometryError>;

    /// How badly `model` explains `datum`, in the unit of [`RansacConfig::threshold`].
    fn residual(&self, model: &Self::Model, datum: &Self::Datum) -> f64;
}

/// RANSAC settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RansacConfig {
    /// Wanted probability `Z` that at least one sample was outlier-free, in (0, 1).
    pub confidence: f64,
    /// A datum is an inlier when its residual is at most this, in the estimator's residual unit
    /// (metres of point distance for [`RigidTransformEstimator`]).
    pub threshold: f64,
    /// Upper limit on samples drawn, whatever the adaptive count asks for.
    pub max_iterations: u32,
    /// Fewest inliers for a model to be accepted; the sample size is always required.
    pub min_inliers: usize,
    /// Seed of the sampling generator.
    pub seed: u64,
}

impl Default for RansacConfig {
    fn default() -> Self {
        Self {
            confidence: 0.99,
            threshold: 0.05,
            max_iterations: 1000,
            min_inliers: 0,
            seed: 0,
        }
    }
}

/// What RANSAC found.
#[derive(Debug, Clone, PartialEq)]
pub struct RansacResult<M> {
    /// The model refitted on all inliers of the best sample.
    pub model: M,
    /// Indices of the data within the threshold of `model`, ascending.
    pub inliers: Vec<usize>,
    /// `inlier_mask[i]` is true when datum `i` is an inlier of `model`.
    pub inlier_mask: Vec<bool>,
    /// Samples drawn.
    pub iterations: u32,
}

/// Runs RANSAC with `estimator` on `data`.
///
/// # Errors
/// [`GeometryError::InvalidConfig`] for a confidence outside (0, 1), a non-positive or
/// non-finite threshold or zero iterations; [`GeometryError::TooFewPoints`] when `data` is
/// smaller than a sample; [`GeometryError::NoConsensus`] when no model reaches the required
/// number of inliers.
pub fn ransac<E: Estimator>(
    estimator: &E,
    data: &[E::Datum],
    config: &RansacConfig,
) -> Result<RansacResult<E::Model>, GeometryError> {
    validate(config)?;
    let m = estimator.sample_size();
    if data.len() < m {
        return Err(GeometryError::TooFewPoints {
            got: data.len(),
            min: m,
        });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let mut best: Option<(E::Model, Vec<bool>, usize)> = None;
    let mut needed = config.max_iterations;
    let mut iterations = 0;
    while iterations < needed {
        iterations += 1;
        let sample = rand::seq::index::sample(&mut rng, data.len(), m).into_vec();
        let Ok(model) = estimator.fit_sample(data, &sample) else {
            continue;
        };
        let mask = inlier_mask(estimator, &model, data, config.threshold);
        let count = mask.iter().filter(|&&b| b).count();
        if best.as_ref().map_or(true, |(_, _, c)| count > *c) {
            let ratio = count as f64 / data.len() as f64;
            needed = required_iterations(config.confidence, ratio, m, config.max_iterations);
            best = Some((model, mask, count));
        }
    }
    let required = config.min_inliers.max(m);
    let (model, mask) = match best {
        Some((model, mask, count)) if count >= required => (model, mask),
        best => {
            return Err(GeometryError::NoConsensus {
                inliers: best.map_or(0, |(_, _, c)| c),
                needed: required,
            })
        }
    };
    Ok(refit(
        estimator,
        data,
        config.threshold,
        model,
        mask,
        iterations,
    ))
}

/// Refits on the consensus set and recomputes the inliers against the refined model. Should
/// the refit fail, the best sample's model and inliers are kept: they are valid, just rougher.
fn refit<E: Estimator>(
    estimator: &E,
    data: &[E::Datum],
    threshold: f64,
    model: E::Model,
    mask: Vec<bool>,
    iterations: u32,
) -> RansacResult<E::Model> {
    let (model, inlier_mask) = match estimator.fit_inliers(data, &indices(&mask)) {
        Ok(refined) => {
            let mask = inlier_mask(estimator, &refined, data, threshold);
            (refined, mask)
        }
        Err(_) => (model, mask),
    };
    RansacResult {
        model,
        inliers: indices(&inlier_mask),
        inlier_mask,
        iterations,
    }
}

fn validate(config: &RansacConfig) -> Result<(), GeometryError> {
    let invalid = |field, reason| Err(GeometryError::InvalidConfig { field, reason });
    if !(config.confidence > 0.0 && config.confidence < 1.0) {
        return invalid("confidence", "must lie in (0, 1)");
    }
    if !(config.threshold.is_finite() && config.threshold > 0.0) {
        return invalid("threshold", "must be positive and finite");
    }
    if config.max_iterations == 0 {
        return invalid("max_iterations", "must be at least 1");
    }
    Ok(())
}

fn inlier_mask<E: Estimator>(
    estimator: &E,
    model: &E::Model,
    data: &[E::Datum],
    threshold: f64,
) -> Vec<bool> {
    // a NaN residual compares false: never an inlier
    data.iter()
        .map(|d| estimator.residual(model, d) <= threshold)
        .collect()
}

fn indices(mask: &[bool]) -> Vec<usize> {
    mask.iter()
        .enumerate()
        .filter_map(|(i, &b)| b.then_some(i))
        .collect()
}

/// Samples needed for confidence `z` at inlier ratio `p` with samples of size `m`:
/// `N = ⌈log(1 − z) / log(1 − pᵐ)⌉` (H&Z eq. 4.18), capped at `max`.
fn required_iterations(z: f64, p: f64, m: usize, max: u32) -> u32 {
    let p_m = p.powi(i32::try_from(m).unwrap_or(i32::MAX));
    if p_m >= 1.0 {
        return 1;
    }
    // ln_1p keeps precision when pᵐ is tiny
    let n = ((1.0 - z).ln() / (-p_m).ln_1p()).ceil();
    if n.is_finite() && n < f64::from(max) {
        (n as u32).max(1)
    } else {
        max
    }
}

/// A matched pair of 3D points: `dst ≈ dst_from_src * src`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointMatch {
    /// The point in the source frame.
    pub src: Point3<f64>,
    /// The same point seen in the destination frame.
    pub dst: Point3<f64>,
}

/// Rigid 3D–3D motion (`dst_from_src`) from point matches, by Horn's method on 3-point samples.
/// The residual is the distance `|dst − dst_from_src · src|` in metres.
#[derive(Debug, Clone, Copy, Default)]
pub struct RigidTransformEstimator;

impl RigidTransformEstimator {
    fn fit(data: &[PointMatch], indices: &[usize]) -> Result<Pose3, GeometryError> {
        let (src, dst): (Vec<_>, Vec<_>) = indices
            .iter()
            .filter_map(|&i| data.get(i))
            .map(|m| (m.src, m.dst))
            .unzip();
        Ok(horn(&src, &dst, false)?.dst_from_src)
    }
}

impl Estimator for RigidTransformEstimator {
    type Datum = PointMatch;
    type Model = Pose3;

    fn sample_size(&self) -> usize {
        3
    }

    fn fit_sample(&self, data: &[PointMatch], sample: &[usize]) -> Result<Pose3, GeometryError> {
        Self::fit(data, sample)
    }

    fn fit_inliers(&self, data: &[PointMatch], inliers: &[usize]) -> Result<Pose3, GeometryError> {
        Self::fit(data, inliers)
    }

    fn residual(&self, model: &Pose3, datum: &PointMatch) -> f64 {
        (datum.dst - model * datum.src).norm()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{random_pose, random_vector};

    /// `n` matches under a random pose, the first `inliers` of them with ±5 mm noise, the rest
    /// with a random destination anywhere in a 20 m cube.
    fn matches(seed: u64, n: usize, inliers: usize) -> (Vec<PointMatch>, Pose3) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let truth = random_pose(&mut rng);
        let data = (0..n)
            .map(|i| {
                let src = Point3::from(random_vector(&mut rng, 5.0));
                let dst = if i < inliers {
                    truth * src + random_vector(&mut rng, 0.005)
                } else {
                    Point3::from(random_vector(&mut rng, 10.0))
                };
                PointMatch { src, dst }
            })
            .collect();
        (data, truth)
    }

    #[test]
    fn recovers_motion_with_60_percent_outliers() {
        let (data, truth) = matches(1, 200, 80);
        let result = ransac(&RigidTransformEstimator, &data, &RansacConfig::default()).unwrap();
        let err = truth.inverse() * result.model;
        assert!(err.translation.vector.norm() < 5e-3, "{err}");
        assert!(err.rotation.angle() < 1e-3, "{err}");
        assert_eq!(result.inliers, (0..80).collect::<Vec<_>>());
        assert_eq!(result.inlier_mask.iter().filter(|&&b| b).count(), 80);
    }

    #[test]
    fn iteration_count_adapts_to_outlier_ratio() {
        let config = RansacConfig::default();
        let few = ransac(&RigidTransformEstimator, &matches(2, 200, 180).0, &config).unwrap();
        let many = ransac(&RigidTransformEstimator, &matches(2, 200, 80).0, &config).unwrap();
        // expected counts at the true ratios: 4 (90 % inliers) and 70 (40 % inliers)
        assert!(few.iterations <= 10, "{}", few.iterations);
        assert!(
            many.iterations > few.iterations,
            "{} vs {}",
            many.iterations,
            few.iterations
        );
        assert!(
            many.iterations < config.max_iterations,
            "{}",
            many.iterations
        );
    }

    #[test]
    fn required_iterations_follows_the_formula() {
        assert_eq!(required_iterations(0.99, 0.4, 3, 1000), 70);
        assert_eq!(required_iterations(0.99, 0.9, 3, 1000), 4);
        assert_eq!(required_iterations(0.99, 1.0, 3, 1000), 1);
        assert_eq!(required_iterations(0.99, 0.0, 3, 1000), 1000);
        assert_eq!(required_iterations(0.99, 0.01, 3, 1000), 1000);
    }

    #[test]
    fn max_iterations_caps_and_seed_repeats() {
        // 90 % inliers: this confidence needs 11 samples
        let (data, _) = matches(3, 100, 90);
        let config = RansacConfig {
            confidence: 0.999_999,
            max_iterations: 5,
            seed: 42,
            ..RansacConfig::default()
        };
        let a = ransac(&RigidTransformEstimator, &data, &config);
        assert_eq!(a.as_ref().map(|r| r.iterations).ok(), Some(5));
        assert_eq!(a, ransac(&RigidTransformEstimator, &data, &config));
    }

    #[test]
    fn bad_input_is_an_error() {
        let (data, _) = matches(4, 50, 0);
        let config = RansacConfig {
            min_inliers: 10,
            ..RansacConfig::default()
        };
        let result = ransac(&RigidTransformEstimator, &data, &config);
        assert!(
            matches!(result, Err(GeometryError::NoConsensus { needed: 10, .. })),
            "{result:?}"
        );
        let result = ransac(&RigidTransformEstimator, &data[..2], &config);
        assert!(matches!(
            result,
            Err(GeometryError::TooFewPoints { got: 2, min: 3 })
        ));
        for bad in [
            RansacConfig {
                confidence: 1.0,
                ..config.clone()
            },
            RansacConfig {
                threshold: f64::NAN,
                ..config.clone()
            },
            RansacConfig {
                max_iterations: 0,
                ..config.clone()
            },
        ] {
            let result = ransac(&RigidTransformEstimator, &data, &bad);
            assert!(
                matches!(result, Err(GeometryError::InvalidConfig { .. })),
                "{bad:?}"
            );
        }
    }

    #[test]
    fn nan_matches_are_never_inliers() {
        let (mut data, truth) = matches(5, 60, 60);
        data[7].dst.x = f64::NAN;
        let result = ransac(&RigidTransformEstimator, &data, &RansacConfig::default()).unwrap();
        assert!(!result.inlier_mask[7]);
        assert_eq!(result.inliers.len(), 59);
        assert!((truth.inverse() * result.model).translation.vector.norm() < 5e-3);
    }

    #[test]
    fn config_reads_partial_json_and_rejects_unknown_fields() {
        let config: RansacConfig = serde_json::from_str(r#"{"threshold": 0.1}"#).unwrap();
        assert_eq!(config.threshold, 0.1);
        assert_eq!(
            config.max_iterations,
            RansacConfig::default().max_iterations
        );
        assert!(serde_json::from_str::<RansacConfig>(r#"{"treshold": 0.1}"#).is_err());
    }
}
