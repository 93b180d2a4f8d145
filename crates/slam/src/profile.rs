//! Named profiles and configuration files: TOML laid over a session's settings.
//!
//! Every session's settings have neutral defaults. What belongs to one sensor or robot (a
//! camera whose colour is not registered to depth, a stereo rig's noise) lives in a named
//! profile: one TOML file under the repository's `config/`, built into the library so it
//! works wherever slamkit is installed. A profile has one table per kind of settings
//! (`[vo]` for [`VoConfig`](slamkit_vo::VoConfig), `[lidar]` for
//! [`LidarSlamConfig`](crate::LidarSlamConfig), `[drone]`, `[mcl]`, `[nav]`, `[sim]`), so one file can
//! describe a robot for several commands. A user's own file with the same layout is read with
//! [`Profile::from_file`].
//!
//! Every config struct is `#[serde(default)]`, so a file may name only the fields it changes.
//! But serde fills a nested table the file names from the nested *type's* `Default`, not from
//! the enclosing default: a particle filter whose relocalisation search narrows ICP-SLAM's
//! loop-closure window to 4 m got the 10 m window back as soon as a file set any other search
//! field. [`lay_over`] therefore merges the file into the serialised base settings, table by
//! table, and keeps every value the file does not name, at any depth; unknown fields still
//! fail (`deny_unknown_fields`).
//!
//! ```
//! use slamkit_slam::profile::Profile;
//! use slamkit_vo::{TrackingMode, VoConfig};
//!
//! let stereo = Profile::builtin("stereo")?;
//! let config: VoConfig = stereo.apply("vo", VoConfig::default())?;
//! assert_eq!(config.mode, TrackingMode::FrameToFrame);
//! assert_eq!(config.max_features, VoConfig::default().max_features); // not named: kept
//! assert!(Profile::builtin("no-such-robot").is_err());
//! # Ok::<(), slamkit_slam::SlamError>(())
//! ```

use crate::SlamError;
use serde::de::DeserializeOwned;
use serde::Serialize;
use slamkit_io::DatasetFormat;
use std::path::Path;

/// The profiles built in: name and text of each `config/NAME.toml`.
const BUILTIN: [(&str, &str); 2] = [
    ("kinect-v1", include_str!("../../../config/kinect-v1.toml")),
    ("stereo", include_str!("../../../config/stereo.toml")),
];

/// The profile `slamkit vo` takes for a dataset layout when none is named: the sensor the
/// layout's recordings come from (`stereo` for KITTI and EuRoC, `kinect-v1` for 7-Scenes);
/// `None` for the RGB-D layouts the defaults already suit (TUM, Redwood).
///
/// ```
/// use slamkit_io::DatasetFormat;
/// use slamkit_slam::profile::layout_profile;
///
/// assert_eq!(layout_profile(DatasetFormat::Kitti), Some("stereo"));
/// assert_eq!(layout_profile(DatasetFormat::Tum), None);
/// ```
pub fn layout_profile(format: DatasetFormat) -> Option<&'static str> {
    match format {
        DatasetFormat::Kitti | DatasetFormat::Euroc => Some("stereo"),
        DatasetFormat::SevenScenes => Some("kinect-v1"),
        DatasetFormat::Tum | DatasetFormat::Redwood | DatasetFormat::RosBag => None,
    }
}

/// A profile: named tables of settings, each laid over one kind of session settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    name: String,
    tables: toml::Table,
}

impl Profile {
    /// The names of the built-in profiles.
    pub fn builtin_names() -> impl Iterator<Item = &'static str> {
        BUILTIN.iter().map(|(name, _)| *name)
    }

    /// The built-in profile `name` (a file of the repository's `config/`).
    ///
    /// # Errors
    /// [`SlamError::Config`] for an unknown name, listing the known ones.
    pub fn builtin(name: &str) -> Result<Self, SlamError> {
        let Some((_, text)) = BUILTIN.iter().find(|(n, _)| *n == name) else {
            let known: Vec<_> = Self::builtin_names().collect();
            return Err(SlamError::Config(format!(
                "no profile `{name}` (built in: {})",
                known.join(", ")
            )));
        };
        Self::parse(name, text)
    }

    /// What `--profile` names: a built-in profile, or a user's file when `name_or_path` ends
    /// in `.toml`.
    ///
    /// # Errors
    /// As [`Profile::builtin`] and [`Profile::from_file`].
    pub fn resolve(name_or_path: &str) -> Result<Self, SlamError> {
        if name_or_path.ends_with(".toml") {
            Self::from_file(Path::new(name_or_path))
        } else {
            Self::builtin(name_or_path)
        }
    }

    /// A profile written by a user, laid out as the built-in ones.
    ///
    /// # Errors
    /// [`SlamError::Config`] when the file cannot be read or is not TOML.
    pub fn from_file(path: &Path) -> Result<Self, SlamError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SlamError::Config(format!("{}: {e}", path.display())))?;
        Self::parse(&path.display().to_string(), &text)
    }

    /// The profile in `text`, called `name` in errors.
    ///
    /// # Errors
    /// [`SlamError::Config`] when `text` is not TOML or holds a value outside a table.
    pub fn parse(name: &str, text: &str) -> Result<Self, SlamError> {
        let tables: toml::Table = toml::from_str(text).map_err(|e| toml_error(name, text, &e))?;
        if let Some((key, _)) = tables.iter().find(|(_, v)| !v.is_table()) {
            return Err(SlamError::Config(format!(
                "profile {name}: `{key}` is not a table; a profile holds [vo], [lidar], ... tables"
            )));
        }
        Ok(Self {
            name: name.to_owned(),
            tables,
        })
    }

    /// The profile's name (a file's path for a user's profile).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The tables the profile sets (`vo`, `lidar`, ...).
    pub fn sections(&self) -> impl Iterator<Item = &str> {
        self.tables.keys().map(String::as_str)
    }

    /// `base` with the profile's table `section` laid over it.
    ///
    /// # Errors
    /// [`SlamError::Config`] when the profile has no such table (a profile for another kind of
    /// robot), or a field in it is unknown or of the wrong type.
    pub fn apply<C: Serialize + DeserializeOwned>(
        &self,
        section: &str,
        base: C,
    ) -> Result<C, SlamError> {
        let Some(toml::Value::Table(table)) = self.tables.get(section) else {
            let sections: Vec<_> = self.sections().collect();
            return Err(SlamError::Config(format!(
                "profile {} has no [{section}] settings (it has: {})",
                self.name,
                sections.join(", ")
            )));
        };
        lay_over(base, table.clone()).map_err(|e| match e {
            SlamError::Config(m) => SlamError::Config(format!("profile {}: {m}", self.name)),
            other => other,
        })
    }
}

/// `base` with the `[section]` table of the profile `profile` (a built-in name or a `.toml`
/// file) and then the file `config` laid over it: how every shell (the CLI, the Python
/// binding) builds a session's settings.
///
/// # Errors
/// [`SlamError::Config`] for an unknown profile, one without `[section]`, or a field of either
/// file that is unknown or of the wrong type.
pub fn settings<C: Serialize + DeserializeOwned>(
    base: C,
    section: &str,
    profile: Option<&str>,
    config: Option<&Path>,
) -> Result<C, SlamError> {
    let base = match profile {
        Some(name) => Profile::resolve(name)?.apply(section, base)?,
        None => base,
    };
    file_over(base, config)
}

/// `base` with the file `config` laid over it ([`config_file_over`]), or `base` itself
/// without one.
///
/// # Errors
/// As [`config_file_over`].
pub fn file_over<C: Serialize + DeserializeOwned>(
    base: C,
    config: Option<&Path>,
) -> Result<C, SlamError> {
    match config {
        Some(path) => config_file_over(base, path),
        None => Ok(base),
    }
}

/// `base` with the TOML file at `path` laid over it (the file holds the settings' own fields,
/// at the top level).
///
/// # Errors
/// [`SlamError::Config`] when the file cannot be read, is not TOML, or names an unknown field.
pub fn config_file_over<C: Serialize + DeserializeOwned>(
    base: C,
    path: &Path,
) -> Result<C, SlamError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| SlamError::Config(format!("{}: {e}", path.display())))?;
    let file: toml::Table =
        toml::from_str(&text).map_err(|e| toml_error(&path.display().to_string(), &text, &e))?;
    lay_over(base, file).map_err(|e| match e {
        SlamError::Config(m) => SlamError::Config(format!("{}: {m}", path.display())),
        other => other,
    })
}

/// `base` with `top` laid over it, table by table, keeping every value `top` does not name.
///
/// # Errors
/// [`SlamError::Config`] when a field of `top` is unknown or of the wrong type.
pub fn lay_over<C: Serialize + DeserializeOwned>(
    base: C,
    top: toml::Table,
) -> Result<C, SlamError> {
    let mut merged = toml::Table::try_from(&base)
        .map_err(|e| SlamError::Config(format!("the base settings as TOML: {e}")))?;
    merge(&mut merged, top);
    // Read back from text, so an error has a place in it: the field it names.
    let text = toml::to_string(&merged)
        .map_err(|e| SlamError::Config(format!("the settings as TOML: {e}")))?;
    toml::from_str(&text).map_err(|e| {
        let field = e
            .span()
            .and_then(|span| field_at(&text, span.start))
            .map(|f| format!("`{f}`: "))
            .unwrap_or_default();
        SlamError::Config(format!("{field}{}", one_line(e.message())))
    })
}

/// The dotted name of the field on the line of `text` holding byte `at` (`a.b.c` for `c = ...`
/// under `[a.b]`).
fn field_at(text: &str, at: usize) -> Option<String> {
    let before = text.get(..at)?;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let line = text[line_start..].lines().next()?;
    let key = line.split('=').next()?.trim();
    let table = before[..line_start].lines().rev().find_map(|l| {
        l.trim()
            .strip_prefix('[')?
            .strip_suffix(']')
            .map(str::to_owned)
    });
    Some(match table {
        Some(table) if !key.is_empty() => format!("{table}.{key}"),
        _ => key.to_owned(),
    })
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

/// A TOML syntax error on one line: the file, the line and what is wrong.
fn toml_error(name: &str, text: &str, e: &toml::de::Error) -> SlamError {
    let at = e
        .span()
        .map(|span| {
            let line = text[..span.start.min(text.len())].matches('\n').count() + 1;
            format!(" line {line}")
        })
        .unwrap_or_default();
    SlamError::Config(format!("{name}{at}: {}", one_line(e.message())))
}

fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ground_robot::closed_loop::NavLoopConfig;
    use crate::{DroneSlamConfig, LidarSlamConfig};
    use slamkit_lidar::icp_slam::{IcpSlamConfig, LoopClosureConfig};
    use slamkit_lidar::rbpf::RbpfConfig;
    use slamkit_vo::VoConfig;
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
        let read = config_file_over(base, f.path()).unwrap();
        assert_eq!(serde_json::to_value(read).unwrap(), expected);
    }

    #[test]
    fn an_empty_file_gives_the_base_settings_of_every_session() {
        round_trip(RbpfConfig::default());
        round_trip(IcpSlamConfig::default());
        round_trip(LidarSlamConfig::default());
        round_trip(DroneSlamConfig::default());
        round_trip(slamkit_lidar::mcl::MclConfig::default());
        round_trip(VoConfig::default());
        round_trip(slamkit_sim::SimConfig::default());
        round_trip(NavLoopConfig::default());
    }

    #[test]
    fn a_nested_table_keeps_the_base_values_it_does_not_name() {
        let f = file("seed = 7\n[relocalisation.search]\nmax_candidates = 3\n");
        let config = config_file_over(RbpfConfig::default(), f.path()).unwrap();
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
    fn unknown_fields_and_bad_toml_are_one_line_errors() {
        for (text, says) in [
            ("seeed = 1\n", "seeed"),
            ("[relocalisation]\nfracton = 0.5\n", "fracton"),
            ("seed = 1\nfoo = = 2\n", "line 2"),
            ("seed = \"x\"\n", "seed"),
        ] {
            let f = file(text);
            let e = config_file_over(RbpfConfig::default(), f.path())
                .unwrap_err()
                .to_string();
            assert!(e.contains(says) && !e.contains('\n'), "{text}: {e}");
        }
        let missing = Path::new("/nonexistent/slamkit.toml");
        let e = config_file_over(RbpfConfig::default(), missing).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/slamkit.toml"), "{e}");
    }

    #[test]
    fn every_builtin_profile_reads_into_the_settings_it_names() {
        for name in Profile::builtin_names() {
            let profile = Profile::builtin(name).unwrap();
            let sections: Vec<String> = profile.sections().map(str::to_owned).collect();
            assert!(!sections.is_empty(), "{name}");
            for section in sections {
                let ok = match section.as_str() {
                    "vo" => profile.apply(&section, VoConfig::default()).is_ok(),
                    "lidar" => profile.apply(&section, LidarSlamConfig::default()).is_ok(),
                    "drone" => profile.apply(&section, DroneSlamConfig::default()).is_ok(),
                    "nav" => profile.apply(&section, NavLoopConfig::default()).is_ok(),
                    "mcl" => profile
                        .apply(&section, slamkit_lidar::mcl::MclConfig::default())
                        .is_ok(),
                    "sim" => profile
                        .apply(&section, slamkit_sim::SimConfig::default())
                        .is_ok(),
                    other => panic!("profile {name}: unknown section [{other}]"),
                };
                assert!(ok, "profile {name} [{section}]");
            }
        }
    }

    #[test]
    fn the_profiles_set_what_their_sensors_need() {
        let kinect: VoConfig = Profile::builtin("kinect-v1")
            .unwrap()
            .apply("vo", VoConfig::default())
            .unwrap();
        let registration = kinect.register_depth.expect("depth registration");
        assert_eq!(registration.color_intrinsics, [525.0, 525.0, 319.5, 239.5]);
        assert_eq!(registration.color_from_depth_m, [-0.025, 0.0, 0.0]);
        let stereo: VoConfig = Profile::builtin("stereo")
            .unwrap()
            .apply("vo", VoConfig::default())
            .unwrap();
        assert_eq!(stereo.motion.noise.disparity_sigma_px, 1.0);
        assert_eq!(stereo.motion.noise.depth_sigma_base_m, 0.0);
        assert_eq!(stereo.orb.n_levels, 1);
        assert_eq!(stereo.orb.cell_px, 30);
    }

    #[test]
    fn a_profile_for_another_rig_says_what_it_has() {
        let e = Profile::builtin("stereo")
            .unwrap()
            .apply("lidar", LidarSlamConfig::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("no [lidar]") && e.contains("vo"), "{e}");
        let e = Profile::parse("p", "speed = 1\n").unwrap_err().to_string();
        assert!(e.contains("speed"), "{e}");
        let e = Profile::builtin("nope").unwrap_err().to_string();
        assert!(e.contains("stereo") && e.contains("kinect-v1"), "{e}");
    }
}
