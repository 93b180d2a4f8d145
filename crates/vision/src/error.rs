//! Errors of the image kernels: bad configuration or images that do not fit together.
//!
//! Kernels that cannot fail on any image (colour conversion, filters) return plain values; the
//! ones that take a configuration or several images return [`VisionError`].

/// What went wrong in an image kernel.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum VisionError {
    /// A configuration value is out of its valid range.
    #[error("invalid configuration: {field} = {value} ({reason})")]
    InvalidConfig {
        /// Name of the offending field.
        field: &'static str,
        /// The value given, formatted.
        value: String,
        /// What the valid range is.
        reason: &'static str,
    },
    /// Two images that must have the same size do not.
    #[error("image sizes differ: {a_width}x{a_height} vs {b_width}x{b_height}")]
    SizeMismatch {
        /// Width of the first image \[px\].
        a_width: usize,
        /// Height of the first image \[px\].
        a_height: usize,
        /// Width of the second image \[px\].
        b_width: usize,
        /// Height of the second image \[px\].
        b_height: usize,
    },
    /// The image is smaller than the kernel needs.
    #[error("image {width}x{height} is too small: need at least {min_width}x{min_height}")]
    ImageTooSmall {
        /// Width \[px\].
        width: usize,
        /// Height \[px\].
        height: usize,
        /// Minimum width \[px\].
        min_width: usize,
        /// Minimum height \[px\].
        min_height: usize,
    },
}

impl VisionError {
    /// Shorthand for [`VisionError::InvalidConfig`].
    pub(crate) fn config(field: &'static str, value: impl ToString, reason: &'static str) -> Self {
        Self::InvalidConfig {
            field,
            value: value.to_string(),
            reason,
        }
    }
}
