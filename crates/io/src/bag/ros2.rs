//! A ROS 2 bag: a folder holding `metadata.yaml` and one or more storage files (MCAP or
//! SQLite `.db3`, [`super::mcap_file`], [`super::sqlite_file`]), or one storage file alone.
//! The files are read in the order `metadata.yaml` lists them (`relative_file_paths`; by name
//! without it), their topics merged by name and type. Messages compressed one by one
//! (rosbag2's `compression_mode: message`, zstd) are decompressed before decoding; a bag
//! compressed file by file is refused with the way to decompress it.

use super::chunk::Compression;
use super::connection::Connection;
use super::info::{BagFormat, BagInfo, TopicInfo};
use super::mcap_file::McapFile;
use super::reader::{Connections, IndexState, MessageRecord, ReadStats};
use super::record::RosTime;
use super::source::MessageSource;
use super::sqlite_file::SqliteFile;
use super::BagError;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// Messages of one connection and their time span.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConnectionCounts {
    /// Messages.
    pub messages: usize,
    /// Earliest time.
    pub start: RosTime,
    /// Latest time.
    pub end: RosTime,
}

/// What one storage file holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FileCounts {
    /// Per connection id of the file.
    pub per_connection: Vec<(u32, ConnectionCounts)>,
    /// Chunks (MCAP).
    pub chunks: usize,
    /// Chunk compressions.
    pub compressions: Vec<Compression>,
    /// What a walk went through, when the counts needed one.
    pub walk: Option<ReadStats>,
}

/// One storage file.
#[derive(Debug)]
enum Storage {
    Mcap(Box<McapFile>),
    Sqlite(SqliteFile),
}

impl Storage {
    fn open(path: &Path) -> Result<Self, BagError> {
        let name = path.display().to_string();
        let mut head = [0u8; 16];
        let got = {
            use std::io::Read;
            std::fs::File::open(path)
                .and_then(|f| f.take(16).read(&mut head))
                .map_err(|error| BagError::Open {
                    file: name.clone(),
                    error,
                })?
        };
        let head = &head[..got];
        if head.starts_with(b"\x89MCAP") {
            Ok(Self::Mcap(Box::new(McapFile::open(path)?)))
        } else if head.starts_with(b"SQLite format 3\0") {
            Ok(Self::Sqlite(SqliteFile::open(path)?))
        } else if head.starts_with(&[0x28, 0xb5, 0x2f, 0xfd]) {
            Err(BagError::Storage {
                file: name,
                what: "compressed as a whole (zstd); decompress it first \
                       (`ros2 bag decompress`, or `zstd -d` and edit metadata.yaml)"
                    .into(),
            })
        } else {
            Err(BagError::NotABag {
                file: name,
                what: "neither MCAP nor SQLite".into(),
            })
        }
    }

    fn connections(&self) -> &Connections {
        match self {
            Self::Mcap(f) => f.connections(),
            Self::Sqlite(f) => f.connections(),
        }
    }

    fn index_state(&self) -> &IndexState {
        match self {
            Self::Mcap(f) => f.index_state(),
            Self::Sqlite(f) => f.index_state(),
        }
    }

    fn read(
        &mut self,
        each: &mut dyn FnMut(&Connection, &MessageRecord),
    ) -> Result<ReadStats, BagError> {
        match self {
            Self::Mcap(f) => f.read(each),
            Self::Sqlite(f) => f.read(each),
        }
    }

    fn counts(&mut self) -> Result<FileCounts, BagError> {
        match self {
            Self::Mcap(f) => f.counts(),
            Self::Sqlite(f) => f.counts(),
        }
    }
}

/// An open ROS 2 bag.
#[derive(Debug)]
pub struct Ros2Bag {
    name: String,
    files: Vec<Storage>,
    /// Global connections (ids are positions in the merged table).
    connections: Connections,
    /// (file, the file's connection id) → global id.
    ids: HashMap<(usize, u32), u32>,
    index: IndexState,
}

impl Ros2Bag {
    /// Opens a bag folder or one storage file.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let name = path.display().to_string();
        let paths = if path.is_dir() {
            storage_files(path)?
        } else {
            vec![path.to_path_buf()]
        };
        let files = paths
            .iter()
            .map(|p| Storage::open(p))
            .collect::<Result<Vec<_>, _>>()?;
        let mut bag = Self {
            name,
            files,
            connections: Connections::new(),
            ids: HashMap::new(),
            index: IndexState::Indexed,
        };
        bag.index = bag
            .files
            .iter()
            .map(Storage::index_state)
            .find(|s| **s != IndexState::Indexed)
            .cloned()
            .unwrap_or(IndexState::Indexed);
        bag.merge_connections();
        Ok(bag)
    }

    fn merge_connections(&mut self) {
        let mut by_key: HashMap<(String, String), u32> = self
            .connections
            .values()
            .map(|c| ((c.topic.clone(), c.message_type.clone()), c.id))
            .collect();
        for (i, file) in self.files.iter().enumerate() {
            for conn in file.connections().values() {
                if self.ids.contains_key(&(i, conn.id)) {
                    continue;
                }
                let key = (conn.topic.clone(), conn.message_type.clone());
                let next = self.connections.len() as u32;
                let id = *by_key.entry(key).or_insert(next);
                if id == next {
                    self.connections
                        .insert(id, Connection { id, ..conn.clone() });
                }
                self.ids.insert((i, conn.id), id);
            }
        }
    }
}

/// The storage files of a bag folder, in the order `metadata.yaml` gives.
fn storage_files(dir: &Path) -> Result<Vec<PathBuf>, BagError> {
    let meta = dir.join("metadata.yaml");
    let listed = std::fs::read_to_string(&meta)
        .map(|text| relative_file_paths(&text))
        .unwrap_or_default();
    let files: Vec<PathBuf> = if listed.is_empty() {
        let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|error| BagError::Open {
                file: dir.display().to_string(),
                error,
            })?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                let n = p.to_string_lossy();
                [".mcap", ".db3", ".mcap.zstd", ".db3.zstd"]
                    .iter()
                    .any(|ext| n.ends_with(ext))
            })
            .collect();
        found.sort();
        found
    } else {
        listed.iter().map(|f| dir.join(f)).collect()
    };
    if files.is_empty() {
        return Err(BagError::NotABag {
            file: dir.display().to_string(),
            what: "a folder with no .mcap or .db3 storage file (not a ROS 2 bag)".into(),
        });
    }
    Ok(files)
}

/// The `relative_file_paths` list of a rosbag2 `metadata.yaml` (a block list of scalars).
fn relative_file_paths(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut inside: Option<usize> = None;
    for line in text.lines() {
        let indent = line.len() - line.trim_start().len();
        let t = line.trim();
        if let Some(key_indent) = inside {
            if let Some(item) = t.strip_prefix("- ") {
                if indent >= key_indent {
                    out.push(item.trim().trim_matches(['\'', '"']).to_string());
                    continue;
                }
            }
            if !t.is_empty() {
                inside = None;
            }
        }
        if t == "relative_file_paths:" {
            inside = Some(indent);
        }
    }
    out
}

/// A message's bytes: zstd-compressed messages (rosbag2's per-message compression)
/// decompressed, bounded.
fn message_bytes(data: &[u8]) -> Result<std::borrow::Cow<'_, [u8]>, String> {
    use std::io::Read;
    if !data.starts_with(&[0x28, 0xb5, 0x2f, 0xfd]) {
        return Ok(std::borrow::Cow::Borrowed(data));
    }
    let decoder =
        ruzstd::decoding::StreamingDecoder::new(data).map_err(|e| format!("zstd: {e}"))?;
    let mut out = Vec::new();
    decoder
        .take(1 << 30)
        .read_to_end(&mut out)
        .map_err(|e| format!("zstd: {e}"))?;
    Ok(std::borrow::Cow::Owned(out))
}

impl MessageSource for Ros2Bag {
    fn bag_name(&self) -> &str {
        &self.name
    }

    fn topics(&self) -> &Connections {
        &self.connections
    }

    fn index(&self) -> &IndexState {
        &self.index
    }

    fn find_connections(&mut self) -> Result<(), BagError> {
        if self.files.iter().all(|f| !f.connections().is_empty()) {
            return Ok(());
        }
        for f in &mut self.files {
            if f.connections().is_empty() {
                f.read(&mut |_, _| {})?;
            }
        }
        self.merge_connections();
        Ok(())
    }

    fn read_stored(
        &mut self,
        visit: &mut dyn FnMut(&Connection, &MessageRecord),
    ) -> Result<ReadStats, BagError> {
        let mut total = ReadStats::default();
        for i in 0..self.files.len() {
            let mut pending: Vec<(Connection, RosTime, Vec<u8>)> = Vec::new();
            let ids = &self.ids;
            let globals = &self.connections;
            let mut unknown = Vec::new();
            let stats = self.files[i].read(&mut |conn, msg| {
                match ids.get(&(i, conn.id)).and_then(|g| globals.get(g)) {
                    Some(global) => {
                        // an undecompressible message goes on as it is, and fails to decode
                        let bytes =
                            message_bytes(msg.data).unwrap_or(std::borrow::Cow::Borrowed(msg.data));
                        visit(
                            global,
                            &MessageRecord {
                                conn: global.id,
                                time: msg.time,
                                data: &bytes,
                            },
                        );
                    }
                    // a channel first met in this walk (an unindexed MCAP): kept for later
                    None => {
                        unknown.push(conn.id);
                        pending.push((conn.clone(), msg.time, msg.data.to_vec()));
                    }
                }
            })?;
            if !unknown.is_empty() {
                self.merge_connections();
                for (conn, time, data) in pending {
                    if let Some(global) = self
                        .ids
                        .get(&(i, conn.id))
                        .and_then(|g| self.connections.get(g))
                    {
                        let bytes =
                            message_bytes(&data).unwrap_or(std::borrow::Cow::Borrowed(&data));
                        visit(
                            global,
                            &MessageRecord {
                                conn: global.id,
                                time,
                                data: &bytes,
                            },
                        );
                    }
                }
            }
            total.messages += stats.messages;
            total.chunks += stats.chunks;
            total.orphan_messages += stats.orphan_messages;
            total.damaged_chunks.extend(stats.damaged_chunks);
            if total.truncated.is_none() {
                total.truncated = stats.truncated;
            }
            for c in stats.compressions {
                if !total.compressions.contains(&c) {
                    total.compressions.push(c);
                }
            }
        }
        Ok(total)
    }

    fn summary(&mut self) -> Result<BagInfo, BagError> {
        self.find_connections()?;
        let mut per: BTreeMap<u32, ConnectionCounts> = BTreeMap::new();
        let (mut chunks, mut compression, mut walk) = (0, Vec::new(), None::<ReadStats>);
        let mut format = None;
        for i in 0..self.files.len() {
            format.get_or_insert(match self.files[i] {
                Storage::Mcap(_) => BagFormat::Mcap,
                Storage::Sqlite(_) => BagFormat::Sqlite3,
            });
            let counts = self.files[i].counts()?;
            for (local, c) in counts.per_connection {
                let Some(&g) = self.ids.get(&(i, local)) else {
                    continue;
                };
                per.entry(g)
                    .and_modify(|e| {
                        e.messages += c.messages;
                        e.start = e.start.min(c.start);
                        e.end = e.end.max(c.end);
                    })
                    .or_insert(c);
            }
            chunks += counts.chunks;
            for c in counts.compressions {
                if !compression.contains(&c) {
                    compression.push(c);
                }
            }
            if let Some(w) = counts.walk {
                walk.get_or_insert_with(ReadStats::default)
                    .damaged_chunks
                    .extend(w.damaged_chunks);
                if let Some(t) = w.truncated {
                    walk.get_or_insert_with(ReadStats::default).truncated = Some(t);
                }
            }
        }
        let mut topics: BTreeMap<String, TopicInfo> = BTreeMap::new();
        for conn in self.connections.values() {
            let count = per.get(&conn.id).map_or(0, |c| c.messages);
            let t = topics
                .entry(conn.topic.clone())
                .or_insert_with(|| TopicInfo {
                    topic: conn.topic.clone(),
                    message_type: conn.message_type.clone(),
                    md5sum: String::new(),
                    messages: 0,
                    connections: 0,
                    latching: false,
                });
            t.messages += count;
            t.connections += 1;
        }
        let counted = per.values().filter(|c| c.messages > 0);
        Ok(BagInfo {
            file: self.name.clone(),
            format: format.unwrap_or(BagFormat::Mcap),
            index: self.index.clone(),
            messages: per.values().map(|c| c.messages).sum(),
            topics: topics.into_values().collect(),
            start_s: counted
                .clone()
                .map(|c| c.start)
                .min()
                .map(RosTime::as_secs_f64),
            end_s: counted.map(|c| c.end).max().map(RosTime::as_secs_f64),
            chunks,
            compression,
            walk,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metadata_lists_files_in_order() {
        let text = "rosbag2_bagfile_information:\n  compression_format: ''\n  files:\n  - path: a.mcap\n  \
                    relative_file_paths:\n  - run_0.mcap\n  - 'run_1.mcap'\n  ros_distro: rosbags\n";
        assert_eq!(relative_file_paths(text), ["run_0.mcap", "run_1.mcap"]);
        assert!(relative_file_paths("version: 9\n").is_empty());
    }
}
