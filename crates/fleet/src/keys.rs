//! Zenoh key expressions of a fleet:
//! `slamkit/<fleet>/<robot>/keyframes/<seq>`, `slamkit/<fleet>/<robot>/edges/<seq>` and
//! `slamkit/<fleet>/<robot>/status` from the robots, `slamkit/<fleet>/merged/{map,report,status}`
//! from the merger.

use crate::FleetError;
use slamkit_slam::map_updates::{MapUpdate, Stream};

/// The key a robot's message goes out on.
///
/// ```
/// use slamkit_fleet::keys::{parse, update_key};
/// use slamkit_slam::map_updates::Stream;
/// assert_eq!(update_key("lab", "r1", Stream::Edges, 7), "slamkit/lab/r1/edges/7");
/// assert_eq!(update_key("lab", "r1", Stream::Status, 7), "slamkit/lab/r1/status");
/// assert_eq!(parse("slamkit/lab/r1/edges/7").unwrap(), ("r1".to_string(), Stream::Edges));
/// ```
pub fn update_key(fleet: &str, robot: &str, stream: Stream, seq: u64) -> String {
    match stream {
        Stream::Status => format!("slamkit/{fleet}/{robot}/status"),
        _ => format!("slamkit/{fleet}/{robot}/{}/{seq}", stream.name()),
    }
}

/// The key of `update` from `robot` of `fleet`.
pub fn key_of(fleet: &str, robot: &str, update: &MapUpdate) -> String {
    update_key(fleet, robot, update.stream(), update.seq)
}

/// Every key of one robot (what its queryable answers).
pub fn robot_keys(fleet: &str, robot: &str) -> String {
    format!("slamkit/{fleet}/{robot}/**")
}

/// Every robot's messages of a fleet.
pub fn fleet_keys(fleet: &str) -> String {
    format!("slamkit/{fleet}/*/**")
}

/// What the merger publishes under `slamkit/<fleet>/merged/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Merged {
    /// The merged map, a `.skmap` file's bytes.
    Map,
    /// The merge's report, JSON.
    Report,
    /// The Zenoh timestamp of the latest merged map, as text, every second: a robot that
    /// holds an older one (it missed a publication, or joined late) asks for the map.
    Status,
}

/// The key of the merger's `what`.
///
/// ```
/// use slamkit_fleet::keys::{merged_key, Merged};
/// assert_eq!(merged_key("lab", Merged::Map), "slamkit/lab/merged/map");
/// assert_eq!(merged_key("lab", Merged::Status), "slamkit/lab/merged/status");
/// ```
pub fn merged_key(fleet: &str, what: Merged) -> String {
    let what = match what {
        Merged::Map => "map",
        Merged::Report => "report",
        Merged::Status => "status",
    };
    format!("slamkit/{fleet}/merged/{what}")
}

/// The robot and stream a key names.
///
/// # Errors
/// [`FleetError::Key`] for a key that is not a robot's message key.
pub fn parse(key: &str) -> Result<(String, Stream), FleetError> {
    let parts: Vec<&str> = key.split('/').collect();
    let stream = match parts.as_slice() {
        ["slamkit", _, _, "keyframes", _] => Stream::Keyframes,
        ["slamkit", _, _, "edges", _] => Stream::Edges,
        ["slamkit", _, _, "status"] => Stream::Status,
        _ => return Err(FleetError::Key(key.to_string())),
    };
    Ok((parts[2].to_string(), stream))
}

/// Checks that a fleet or robot name can stand in a key (no `/`, `*`, `$`, `?`, `#`, not
/// empty, not `merged`).
///
/// # Errors
/// [`FleetError::Name`] naming the problem.
pub fn check_name(name: &str) -> Result<(), FleetError> {
    let bad = name.is_empty()
        || name == "merged"
        || name
            .chars()
            .any(|c| "/*$?#".contains(c) || c.is_whitespace());
    if bad {
        return Err(FleetError::Name(name.to_string()));
    }
    Ok(())
}
