//! What a bag holds, as `rosbag info` shows it: topics with their types and message counts,
//! the time span, chunks and compression; from the index when the bag has a readable one,
//! else by walking its chunks.

use super::chunk::Compression;
use super::reader::{count_by_connection, Bag, ConnectionSpan, IndexState, ReadStats};
use super::record::RosTime;
use super::BagError;
use std::collections::BTreeMap;
use std::io::{Read, Seek};

/// One topic of a bag.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct TopicInfo {
    /// Topic name.
    pub topic: String,
    /// Message type (of its first connection; see `types` when there are several).
    pub message_type: String,
    /// md5sum of the message type (ROS 1; empty for ROS 2).
    #[serde(skip_serializing_if = "String::is_empty")]
    pub md5sum: String,
    /// Messages on the topic.
    pub messages: usize,
    /// Connections (publishers) on the topic.
    pub connections: usize,
    /// True when latched (`/tf_static`).
    pub latching: bool,
}

/// The kind of bag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BagFormat {
    /// ROS 1 bag, format 2.0.
    Ros1,
    /// ROS 2 bag stored in MCAP.
    Mcap,
    /// ROS 2 bag stored in SQLite 3 (`.db3`).
    Sqlite3,
}

/// Summary of a bag.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BagInfo {
    /// The file (or ROS 2 bag folder).
    pub file: String,
    /// The kind of bag.
    pub format: BagFormat,
    /// The state of the index (counts come from it when it is `indexed`).
    pub index: IndexState,
    /// Topics, sorted by name.
    pub topics: Vec<TopicInfo>,
    /// Messages in all.
    pub messages: usize,
    /// Earliest record time \[s\] (`None` for a bag without messages).
    pub start_s: Option<f64>,
    /// Latest record time \[s\].
    pub end_s: Option<f64>,
    /// Chunks (none in a `.db3`).
    pub chunks: usize,
    /// Compression of the chunks (known after a walk only; empty when counted from the index).
    pub compression: Vec<Compression>,
    /// What a walk skipped (`None` when counted from the index).
    pub walk: Option<ReadStats>,
}

impl BagInfo {
    /// Latest minus earliest record time \[s\].
    pub fn duration_s(&self) -> Option<f64> {
        Some(self.end_s? - self.start_s?)
    }
}

/// Summarises `bag`: from its index when readable, else from a walk of its chunks.
pub fn bag_info<R: Read + Seek>(bag: &mut Bag<R>) -> Result<BagInfo, BagError> {
    let mut per_conn: BTreeMap<u32, ConnectionSpan> = BTreeMap::new();
    let (chunks, compression, walk) = if *bag.index_state() == IndexState::Indexed {
        for chunk in bag.chunk_infos() {
            for &(conn, count) in &chunk.counts {
                let e = per_conn.entry(conn).or_insert(ConnectionSpan {
                    messages: 0,
                    start: chunk.start,
                    end: chunk.end,
                });
                e.messages += count as usize;
                e.start = e.start.min(chunk.start);
                e.end = e.end.max(chunk.end);
            }
        }
        (bag.chunk_infos().len(), Vec::new(), None)
    } else {
        let (counts, stats) = count_by_connection(bag)?;
        per_conn.extend(counts);
        (stats.chunks, stats.compressions.clone(), Some(stats))
    };
    let mut topics: BTreeMap<String, TopicInfo> = BTreeMap::new();
    for conn in bag.connections().values() {
        let count = per_conn.get(&conn.id).map_or(0, |c| c.messages);
        let t = topics
            .entry(conn.topic.clone())
            .or_insert_with(|| TopicInfo {
                topic: conn.topic.clone(),
                message_type: conn.message_type.clone(),
                md5sum: conn.md5sum.clone(),
                messages: 0,
                connections: 0,
                latching: conn.latching,
            });
        t.messages += count;
        t.connections += 1;
    }
    let start = per_conn.values().map(|c| c.start).min();
    let end = per_conn.values().map(|c| c.end).max();
    Ok(BagInfo {
        file: bag.name().to_string(),
        format: BagFormat::Ros1,
        index: bag.index_state().clone(),
        messages: per_conn.values().map(|c| c.messages).sum(),
        topics: topics.into_values().collect(),
        start_s: start.map(RosTime::as_secs_f64),
        end_s: end.map(RosTime::as_secs_f64),
        chunks,
        compression,
        walk,
    })
}
