//! Errors of the map crate.

use std::path::PathBuf;

/// What went wrong while building or querying a map.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MapError {
    /// A configuration value is out of its valid range.
    #[error("invalid map configuration: {message}")]
    InvalidConfig {
        /// Which value and why.
        message: String,
    },
    /// A pose holds NaN or infinite values.
    #[error("pose is not finite: x {x_m}, y {y_m}, angle {angle_rad}")]
    NonFinitePose {
        /// Translation x \[m\].
        x_m: f64,
        /// Translation y \[m\].
        y_m: f64,
        /// Rotation \[rad\].
        angle_rad: f64,
    },
    /// The map would span more than a grid may: a pose or odometry jump, most likely.
    #[error(
        "the map would span {width_m:.0} m × {height_m:.0} m, more than a grid may \
         ({limit_tiles} tiles of {tile_m} m; a pose or odometry jump?)"
    )]
    TooLarge {
        /// Width of the bounding box asked for \[m\].
        width_m: f64,
        /// Height of the bounding box asked for \[m\].
        height_m: f64,
        /// Most tiles a grid may span.
        limit_tiles: u64,
        /// Side of a tile \[m\].
        tile_m: f64,
    },
    /// A point lies beyond the cell indices a grid can address.
    #[error("point ({x_m}, {y_m}) is outside the addressable map area")]
    OutsideMap {
        /// x \[m\].
        x_m: f64,
        /// y \[m\].
        y_m: f64,
    },
}

/// What went wrong while reading or writing a map file: a grid (PGM, PNG and YAML) or an
/// octree (OctoMap `.bt`).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MapFileError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A line of the map YAML file is malformed.
    #[error("{path}:{line}: {message}")]
    Yaml {
        /// The YAML file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A required key is missing from the map YAML file.
    #[error("{path}: missing key `{key}`")]
    MissingKey {
        /// The YAML file.
        path: PathBuf,
        /// The key.
        key: &'static str,
    },
    /// The PGM image is malformed or truncated.
    #[error("{path}: bad PGM image: {message}")]
    Pgm {
        /// The image file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The image crate could not decode or encode the image.
    #[error("{path}: {source}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// The underlying error.
        source: image::ImageError,
    },
    /// The OctoMap `.bt` file is malformed or truncated.
    #[error("{path}: bad OctoMap .bt file: {message}")]
    Octree {
        /// The `.bt` file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The file is valid but uses a feature this reader does not support.
    #[error("{path}: unsupported: {message}")]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What is unsupported.
        message: String,
    },
    /// The map described by the file cannot be built.
    #[error("{path}: {source}")]
    Map {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: MapError,
    },
}
