//! The one error type of slamkit-io: every variant names the file, and the line or frame where
//! that applies, so a user can open the file and see what is wrong.

use std::path::PathBuf;

/// Everything that can go wrong while reading or writing a dataset, trajectory or image.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IoError {
    /// The operating system refused to open, read or write a file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder involved.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A line of a text file could not be understood.
    #[error("{file}:{line}: {message}")]
    Parse {
        /// The file (or `<input>` for in-memory text).
        file: String,
        /// 1-based line number.
        line: usize,
        /// What is wrong with the line.
        message: String,
    },
    /// A file holds no data at all (no pose, no frame).
    #[error("{file}: no data ({what})")]
    Empty {
        /// The file (or `<input>` for in-memory text).
        file: String,
        /// What was expected.
        what: String,
    },
    /// An image could not be decoded or has an unexpected pixel type.
    #[error("{}: image: {message}", path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A dataset folder or file is inconsistent as a whole (missing entry, bad frame index,
    /// a value that cannot be written).
    #[error("{file}: {message}")]
    Invalid {
        /// The file or folder involved.
        file: String,
        /// What is wrong.
        message: String,
    },
}

impl IoError {
    /// Wraps an OS error with the path it concerns.
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }

    /// A parse error at `line` (1-based) of `file`.
    pub(crate) fn parse(file: &str, line: usize, message: impl Into<String>) -> Self {
        Self::Parse {
            file: file.to_string(),
            line,
            message: message.into(),
        }
    }

    /// An inconsistency in `file` as a whole.
    pub(crate) fn invalid(file: impl std::fmt::Display, message: impl Into<String>) -> Self {
        Self::Invalid {
            file: file.to_string(),
            message: message.into(),
        }
    }
}

/// Reads a whole text file, naming it on failure.
pub(crate) fn read_text(path: &std::path::Path) -> Result<String, IoError> {
    std::fs::read_to_string(path).map_err(|e| IoError::io(path, e))
}
