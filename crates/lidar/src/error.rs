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
}
