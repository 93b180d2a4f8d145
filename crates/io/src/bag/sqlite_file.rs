//! One SQLite storage file (`.db3`) of a ROS 2 bag, read through `rusqlite` (SQLite's own C
//! source, built in): the `topics` table (name, type, serialisation), the
//! `message_definitions` table when the bag has one (rosbag2 since Iron), and the `messages`
//! table in insertion order (its `id`), which is the order the messages were written. The
//! file is opened read-only; a damaged database gives SQLite's error, naming the file.

use super::connection::Connection;
use super::reader::{Connections, IndexState, MessageRecord, ReadStats};
use super::record::RosTime;
use super::ros2::{ConnectionCounts, FileCounts};
use super::wire::Serialization;
use super::BagError;
use rusqlite::{Connection as Db, OpenFlags};
use std::collections::HashMap;
use std::path::Path;

/// An open `.db3` file.
#[derive(Debug)]
pub struct SqliteFile {
    name: String,
    db: Db,
    connections: Connections,
}

impl SqliteFile {
    /// Opens the database read-only and reads its topics.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let name = path.display().to_string();
        let db = Db::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(|e| sql_error(&name, e))?;
        let mut out = Self {
            name,
            db,
            connections: Connections::new(),
        };
        out.read_topics()?;
        Ok(out)
    }

    /// The file's name in errors.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Its topics.
    pub fn connections(&self) -> &Connections {
        &self.connections
    }

    /// A database is always indexed.
    pub fn index_state(&self) -> &IndexState {
        &IndexState::Indexed
    }

    fn read_topics(&mut self) -> Result<(), BagError> {
        let name = self.name.clone();
        let err = |e| sql_error(&name, e);
        let has_definitions: bool = self
            .db
            .query_row(
                "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = 'message_definitions'",
                [],
                |r| r.get::<_, i64>(0),
            )
            .map_err(err)?
            > 0;
        let mut definitions = HashMap::new();
        if has_definitions {
            let mut q = self
                .db
                .prepare("SELECT topic_type, encoding, encoded_message_definition FROM message_definitions")
                .map_err(err)?;
            let rows = q
                .query_map([], |r| {
                    Ok((
                        r.get::<_, String>(0)?,
                        r.get::<_, String>(1)?,
                        r.get::<_, String>(2)?,
                    ))
                })
                .map_err(err)?;
            for row in rows {
                let (ty, encoding, text) = row.map_err(err)?;
                if encoding == "ros2msg" {
                    definitions.insert(ty, text);
                }
            }
        }
        let mut q = self
            .db
            .prepare("SELECT id, name, type, serialization_format FROM topics")
            .map_err(err)?;
        let rows = q
            .query_map([], |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, String>(1)?,
                    r.get::<_, String>(2)?,
                    r.get::<_, String>(3)?,
                ))
            })
            .map_err(err)?;
        for row in rows {
            let (id, topic, ty, format) = row.map_err(err)?;
            let Ok(id) = u32::try_from(id) else {
                return Err(BagError::NotABag {
                    file: name.clone(),
                    what: format!("topic id {id} out of range"),
                });
            };
            self.connections.insert(
                id,
                Connection {
                    id,
                    topic,
                    message_definition: definitions.get(&ty).cloned().unwrap_or_default(),
                    message_type: ty,
                    md5sum: String::new(),
                    serialization: match format.as_str() {
                        "cdr" => Serialization::Cdr,
                        other => Serialization::Other(other.to_string()),
                    },
                    callerid: None,
                    latching: false,
                },
            );
        }
        Ok(())
    }

    /// Every message in insertion order.
    pub fn read(
        &mut self,
        each: &mut dyn FnMut(&Connection, &MessageRecord),
    ) -> Result<ReadStats, BagError> {
        let name = self.name.clone();
        let err = |e| sql_error(&name, e);
        let mut stats = ReadStats::default();
        let mut q = self
            .db
            .prepare("SELECT topic_id, timestamp, data FROM messages ORDER BY id")
            .map_err(err)?;
        let mut rows = q.query([]).map_err(err)?;
        while let Some(row) = rows.next().map_err(err)? {
            let (Ok(topic), Ok(ts), Ok(data)) = (
                row.get::<_, i64>(0),
                row.get::<_, i64>(1),
                row.get_ref(2).and_then(|v| v.as_blob().map_err(Into::into)),
            ) else {
                stats.orphan_messages += 1;
                continue;
            };
            let conn = u32::try_from(topic)
                .ok()
                .and_then(|id| self.connections.get(&id));
            match conn {
                Some(conn) => {
                    stats.messages += 1;
                    each(
                        conn,
                        &MessageRecord {
                            conn: conn.id,
                            time: stamp(ts),
                            data,
                        },
                    );
                }
                None => stats.orphan_messages += 1,
            }
        }
        Ok(stats)
    }

    /// Messages per topic with their time span, counted by SQLite.
    pub fn counts(&mut self) -> Result<FileCounts, BagError> {
        let name = self.name.clone();
        let err = |e| sql_error(&name, e);
        let mut q = self
            .db
            .prepare(
                "SELECT topic_id, count(*), min(timestamp), max(timestamp) FROM messages GROUP BY topic_id",
            )
            .map_err(err)?;
        let rows = q
            .query_map([], |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, i64>(1)?,
                    r.get::<_, i64>(2)?,
                    r.get::<_, i64>(3)?,
                ))
            })
            .map_err(err)?;
        let mut per_connection = Vec::new();
        for row in rows {
            let (id, n, start, end) = row.map_err(err)?;
            if let Ok(id) = u32::try_from(id) {
                per_connection.push((
                    id,
                    ConnectionCounts {
                        messages: usize::try_from(n).unwrap_or_default(),
                        start: stamp(start),
                        end: stamp(end),
                    },
                ));
            }
        }
        Ok(FileCounts {
            per_connection,
            chunks: 0,
            compressions: Vec::new(),
            walk: None,
        })
    }
}

/// A rosbag2 timestamp (nanoseconds since the epoch; negative ones clamp to 0).
fn stamp(ns: i64) -> RosTime {
    super::mcap_file::nanos_to_time(u64::try_from(ns).unwrap_or(0))
}

fn sql_error(file: &str, e: rusqlite::Error) -> BagError {
    BagError::Storage {
        file: file.to_string(),
        what: format!("not a readable rosbag2 SQLite database: {e}"),
    }
}
