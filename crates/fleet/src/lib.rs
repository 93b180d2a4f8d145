//! slamkit-fleet: many robots, one map. Each robot publishes its map updates
//! ([`slamkit_slam::map_updates`]) on Zenoh and answers queries for the ones a peer missed; a
//! merger collects every robot's updates, fetches what it lacks by sequence number, and merges
//! the robots' maps ([`slamkit_slam::merge`]) (issue 22, item 2).
//!
//! * [`keys`]: the key expressions, `slamkit/<fleet>/<robot>/{keyframes,edges,status}`.
//! * [`peer`]: opening a Zenoh peer on explicit endpoints, multicast scouting off.
//! * [`robot`]: [`RobotPublisher`], one robot's side: publish, keep, answer queries.
//! * [`merger`]: [`Merger`], the receiving side: subscribe, fetch what is missing, merge.
//!
//! All networking is Zenoh's (pub/sub and queries over its TCP transport); nothing here opens
//! a socket itself. Nothing here prints.

pub mod keys;
pub mod merger;
pub mod peer;
pub mod robot;

pub use merger::Merger;
pub use peer::PeerConfig;
pub use robot::RobotPublisher;

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
