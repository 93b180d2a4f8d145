//! `--config` files: a TOML file laid over a command's base settings.
//!
//! Every config struct is `#[serde(default)]`, so a file may name only the fields it changes.
//! But serde fills a nested table the file names from the nested *type's* `Default`, not from
//! the enclosing default: a particle filter whose relocalisation search narrows ICP-SLAM's
//! loop-closure window to 4 m got the 10 m window back as soon as a file set any other search
//! field. Laying the file over the serialised base settings, table by table, keeps every value
//! the file does not name, at any depth; unknown fields still fail (`deny_unknown_fields`).

use anyhow::Context;
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::Path;

/// `base` with the TOML file at `path` laid over it, or `base` itself without a file.
pub fn config_over<C: Serialize + DeserializeOwned>(
    base: C,
    path: Option<&Path>,
) -> anyhow::Result<C> {
    let Some(path) = path else {
        return Ok(base);
    };
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let file: toml::Table =
        toml::from_str(&text).with_context(|| format!("parsing config {}", path.display()))?;
    let mut merged = toml::Table::try_from(&base).context("serialising the base settings")?;
    merge(&mut merged, file);
    merged
        .try_into()
        .with_context(|| format!("parsing config {}", path.display()))
}

/// Overwrites `base` with `top`, table by table.
fn merge(base: &mut toml::Table, top: toml::Table) {
    for (key, value) in top {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(t)) => merge(b, t),
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_lidar::icp_slam::{IcpSlamConfig, LoopClosureConfig};
    use slamkit_lidar::rbpf::RbpfConfig;
    use std::io::Write;

    fn file(text: &str) -> tempfile::NamedTempFile {
        let mut f = tempfile::NamedTempFile::new().unwrap();
        f.write_all(text.as_bytes()).unwrap();
        f
    }

    /// `base` read back through an empty file, compared as JSON.
    fn round_trip<C: Serialize + DeserializeOwned>(base: C) {
        let f = file("");
        let expected = serde_json::to_value(&base).unwrap();
        let read = config_over(base, Some(f.path())).unwrap();
        assert_eq!(serde_json::to_value(read).unwrap(), expected);
    }

    #[test]
    fn an_empty_file_gives_the_base_settings_of_every_command() {
        round_trip(RbpfConfig::default());
        round_trip(IcpSlamConfig::default());
        round_trip(slamkit_lidar::mcl::MclConfig::default());
        round_trip(slamkit_vo::VoConfig::default());
        round_trip(slamkit_sim::SimConfig::default());
        round_trip(slamkit_slam::ground_robot::closed_loop::NavLoopConfig::default());
    }

    #[test]
    fn a_nested_table_keeps_the_base_values_it_does_not_name() {
        let f = file("seed = 7\n[relocalisation.search]\nmax_candidates = 3\n");
        let config = config_over(RbpfConfig::default(), Some(f.path())).unwrap();
        let base = RbpfConfig::default();
        assert_eq!(config.seed, 7);
        assert_eq!(config.relocalisation.search.max_candidates, 3);
        // The filter's own 4 m window and 0.65 goodness, not the loop closure's defaults.
        assert_eq!(
            config.relocalisation.search.max_window_m,
            base.relocalisation.search.max_window_m
        );
        assert_eq!(
            config.relocalisation.search.min_goodness,
            base.relocalisation.search.min_goodness
        );
        assert_ne!(
            base.relocalisation.search.max_window_m,
            LoopClosureConfig::default().max_window_m
        );
    }

    #[test]
    fn unknown_fields_and_bad_toml_are_errors() {
        for text in [
            "seeed = 1\n",
            "[relocalisation]\nfracton = 0.5\n",
            "seed = [\n",
        ] {
            let f = file(text);
            assert!(
                config_over(RbpfConfig::default(), Some(f.path())).is_err(),
                "{text}"
            );
        }
        let missing = Path::new("/nonexistent/slamkit.toml");
        assert!(config_over(RbpfConfig::default(), Some(missing)).is_err());
    }
}
