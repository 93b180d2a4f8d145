//! The settings of a command: the session's defaults, a profile's table over them
//! (`--profile`), and the `--config` file's fields on top (see [`slamkit_slam::profile`]).

use serde::de::DeserializeOwned;
use serde::Serialize;
use slamkit_slam::profile::{config_file_over, Profile};
use std::path::Path;

/// `base` with the `[section]` table of the profile `profile` (a built-in name or a `.toml`
/// file) and then the file `config` laid over it.
pub fn settings<C: Serialize + DeserializeOwned>(
    base: C,
    section: &str,
    profile: Option<&str>,
    config: Option<&Path>,
) -> anyhow::Result<C> {
    let base = match profile {
        Some(name) => Profile::resolve(name)?.apply(section, base)?,
        None => base,
    };
    with_file(base, config)
}

/// `base` with the file `config` laid over it, or `base` itself without one.
pub fn with_file<C: Serialize + DeserializeOwned>(
    base: C,
    config: Option<&Path>,
) -> anyhow::Result<C> {
    Ok(match config {
        Some(path) => config_file_over(base, path)?,
        None => base,
    })
}
