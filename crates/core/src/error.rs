//! Errors of the geometry routines.
//!
//! Every routine here is fed sensor data, so bad input (NaN, too few or degenerate points) is an
//! `Err` the caller can count and skip, never a panic.

/// What went wrong in a geometric estimate.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GeometryError {
    /// Corresponding point sets must pair up one to one.
    #[error("point sets differ in length: {src} source points, {dst} destination points")]
    LengthMismatch {
        /// Number of source points.
        src: usize,
        /// Number of destination points.
        dst: usize,
    },
    /// The estimate needs more data than it was given.
    #[error("need at least {min} points, got {got}")]
    TooFewPoints {
        /// Number of points given.
        got: usize,
        /// Number of points needed.
        min: usize,
    },
    /// The points do not fix the transform: all coincident or all on one line.
    #[error("{set} points are degenerate (coincident or collinear)")]
    Degenerate {
        /// Which point set: `"source"` or `"destination"`.
        set: &'static str,
    },
    /// A coordinate is NaN or infinite.
    #[error("{set} point {index} has a non-finite coordinate")]
    NonFinite {
        /// Which point set: `"source"` or `"destination"`.
        set: &'static str,
        /// Index of the offending point.
        index: usize,
    },
    /// A linear-algebra routine failed to produce its result.
    #[error("numerical failure in {what}")]
    NumericalFailure {
        /// The routine that failed.
        what: &'static str,
    },
    /// RANSAC found no model that enough data agree with.
    #[error("no consensus: best model has {inliers} inliers, need {needed}")]
    NoConsensus {
        /// Inliers of the best model found.
        inliers: usize,
        /// Inliers required.
        needed: usize,
    },
    /// A configuration value is out of its valid range.
    #[error("invalid configuration: {field} {reason}")]
    InvalidConfig {
        /// Name of the offending field.
        field: &'static str,
        /// What is wrong with it.
        reason: &'static str,
    },
}

/// `err` and its causes on one line, `outer: cause: root cause`, as the CLI prints errors; a
/// cause an outer message already quotes is not repeated.
///
/// ```
/// use slamkit_core::error::{error_chain, GeometryError};
/// #[derive(Debug, thiserror::Error)]
/// #[error("aligning the trajectories")]
/// struct Outer(#[source] GeometryError);
/// let err = Outer(GeometryError::Degenerate { set: "destination" });
/// assert_eq!(
///     error_chain(&err),
///     "aligning the trajectories: destination points are degenerate (coincident or collinear)"
/// );
/// ```
pub fn error_chain(err: &dyn std::error::Error) -> String {
    let mut message = err.to_string();
    let mut source = err.source();
    while let Some(cause) = source {
        let text = cause.to_string();
        if !message.contains(&text) {
            message = format!("{message}: {text}");
        }
        source = cause.source();
    }
    message
}
