//! [`RobotPublisher`]: one robot's side of the fleet. It publishes each map update on its key,
//! keeps every keyframes and edges message it made, and answers a query for any of them by
//! sequence number, so a peer that missed some (a dropped packet, a reconnect, a late start)
//! fetches them: nothing is lost while the robot runs.

use crate::keys::{check_name, key_of, robot_keys};
use crate::FleetError;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slamkit_slam::map_updates::{MapUpdate, Stream};
use std::sync::{Arc, Mutex};
use zenoh::Wait;

/// The query parameter listing the sequence numbers wanted, comma-separated:
/// `slamkit/<fleet>/<robot>/**?seqs=3,5,9`.
pub const SEQS_PARAMETER: &str = "seqs";

/// Messages kept for queries: key and bytes, by sequence number.
type Store = Arc<Mutex<Vec<(String, Vec<u8>)>>>;

/// Publishes one robot's map updates and answers queries for them.
pub struct RobotPublisher {
    session: zenoh::Session,
    fleet: String,
    robot: String,
    store: Store,
    _queryable: zenoh::query::Queryable<()>,
    /// Fraction of publications dropped on purpose (tests), and the draws.
    loss: Option<(f64, ChaCha8Rng)>,
    sent_bytes: usize,
    dropped: usize,
}

impl RobotPublisher {
    /// A publisher for `robot` of `fleet` on `session`, its queryable declared.
    ///
    /// # Errors
    /// [`FleetError::Name`] for a name that cannot stand in a key, [`FleetError::Zenoh`] when
    /// the queryable cannot be declared.
    pub fn new(session: zenoh::Session, fleet: &str, robot: &str) -> Result<Self, FleetError> {
        check_name(fleet)?;
        check_name(robot)?;
        let store: Store = Arc::default();
        let served = Arc::clone(&store);
        let queryable = session
            .declare_queryable(robot_keys(fleet, robot))
            .callback(move |query| {
                let wanted = query
                    .parameters()
                    .get(SEQS_PARAMETER)
                    .map(parse_seqs)
                    .unwrap_or_default();
                let replies: Vec<(String, Vec<u8>)> = match served.lock() {
                    Ok(store) => wanted
                        .iter()
                        .filter_map(|s| store.get(usize::try_from(*s).ok()?).cloned())
                        .collect(),
                    Err(_) => Vec::new(),
                };
                for (key, bytes) in replies {
                    // a reply that cannot go out is asked for again by the next query
                    let _ = query.reply(key, bytes).wait();
                }
            })
            .wait()
            .map_err(FleetError::zenoh)?;
        Ok(Self {
            session,
            fleet: fleet.to_string(),
            robot: robot.to_string(),
            store,
            _queryable: queryable,
            loss: None,
            sent_bytes: 0,
            dropped: 0,
        })
    }

    /// Drops a fraction `p` of publications (the messages are still kept and served to
    /// queries), drawn with `seed`: lossy Wi-Fi in tests.
    pub fn with_loss(mut self, p: f64, seed: u64) -> Self {
        self.loss = Some((p, ChaCha8Rng::seed_from_u64(seed)));
        self
    }

    /// Publishes `update` (a keyframes or edges message is kept for queries first).
    ///
    /// # Errors
    /// [`FleetError::Message`] for an update that cannot be encoded or is out of sequence,
    /// [`FleetError::Zenoh`] when Zenoh refuses the publication.
    pub fn publish(&mut self, update: &MapUpdate) -> Result<(), FleetError> {
        let key = key_of(&self.fleet, &self.robot, update);
        let bytes = update.to_bytes().map_err(|source| FleetError::Message {
            key: key.clone(),
            source,
        })?;
        if update.stream() != Stream::Status {
            let mut store = self
                .store
                .lock()
                .map_err(|_| FleetError::Zenoh("the message store was poisoned".into()))?;
            if update.seq != store.len() as u64 {
                return Err(FleetError::Message {
                    key,
                    source: slamkit_slam::map_file::MapFileError::Malformed(format!(
                        "sequence number {} after {} messages",
                        update.seq,
                        store.len()
                    )),
                });
            }
            store.push((key.clone(), bytes.clone()));
        }
        if let Some((p, rng)) = &mut self.loss {
            if rng.gen::<f64>() < *p {
                self.dropped += 1;
                return Ok(());
            }
        }
        self.sent_bytes += bytes.len() + key.len();
        self.session
            .put(key, bytes)
            .wait()
            .map_err(FleetError::zenoh)
    }

    /// Bytes published (messages and their keys; not the answers to queries).
    pub fn sent_bytes(&self) -> usize {
        self.sent_bytes
    }

    /// Publications dropped on purpose.
    pub fn dropped(&self) -> usize {
        self.dropped
    }
}

/// The sequence numbers of a `seqs` parameter; what does not parse is left out.
///
/// ```
/// assert_eq!(slamkit_fleet::robot::parse_seqs("3,5,x,9"), [3, 5, 9]);
/// ```
pub fn parse_seqs(list: &str) -> Vec<u64> {
    list.split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect()
}
