//! Geometric verification of a fix the other way round: the searched map's view of the place
//! (its keyframe nearest the fix with the keyframe's neighbours in time) is aligned by ICP into
//! the querying map's keyframes around the query, starting from the inverse of the fix. A true
//! match explains both views; a query that saw only part of a place (a stretch of corridor that
//! fits anywhere along a longer one, a room corner that fits another room) gives a reverse
//! alignment that fits poorly or slides away from the fix.

use super::{submap_points, ClosureStatus, InterClosure};
use crate::SlamError;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use slamkit_lidar::cloud::voxel_downsample;
use slamkit_lidar::icp::{align, IcpConfig};
use slamkit_lidar::point_map::{index_keyframes, Keyframe};

/// Geometric verification settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VerifyConfig {
    /// The searched map's view holds this many keyframes on each side of the matched one.
    pub half_keyframes: usize,
    /// Points of that view farther than this from its keyframe are left out \[m\].
    pub max_range_m: f64,
    /// The querying map's keyframes within this distance of the query are the target \[m\].
    pub target_radius_m: f64,
    /// Voxel size of source and target \[m\].
    pub voxel_m: f64,
    /// The reverse alignment.
    pub icp: IcpConfig,
    /// Lowest ICP goodness of the reverse alignment, in \[0, 1\].
    pub min_goodness: f64,
    /// The reverse alignment's relative pose must lie within this of the fix's \[m\]...
    pub agree_m: f64,
    /// ...and turn by no more than this from it \[rad\].
    pub agree_rad: f64,
}

impl Default for VerifyConfig {
    fn default() -> Self {
        Self {
            half_keyframes: 10,
            max_range_m: 10.0,
            target_radius_m: 10.0,
            voxel_m: 0.05,
            icp: IcpConfig::default(),
            min_goodness: 0.6,
            agree_m: 0.1,
            agree_rad: 2f64.to_radians(),
        }
    }
}

impl VerifyConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), SlamError> {
        self.icp.validate()?;
        let ok = self.max_range_m > 0.0
            && self.target_radius_m > 0.0
            && self.voxel_m > 0.0
            && (0.0..=1.0).contains(&self.min_goodness)
            && self.agree_m >= 0.0
            && self.agree_rad >= 0.0;
        if ok {
            Ok(())
        } else {
            Err(SlamError::Config(format!(
                "merge verify: a field is out of range in {self:?}"
            )))
        }
    }
}

/// Verifies every closure (`keyframes[m]`: map `m`'s keyframes), setting its reverse goodness,
/// and its status to [`ClosureStatus::FailedVerification`] when the reverse alignment fails.
pub fn verify_all(
    keyframes: &[Vec<Keyframe>],
    closures: &mut [InterClosure],
    config: &VerifyConfig,
) {
    closures.par_iter_mut().for_each(|c| {
        let reverse = reverse_alignment(keyframes, c, config);
        c.reverse_goodness = reverse.map(|(goodness, _)| goodness);
        if !reverse.is_some_and(|(_, agrees)| agrees) {
            c.status = ClosureStatus::FailedVerification;
        }
    });
}

/// The reverse alignment's goodness, and whether it passes (fits well enough and agrees with
/// the fix); `None` when it could not run (a keyframe out of range, too few points).
fn reverse_alignment(
    keyframes: &[Vec<Keyframe>],
    c: &InterClosure,
    config: &VerifyConfig,
) -> Option<(f64, bool)> {
    let (from_kfs, to_kfs) = (keyframes.get(c.from_map)?, keyframes.get(c.to_map)?);
    let world_from_to = to_kfs.get(c.to_keyframe)?.world_from_base;
    let source: Vec<_> = submap_points(from_kfs, c.from_keyframe, config.half_keyframes)
        .into_iter()
        .filter(|p| p.coords.norm() < config.max_range_m)
        .collect();
    let source = voxel_downsample(&source, config.voxel_m);
    let centre = world_from_to.translation.vector;
    let near: Vec<Keyframe> = to_kfs
        .iter()
        .filter(|kf| {
            (kf.world_from_base.translation.vector - centre).norm() < config.target_radius_m
        })
        .cloned()
        .collect();
    let target = index_keyframes(&near, config.voxel_m);
    // the fix says world_to_from_from = world_from_to · (from_from_to)⁻¹
    let guess = world_from_to * c.from_from_to.inverse();
    let fit = align(&source, &target, &guess, &config.icp).ok()?;
    let reverse_from_from_to = fit.target_from_source.inverse() * world_from_to;
    let d = c.from_from_to.inverse() * reverse_from_from_to;
    let agrees = fit.goodness >= config.min_goodness
        && d.translation.vector.norm() <= config.agree_m
        && d.rotation.angle().abs() <= config.agree_rad;
    Some((fit.goodness, agrees))
}
