//! What can go wrong in visual odometry. A bad frame is not an error of the run: it is a
//! [`crate::FrameStatus::Failed`] with a [`crate::FailReason`], counted and skipped.

/// Errors of the visual-odometry crate.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VoError {
    /// A configuration value is out of its range.
    #[error("invalid VO configuration: {field} = {value}: {reason}")]
    InvalidConfig {
        /// The offending field.
        field: &'static str,
        /// Its value, formatted.
        value: String,
        /// What is expected.
        reason: &'static str,
    },
    /// An image kernel rejected its input or configuration.
    #[error("vision: {0}")]
    Vision(#[from] slamkit_vision::VisionError),
    /// A pose-graph edge was refused.
    #[error("pose-graph edge {from} -> {to}: {reason}")]
    InvalidEdge {
        /// Index of the node the measurement is expressed in.
        from: usize,
        /// Index of the measured node.
        to: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// Writing an output file failed.
    #[error("writing {path}: {source}")]
    Write {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
}

impl VoError {
    /// An [`VoError::InvalidConfig`] for `field`.
    pub fn config(
        field: &'static str,
        value: impl std::fmt::Display,
        reason: &'static str,
    ) -> Self {
        Self::InvalidConfig {
            field,
            value: value.to_string(),
            reason,
        }
    }
}
