//! Errors of the scan matchers and the ICP-SLAM front end.

/// What can go wrong while matching scans or building a map from them.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LidarError {
    /// A scan (or point set) has too few usable points to be matched.
    #[error("scan has {got} usable points, need at least {min}")]
    TooFewPoints {
        /// Usable points found.
        got: usize,
        /// Minimum required.
        min: usize,
    },
    /// ICP found too few correspondences to constrain the pose.
    #[error("ICP found {got} correspondences, need at least {min}")]
    TooFewCorrespondences {
        /// Correspondences found.
        got: usize,
        /// Minimum required.
        min: usize,
    },
    /// The normal equations of an ICP step were singular (degenerate geometry).
    #[error("ICP normal equations are singular (degenerate scene, e.g. one straight wall)")]
    Degenerate,
    /// A configuration value is out of its valid range.
    #[error("invalid configuration: {field} = {value}: {reason}")]
    InvalidConfig {
        /// Name of the field.
        field: &'static str,
        /// Its value, as text.
        value: String,
        /// Why it is invalid.
        reason: &'static str,
    },
    /// A map given to continue or localise in is inconsistent.
    #[error("invalid map: {0}")]
    InvalidMap(String),
}

impl LidarError {
    /// [`LidarError::InvalidConfig`] for `field` holding `value`.
    pub(crate) fn invalid_config(field: &'static str, value: f64, reason: &'static str) -> Self {
        Self::InvalidConfig {
            field,
            value: value.to_string(),
            reason,
        }
    }
}

/// One configuration field to check: its name, its value and whether the value is in range.
pub(crate) type FieldCheck = (&'static str, f64, bool);

/// The first field that is out of range or not finite, as [`LidarError::InvalidConfig`] with
/// `reason`; `Ok` when all pass.
pub(crate) fn check_fields(
    checks: impl IntoIterator<Item = FieldCheck>,
    reason: &'static str,
) -> Result<(), LidarError> {
    match checks
        .into_iter()
        .find(|(_, value, ok)| !(*ok && value.is_finite()))
    {
        Some((field, value, _)) => Err(LidarError::invalid_config(field, value, reason)),
        None => Ok(()),
    }
}
