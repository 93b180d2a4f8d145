//! The one error type of slamkit-io: every variant names the file, and the line or frame where
//! that applies, so a user can open the file and see what is wrong.
//!
//! Each message is one whole line, the operating system's reason included; so no variant
//! also hands that reason out as its `source()`, which a caller printing the error chain
//! would print a second time (`x.tum: No such file…: No such file…`).

use std::path::PathBuf;

/// Everything that can go wrong while reading or writing a dataset, trajectory or image.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IoError {
    /// The operating system refused to open, read or write a file.
    #[error("{}: {error}", path.display())]
    Io {
        /// The file or folder involved.
        path: PathBuf,
        /// The operating system's error (in the message, not a `source()`).
        error: std::io::Error,
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
    pub(crate) fn io(path: impl Into<PathBuf>, error: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            error,
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::error::Error;

    /// Issue 25 (13): a missing file's error is one line with the path and the reason once;
    /// the reason is not also a `source()` that an error chain would print again.
    #[test]
    fn missing_file_message_names_path_and_reason_once() {
        let path = std::path::Path::new("/nonexistent/gt.tum");
        let err = read_text(path).unwrap_err();
        assert!(err.source().is_none());
        let msg = err.to_string();
        assert!(
            msg.starts_with("/nonexistent/gt.tum: No such file"),
            "{msg}"
        );
        assert_eq!(msg.matches("gt.tum").count(), 1, "{msg}");
        let log = crate::carmen::read_carmen(path).unwrap_err();
        assert!(log.source().is_none());
        assert_eq!(log.to_string(), msg);
    }
}
