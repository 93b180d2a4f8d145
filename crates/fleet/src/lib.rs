//! slamkit-fleet: many robots, one map. Each robot publishes its map updates
//! ([`slamkit_slam::map_updates`]) on Zenoh and answers queries for the ones a peer missed; a
//! merger collects every robot's updates, fetches what it lacks by sequence number, merges the
//! robots' maps ([`slamkit_slam::merge`]) and sends the merged map back to every robot (issue
//! 22, items 2 to 4).
//!
//! * [`keys`]: the key expressions, `slamkit/<fleet>/<robot>/{keyframes,edges,status}` and
//!   `slamkit/<fleet>/merged/{map,report,status}`.
//! * [`peer`]: opening a Zenoh peer on explicit endpoints, multicast scouting off.
//! * [`robot`]: [`RobotPublisher`], one robot's side: publish, keep, answer queries.
//! * [`merger`]: [`Merger`], the receiving side: subscribe, fetch what is missing, merge.
//! * [`store`]: [`store::StoreFile`], a robot's messages on disk, so a restarted robot process
//!   resumes from its sequence numbers.
//! * [`merged_map`]: [`MergedMapInbox`], a robot's copy of the newest merged map, in a file it
//!   can localise and plan in, fetched by query when it joined late or missed it.
//! * [`robot_node`] and [`merger_node`]: a robot and the merger as processes run them
//!   (`slamkit fleet robot|merger`): a log played at a chosen rate, merges published on
//!   `slamkit/<fleet>/merged/{map,report,status}` and kept by every robot, the outputs and
//!   reports.
//!
//! All networking is Zenoh's (pub/sub and queries over its TCP transport); nothing here opens
//! a socket itself. Nothing here prints.

pub mod keys;
pub mod merged_map;
pub mod merger;
pub mod merger_node;
pub mod peer;
pub mod robot;
pub mod robot_node;
pub mod store;

pub use merged_map::MergedMapInbox;
pub use merger::Merger;
pub use merger_node::{MergerNode, MergerNodeConfig};
pub use peer::PeerConfig;
pub use robot::RobotPublisher;
pub use robot_node::{RobotNode, RobotNodeConfig};

/// Why a fleet operation failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FleetError {
    /// Zenoh refused (opening a session, publishing, declaring, querying).
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// A fleet or robot name that cannot stand in a key.
    #[error("name {0:?} cannot stand in a key (empty, `merged`, or holds / * $ ? # or a space)")]
    Name(String),
    /// A key that is not a fleet message's.
    #[error("key {0} is not a slamkit fleet message's")]
    Key(String),
    /// A message that could not be encoded or decoded.
    #[error("message on {key}: {source}")]
    Message {
        /// Its key.
        key: String,
        /// What was wrong.
        source: slamkit_slam::map_file::MapFileError,
    },
    /// A robot's store file could not be read or written.
    #[error("store {}: {source}", path.display())]
    Store {
        /// The file.
        path: std::path::PathBuf,
        /// What failed.
        source: std::io::Error,
    },
    /// The SLAM side refused (a message that does not fit the map, a merge).
    #[error(transparent)]
    Slam(#[from] slamkit_slam::SlamError),
}

impl FleetError {
    /// Wraps a Zenoh error.
    pub(crate) fn zenoh(e: impl std::fmt::Display) -> Self {
        FleetError::Zenoh(e.to_string())
    }
}
