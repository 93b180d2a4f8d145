//! [`RobotPublisher`]: one robot's side of the fleet. It publishes each map update on its key,
//! keeps every keyframes and edges message it made (in memory, and in a [`StoreFile`] when
//! given one, so a restarted robot process still has them), and answers a query for any of
//! them by sequence number, or for its latest status, so a peer that missed some (a dropped
//! packet, a reconnect, a late start, a restarted merger) fetches them: nothing sent is lost.

use crate::keys::{check_name, key_of, robot_keys};
use crate::store::StoreFile;
use crate::FleetError;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slamkit_slam::map_updates::{MapUpdate, Stream};
use std::path::Path;
use std::sync::{Arc, Mutex};
use zenoh::Wait;

/// The query parameter listing the sequence numbers wanted, comma-separated:
/// `slamkit/<fleet>/<robot>/**?seqs=3,5,9`.
pub const SEQS_PARAMETER: &str = "seqs";
/// The query parameter asking for a robot's latest status: `slamkit/<fleet>/*/**?status`.
pub const STATUS_PARAMETER: &str = "status";

/// What a robot serves to queries: its messages (key and bytes, by sequence number) and its
/// latest status.
#[derive(Default)]
struct Served {
    messages: Vec<(String, Vec<u8>)>,
    status: Option<(String, Vec<u8>)>,
}

type Store = Arc<Mutex<Served>>;

/// Publishes one robot's map updates and answers queries for them.
pub struct RobotPublisher {
    session: zenoh::Session,
    fleet: String,
    robot: String,
    store: Store,
    file: Option<StoreFile>,
    _queryable: zenoh::query::Queryable<()>,
    /// Fraction of publications dropped on purpose (tests), and the draws.
    loss: Option<(f64, ChaCha8Rng)>,
    sent_bytes: usize,
    sent_messages: usize,
    dropped: usize,
    /// Whether the session is open ([`RobotPublisher::disconnect`]).
    online: bool,
    held_back: usize,
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
        let queryable = answer_queries(&session, fleet, robot, &store)?;
        Ok(Self {
            session,
            fleet: fleet.to_string(),
            robot: robot.to_string(),
            store,
            file: None,
            _queryable: queryable,
            loss: None,
            sent_bytes: 0,
            sent_messages: 0,
            dropped: 0,
            online: true,
            held_back: 0,
        })
    }

    /// Leaves the network: closes the Zenoh session (its queryable goes with it), so peers
    /// neither hear from it nor reach it; what [`publish`](Self::publish) is given meanwhile
    /// is kept and stored but not sent (a robot out of Wi-Fi range).
    ///
    /// # Errors
    /// [`FleetError::Zenoh`] when the session cannot be closed.
    pub fn disconnect(&mut self) -> Result<(), FleetError> {
        self.online = false;
        self.session.close().wait().map_err(FleetError::zenoh)
    }

    /// Joins the network again on `session` (a new one: a closed session cannot reopen) and
    /// answers queries for every message kept, those made while away included: peers fetch
    /// what they missed.
    ///
    /// # Errors
    /// [`FleetError::Zenoh`] when the queryable cannot be declared.
    pub fn reconnect(&mut self, session: zenoh::Session) -> Result<(), FleetError> {
        self._queryable = answer_queries(&session, &self.fleet, &self.robot, &self.store)?;
        self.session = session;
        self.online = true;
        Ok(())
    }

    /// Whether it is on the network (not [`disconnect`](Self::disconnect)ed).
    pub fn online(&self) -> bool {
        self.online
    }

    /// Messages kept but not sent because the robot was disconnected.
    pub fn held_back(&self) -> usize {
        self.held_back
    }

    /// Drops a fraction `p` of publications (the messages are still kept and served to
    /// queries), drawn with `seed`: lossy Wi-Fi in tests.
    pub fn with_loss(mut self, p: f64, seed: u64) -> Self {
        self.loss = Some((p, ChaCha8Rng::seed_from_u64(seed)));
        self
    }

    /// Keeps every message in the store file at `path` too, and serves the messages it
    /// already holds (those of this robot's run before a restart): [`publish`](Self::publish)
    /// then skips the messages up to [`stored`](Self::stored) and publishes from there on.
    ///
    /// # Errors
    /// [`FleetError::Store`] when the file cannot be read, [`FleetError::Message`] for a record
    /// that is not a message of this robot's sequence.
    pub fn with_store_file(mut self, path: &Path) -> Result<Self, FleetError> {
        let (file, held) = StoreFile::open(path)?;
        let mut messages = Vec::with_capacity(held.len());
        for (i, bytes) in held.into_iter().enumerate() {
            let wrong = |source| FleetError::Message {
                key: format!("{} record {i}", path.display()),
                source,
            };
            let update = MapUpdate::from_bytes(&bytes).map_err(wrong)?;
            if update.seq != i as u64 || update.stream() == Stream::Status {
                return Err(wrong(malformed(format!(
                    "a {} message numbered {} in place {i}",
                    update.stream().name(),
                    update.seq
                ))));
            }
            messages.push((key_of(&self.fleet, &self.robot, &update), bytes));
        }
        self.lock()?.messages = messages;
        self.file = Some(file);
        Ok(self)
    }

    /// Publishes `update`; returns whether it was new. A keyframes or edges message is kept
    /// (and stored, with a store file) before it goes out; one the robot had sent before a
    /// restart must be the same as then, and is not sent again.
    ///
    /// # Errors
    /// [`FleetError::Message`] for an update that cannot be encoded, is out of sequence, or
    /// differs from the one of its number sent before a restart (another log or other
    /// settings); [`FleetError::Store`] when it cannot be stored; [`FleetError::Zenoh`] when
    /// Zenoh refuses the publication.
    pub fn publish(&mut self, update: &MapUpdate) -> Result<bool, FleetError> {
        let key = key_of(&self.fleet, &self.robot, update);
        let bytes = update.to_bytes().map_err(|source| FleetError::Message {
            key: key.clone(),
            source,
        })?;
        if update.stream() == Stream::Status {
            self.lock()?.status = Some((key.clone(), bytes.clone()));
        } else {
            let kept = self.lock()?.messages.len() as u64;
            if update.seq < kept {
                let same = self.lock()?.messages[update.seq as usize].1 == bytes;
                return if same {
                    Ok(false)
                } else {
                    Err(FleetError::Message {
                        key,
                        source: malformed(
                            "differs from the message of that number sent before the restart \
                             (another log or other settings)"
                                .into(),
                        ),
                    })
                };
            }
            if update.seq > kept {
                return Err(FleetError::Message {
                    key,
                    source: malformed(format!(
                        "sequence number {} after {kept} messages",
                        update.seq
                    )),
                });
            }
            if let Some(file) = &mut self.file {
                file.append(&bytes)?;
            }
            self.lock()?.messages.push((key.clone(), bytes.clone()));
        }
        if !self.online {
            self.held_back += usize::from(update.stream() != Stream::Status);
            return Ok(true);
        }
        if let Some((p, rng)) = &mut self.loss {
            if rng.gen::<f64>() < *p {
                self.dropped += 1;
                return Ok(true);
            }
        }
        self.sent_bytes += bytes.len() + key.len();
        self.sent_messages += 1;
        self.session
            .put(key, bytes)
            .timestamp(self.session.new_timestamp())
            .wait()
            .map_err(FleetError::zenoh)?;
        Ok(true)
    }

    /// Keyframes and edges messages kept (sent now or before a restart).
    pub fn stored(&self) -> u64 {
        self.store
            .lock()
            .map_or(0, |served| served.messages.len() as u64)
    }

    /// Bytes of the keyframes and edges messages kept, keys included: what the robot's map
    /// updates cost without loss, over its whole run (before and after a restart).
    pub fn stored_bytes(&self) -> usize {
        self.store.lock().map_or(0, |served| {
            served.messages.iter().map(|(k, b)| k.len() + b.len()).sum()
        })
    }

    /// Messages published (not counting the answers to queries and those dropped on purpose).
    pub fn sent_messages(&self) -> usize {
        self.sent_messages
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

impl RobotPublisher {
    fn lock(&self) -> Result<std::sync::MutexGuard<'_, Served>, FleetError> {
        self.store
            .lock()
            .map_err(|_| FleetError::Zenoh("the message store was poisoned".into()))
    }
}

/// Declares on `session` the queryable that answers `robot`'s messages in `store` by sequence
/// number, and its latest status.
fn answer_queries(
    session: &zenoh::Session,
    fleet: &str,
    robot: &str,
    store: &Store,
) -> Result<zenoh::query::Queryable<()>, FleetError> {
    let served = Arc::clone(store);
    session
        .declare_queryable(robot_keys(fleet, robot))
        .callback(move |query| {
            let parameters = query.parameters();
            let wanted = parameters
                .get(SEQS_PARAMETER)
                .map(parse_seqs)
                .unwrap_or_default();
            let with_status = parameters.contains_key(STATUS_PARAMETER);
            let replies: Vec<(String, Vec<u8>)> = match served.lock() {
                Ok(served) => wanted
                    .iter()
                    .filter_map(|s| served.messages.get(usize::try_from(*s).ok()?).cloned())
                    .chain(served.status.clone().filter(|_| with_status))
                    .collect(),
                Err(_) => Vec::new(),
            };
            for (key, bytes) in replies {
                // a reply that cannot go out is asked for again by the next query
                let _ = query.reply(key, bytes).wait();
            }
        })
        .wait()
        .map_err(FleetError::zenoh)
}

fn malformed(what: String) -> slamkit_slam::map_file::MapFileError {
    slamkit_slam::map_file::MapFileError::Malformed(what)
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
