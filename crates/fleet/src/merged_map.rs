//! [`MergedMapInbox`]: a robot's copy of its fleet's merged map. It subscribes to the merged
//! map and the merger's status (`slamkit/<fleet>/merged/{map,status}`), keeps the newest map
//! (by its Zenoh timestamp) in a file written atomically, where the robot's tools read it
//! (`slamkit lidar --localize`, `slamkit plan --map`). It asks for the map by query as soon as
//! the merger's queryable is in reach (a robot that joins late, or is restarted, gets the
//! latest at once), and again when a status names a newer map than it holds (it missed the
//! publication): within a second of the merger's next status.

use crate::keys::{check_name, merged_key, Merged};
use crate::FleetError;
use serde::Serialize;
use slamkit_slam::lidar::LidarMap;
use slamkit_slam::map_file::{write_atomically, MapFile};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::time::{Duration, Instant};
use zenoh::sample::Sample;
use zenoh::time::Timestamp;
use zenoh::Wait;

/// How long a query for the merged map waits for its answer; no new query goes out before.
const QUERY_TIMEOUT: Duration = Duration::from_secs(2);

/// What a robot took of the merged map and the merger's status.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct MergedReceipts {
    /// Merged maps taken (published and fetched, older ones included).
    pub maps: usize,
    /// Of those, the answers to the robot's queries.
    pub fetched: usize,
    /// Of those, the ones newer than the map held, written to the file.
    pub kept: usize,
    /// Their bytes, keys included.
    pub map_bytes: usize,
    /// The merger's statuses taken.
    pub statuses: usize,
    /// Their bytes, keys included.
    pub status_bytes: usize,
    /// Maps and statuses that could not be read (not a 2D lidar map, no timestamp).
    pub rejected: usize,
    /// Queries sent for the merged map.
    pub queries: usize,
    /// Keyframes of the map held.
    pub keyframes: usize,
}

/// A map or status that arrived, and whether it answered a query.
type Arrival = (Sample, bool);

/// The robot's side of the merged map.
pub struct MergedMapInbox {
    _session: zenoh::Session,
    querier: zenoh::query::Querier<'static>,
    /// Whether the first query went out (once the merger's queryable was in reach).
    asked_first: bool,
    fleet: String,
    path: PathBuf,
    sender: Sender<Arrival>,
    arrivals: Receiver<Arrival>,
    _subscribers: [zenoh::pubsub::Subscriber<()>; 2],
    newest: Option<Timestamp>,
    asked: Option<Instant>,
    receipts: MergedReceipts,
}

impl MergedMapInbox {
    /// Subscribes on `session` to `fleet`'s merged map and status; the newest map will be kept
    /// at `path`.
    ///
    /// # Errors
    /// [`FleetError::Name`] for a fleet name that cannot stand in a key, [`FleetError::Zenoh`]
    /// when a subscriber cannot be declared.
    pub fn new(session: zenoh::Session, fleet: &str, path: &Path) -> Result<Self, FleetError> {
        check_name(fleet)?;
        let (sender, arrivals) = channel();
        let (subscribers, querier) = declare(&session, fleet, &sender)?;
        Ok(Self {
            _session: session,
            querier,
            asked_first: false,
            fleet: fleet.to_string(),
            path: path.to_path_buf(),
            sender,
            arrivals,
            _subscribers: subscribers,
            newest: None,
            asked: None,
            receipts: MergedReceipts::default(),
        })
    }

    /// Listens again on `session` (a new one, after the robot's old session was closed: it
    /// left the network) and asks for the merged map once the merger is in reach, so a map
    /// published while the robot was away comes to it.
    ///
    /// # Errors
    /// [`FleetError::Zenoh`] when a subscriber cannot be declared.
    pub fn reconnect(&mut self, session: zenoh::Session) -> Result<(), FleetError> {
        (self._subscribers, self.querier) = declare(&session, &self.fleet, &self.sender)?;
        self._session = session;
        (self.asked_first, self.asked) = (false, None);
        Ok(())
    }

    /// Takes what arrived: writes a map newer than the one held to the file, and asks for the
    /// map when the merger first comes in reach or a status names a newer one. Returns how
    /// many maps it wrote.
    ///
    /// # Errors
    /// [`FleetError::Store`] when the file cannot be written, [`FleetError::Zenoh`] when a
    /// query cannot be sent.
    pub fn poll(&mut self) -> Result<usize, FleetError> {
        if !self.asked_first {
            let in_reach = self.querier.matching_status().wait().map(|m| m.matching());
            if in_reach.map_err(FleetError::zenoh)? {
                self.asked_first = true;
                self.ask()?;
            }
        }
        let mut written = 0;
        while let Ok((sample, fetched)) = self.arrivals.try_recv() {
            let key = sample.key_expr().as_str();
            let bytes = sample.payload().to_bytes();
            if key == merged_key(&self.fleet, Merged::Status) {
                self.receipts.statuses += 1;
                self.receipts.status_bytes += key.len() + bytes.len();
                match std::str::from_utf8(&bytes)
                    .ok()
                    .map(str::parse::<Timestamp>)
                {
                    Some(Ok(stamp)) if self.newest.map_or(true, |n| n < stamp) => self.ask()?,
                    Some(Ok(_)) => {}
                    _ => self.receipts.rejected += 1,
                }
                continue;
            }
            self.receipts.maps += 1;
            self.receipts.fetched += usize::from(fetched);
            self.receipts.map_bytes += key.len() + bytes.len();
            let Some(stamp) = sample.timestamp().copied() else {
                self.receipts.rejected += 1;
                continue;
            };
            if self.newest.is_some_and(|n| n >= stamp) {
                continue;
            }
            let Ok(map) = MapFile::from_bytes(&bytes).and_then(|f| LidarMap::from_file(&f)) else {
                self.receipts.rejected += 1;
                continue;
            };
            write_atomically(&self.path, &bytes).map_err(|source| FleetError::Store {
                path: self.path.clone(),
                source,
            })?;
            self.newest = Some(stamp);
            self.receipts.kept += 1;
            self.receipts.keyframes = map.keyframes.len();
            written += 1;
        }
        Ok(written)
    }

    /// Asks for the merged map, unless a query is still waiting for its answer.
    fn ask(&mut self) -> Result<(), FleetError> {
        if self.asked.is_some_and(|t| t.elapsed() < QUERY_TIMEOUT) {
            return Ok(());
        }
        let sender = self.sender.clone();
        self.querier
            .get()
            .callback(move |reply| {
                if let Ok(sample) = reply.result() {
                    let _ = sender.send((sample.clone(), true));
                }
            })
            .wait()
            .map_err(FleetError::zenoh)?;
        self.asked = Some(Instant::now());
        self.receipts.queries += 1;
        Ok(())
    }

    /// What it took so far.
    pub fn receipts(&self) -> MergedReceipts {
        self.receipts
    }

    /// The file the newest merged map is kept in.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The Zenoh timestamp of the map held.
    pub fn newest(&self) -> Option<Timestamp> {
        self.newest
    }
}

/// Declares on `session` the subscribers to `fleet`'s merged map and status, which hand what
/// comes to `sender`, and the querier for the map.
fn declare(
    session: &zenoh::Session,
    fleet: &str,
    sender: &Sender<Arrival>,
) -> Result<
    (
        [zenoh::pubsub::Subscriber<()>; 2],
        zenoh::query::Querier<'static>,
    ),
    FleetError,
> {
    let subscribe = |what| {
        let sender = sender.clone();
        session
            .declare_subscriber(merged_key(fleet, what))
            .callback(move |sample| {
                // the receiver is gone only once the inbox is dropped
                let _ = sender.send((sample, false));
            })
            .wait()
            .map_err(FleetError::zenoh)
    };
    let subscribers = [subscribe(Merged::Map)?, subscribe(Merged::Status)?];
    let querier = session
        .declare_querier(merged_key(fleet, Merged::Map))
        .timeout(QUERY_TIMEOUT)
        .wait()
        .map_err(FleetError::zenoh)?;
    Ok((subscribers, querier))
}
