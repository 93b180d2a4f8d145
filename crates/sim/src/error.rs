//! The one error type of slamkit-sim: bad world descriptions and impossible robot paths.

/// Everything that can go wrong while loading a world or planning a simulated run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// The world name is neither built in nor a file.
    #[error("unknown world {name:?} (built in: small, large, office)")]
    UnknownWorld {
        /// The name asked for.
        name: String,
    },
    /// The world TOML could not be parsed.
    #[error("world {world}: {message}")]
    Parse {
        /// The world name or file.
        world: String,
        /// The parser's message, with line and column.
        message: String,
    },
    /// The world parsed but describes something impossible.
    #[error("world {world}: {what}")]
    InvalidWorld {
        /// The world name or file.
        world: String,
        /// What is wrong (names the primitive).
        what: String,
    },
    /// A sensor or robot configuration value is out of range.
    #[error("config: {0}")]
    InvalidConfig(String),
}
