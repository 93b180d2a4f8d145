//! One MCAP storage file of a ROS 2 bag, read through Foxglove's `mcap` crate: its summary
//! (channels, schemas, statistics) when the file has one, and its records streamed from
//! start to end. Chunks are decompressed here, not in the crate (whose zstd and lz4 are C
//! libraries): zstd through the pure-Rust `ruzstd`, lz4 frames through `lz4_flex`, each
//! bounded by the size the chunk declares and checked against the chunk's CRC.
//!
//! A file without a summary (a recording that was not closed) is walked instead; a chunk
//! that does not decompress or parse is skipped and counted; a file that ends inside a
//! record keeps what came before it (recorded as `truncated`); other damage to the record
//! framing stops the read with an error.

use super::chunk::{decompress_exact, Compression};
use super::connection::Connection;
use super::reader::{Connections, DamagedChunk, IndexState, MessageRecord, ReadStats};
use super::record::{RecordError, RosTime};
use super::ros2::{ConnectionCounts, FileCounts};
use super::wire::Serialization;
use super::BagError;
use mcap::records::Record;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use mcap::sans_io::{SummaryReadEvent, SummaryReader, SummaryReaderOptions};
use std::collections::HashMap;
use std::fs::File;
use std::io::{Read, Seek};
use std::path::Path;

/// Chunks larger than this once decompressed are refused (rosbag2 writes chunks of about
/// 1 MiB; a larger declared size is damage or a decompression bomb).
const MAX_CHUNK_BYTES: u64 = 1 << 30;

/// An open MCAP file.
#[derive(Debug)]
pub struct McapFile {
    path: std::path::PathBuf,
    name: String,
    len: u64,
    summary: Option<mcap::Summary>,
    index: IndexState,
    connections: Connections,
    schemas: HashMap<u16, (String, String)>,
}

impl McapFile {
    /// Opens the file and reads its summary, when it has one.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let name = path.display().to_string();
        let open_err = |error| BagError::Open {
            file: name.clone(),
            error,
        };
        let mut file = File::open(path).map_err(open_err)?;
        let len = file.metadata().map_err(open_err)?.len();
        let mut head = [0u8; 8];
        if file.read_exact(&mut head).is_err() || head != *mcap::MAGIC {
            return Err(BagError::NotABag {
                file: name,
                what: "no MCAP magic".into(),
            });
        }
        let (summary, index) = match read_summary(&mut file, len) {
            Ok(Some(s)) => (Some(s), IndexState::Indexed),
            Ok(None) => (None, IndexState::NotIndexed),
            Err(e) => (None, IndexState::Unreadable(e)),
        };
        let mut out = Self {
            path: path.to_path_buf(),
            name,
            len,
            summary: None,
            index,
            connections: Connections::new(),
            schemas: HashMap::new(),
        };
        if let Some(summary) = &summary {
            for (id, s) in &summary.schemas {
                out.schemas
                    .insert(*id, schema_text(&s.name, &s.encoding, &s.data));
            }
            for c in summary.channels.values() {
                out.add_channel(
                    c.id,
                    c.schema.as_ref().map(|s| s.id),
                    &c.topic,
                    &c.message_encoding,
                );
            }
        }
        out.summary = summary;
        Ok(out)
    }

    /// The file's name in errors.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Its connections (channels; complete once read or walked).
    pub fn connections(&self) -> &Connections {
        &self.connections
    }

    /// Whether it has a summary.
    pub fn index_state(&self) -> &IndexState {
        &self.index
    }

    fn add_channel(&mut self, id: u16, schema: Option<u16>, topic: &str, encoding: &str) {
        let (ty, definition) = schema
            .and_then(|s| self.schemas.get(&s).cloned())
            .unwrap_or_default();
        let serialization = match encoding {
            "cdr" => Serialization::Cdr,
            other => Serialization::Other(other.to_string()),
        };
        self.connections.entry(u32::from(id)).or_insert(Connection {
            id: u32::from(id),
            topic: topic.to_string(),
            message_type: ty,
            md5sum: String::new(),
            message_definition: definition,
            serialization,
            callerid: None,
            latching: false,
        });
    }

    /// Reads every record from start to end, handing each message to `each`.
    pub fn read(
        &mut self,
        each: &mut dyn FnMut(&Connection, &MessageRecord),
    ) -> Result<ReadStats, BagError> {
        let mut file = File::open(&self.path).map_err(|error| BagError::Open {
            file: self.name.clone(),
            error,
        })?;
        let options = LinearReaderOptions::default()
            .with_emit_chunks(true)
            .with_record_length_limit(MAX_CHUNK_BYTES as usize);
        let mut reader = LinearReader::new_with_options(options);
        let mut stats = ReadStats::default();
        let mut consumed = 0u64;
        while let Some(event) = reader.next_event() {
            match event {
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    let n = file
                        .read(reader.insert(need))
                        .map_err(|error| BagError::Open {
                            file: self.name.clone(),
                            error,
                        })?;
                    consumed += n as u64;
                    reader.notify_read(n);
                }
                Ok(LinearReadEvent::Record { opcode, data }) => {
                    let data = data.to_vec();
                    if opcode == mcap::records::op::CHUNK {
                        stats.chunks += 1;
                        if let Err(error) = self.chunk(&data, &mut stats, each) {
                            stats.damaged_chunks.push(DamagedChunk {
                                offset: consumed,
                                error,
                            });
                        }
                    } else {
                        self.record(opcode, &data, &mut stats, each)
                            .map_err(|e| self.damaged(consumed, e))?;
                    }
                }
                Err(mcap::McapError::UnexpectedEof) | Err(mcap::McapError::UnexpectedEoc) => {
                    stats.truncated = Some(DamagedChunk {
                        offset: consumed,
                        error: "the file ends inside a record".into(),
                    });
                    break;
                }
                Err(e) => return Err(self.damaged(consumed, e.to_string())),
            }
        }
        Ok(stats)
    }

    fn damaged(&self, offset: u64, what: String) -> BagError {
        BagError::Damaged {
            file: self.name.clone(),
            offset: offset.min(self.len),
            error: RecordError::Malformed(what),
        }
    }

    /// One record outside or inside a chunk.
    fn record(
        &mut self,
        opcode: u8,
        body: &[u8],
        stats: &mut ReadStats,
        each: &mut dyn FnMut(&Connection, &MessageRecord),
    ) -> Result<(), String> {
        match mcap::parse_record(opcode, body).map_err(|e| e.to_string())? {
            Record::Schema { header, data } => {
                let text = schema_text(&header.name, &header.encoding, &data);
                self.schemas.entry(header.id).or_insert(text);
            }
            Record::Channel(c) => {
                let schema = (c.schema_id != 0).then_some(c.schema_id);
                self.add_channel(c.id, schema, &c.topic, &c.message_encoding);
            }
            Record::Message { header, data } => {
                match self.connections.get(&u32::from(header.channel_id)) {
                    Some(conn) => {
                        stats.messages += 1;
                        each(
                            conn,
                            &MessageRecord {
                                conn: conn.id,
                                time: nanos_to_time(header.log_time),
                                data: &data,
                            },
                        );
                    }
                    None => stats.orphan_messages += 1,
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// The records of one chunk.
    fn chunk(
        &mut self,
        body: &[u8],
        stats: &mut ReadStats,
        each: &mut dyn FnMut(&Connection, &MessageRecord),
    ) -> Result<(), String> {
        let Record::Chunk { header, data } =
            mcap::parse_record(mcap::records::op::CHUNK, body).map_err(|e| e.to_string())?
        else {
            return Err("not a chunk".into());
        };
        let compression = match header.compression.as_str() {
            "" => Compression::None,
            "zstd" => Compression::Zstd,
            "lz4" => Compression::Lz4,
            other => return Err(format!("unknown chunk compression {other:?}")),
        };
        if !stats.compressions.contains(&compression) {
            stats.compressions.push(compression);
        }
        if header.uncompressed_size > MAX_CHUNK_BYTES {
            return Err(format!(
                "chunk declares {} bytes uncompressed, more than slamkit reads",
                header.uncompressed_size
            ));
        }
        let bytes = decompress_exact(compression, &data, header.uncompressed_size)
            .map_err(|e| e.to_string())?;
        if header.uncompressed_crc != 0 && crc32fast::hash(&bytes) != header.uncompressed_crc {
            return Err("chunk CRC mismatch".into());
        }
        let mut pos = 0usize;
        while pos < bytes.len() {
            let (Some(&op), Some(len)) = (
                bytes.get(pos),
                bytes
                    .get(pos + 1..pos + 9)
                    .and_then(|b| <[u8; 8]>::try_from(b).ok())
                    .map(u64::from_le_bytes),
            ) else {
                return Err(format!("record header cut at byte {pos} of the chunk"));
            };
            let start = pos + 9;
            let end = usize::try_from(len)
                .ok()
                .and_then(|l| start.checked_add(l))
                .filter(|&e| e <= bytes.len())
                .ok_or_else(|| format!("record at byte {pos} of the chunk runs past its end"))?;
            self.record(op, &bytes[start..end], stats, each)
                .map_err(|e| format!("at byte {pos} of the chunk: {e}"))?;
            pos = end;
        }
        Ok(())
    }

    /// Messages per channel with their time span, chunks and compressions: from the summary's
    /// statistics when there are some, else by reading the file.
    pub fn counts(&mut self) -> Result<FileCounts, BagError> {
        if let Some(stats) = self.summary.as_ref().and_then(|s| s.stats.clone()) {
            let summary = self.summary.as_ref();
            let (start, end) = (
                nanos_to_time(stats.message_start_time),
                nanos_to_time(stats.message_end_time),
            );
            let mut compressions = Vec::new();
            for c in summary
                .map(|s| s.chunk_indexes.as_slice())
                .unwrap_or_default()
            {
                let c = match c.compression.as_str() {
                    "" => Compression::None,
                    "zstd" => Compression::Zstd,
                    "lz4" => Compression::Lz4,
                    _ => continue,
                };
                if !compressions.contains(&c) {
                    compressions.push(c);
                }
            }
            return Ok(FileCounts {
                per_connection: stats
                    .channel_message_counts
                    .iter()
                    .map(|(&id, &n)| {
                        (
                            u32::from(id),
                            ConnectionCounts {
                                messages: n as usize,
                                start,
                                end,
                            },
                        )
                    })
                    .collect(),
                chunks: stats.chunk_count as usize,
                compressions,
                walk: None,
            });
        }
        let mut per: HashMap<u32, ConnectionCounts> = HashMap::new();
        let stats = self.read(&mut |conn, msg| {
            let e = per.entry(conn.id).or_insert(ConnectionCounts {
                messages: 0,
                start: msg.time,
                end: msg.time,
            });
            e.messages += 1;
            e.start = e.start.min(msg.time);
            e.end = e.end.max(msg.time);
        })?;
        Ok(FileCounts {
            per_connection: per.into_iter().collect(),
            chunks: stats.chunks,
            compressions: stats.compressions.clone(),
            walk: Some(stats),
        })
    }
}

/// Reads the summary section (`Ok(None)` for a file without one).
fn read_summary(file: &mut File, len: u64) -> Result<Option<mcap::Summary>, String> {
    let options = SummaryReaderOptions::default()
        .with_file_size(len)
        .with_record_length_limit(MAX_CHUNK_BYTES as usize);
    let mut reader = SummaryReader::new_with_options(options);
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| e.to_string())? {
            SummaryReadEvent::ReadRequest(need) => {
                let n = file.read(reader.insert(need)).map_err(|e| e.to_string())?;
                reader.notify_read(n);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let at = file.seek(to).map_err(|e| e.to_string())?;
                reader.notify_seeked(at);
            }
        }
    }
    Ok(reader.finish())
}

/// A schema as (type name, ROS 2 definition text when it is one).
fn schema_text(name: &str, encoding: &str, data: &[u8]) -> (String, String) {
    let text = match encoding {
        "ros2msg" => String::from_utf8_lossy(data).into_owned(),
        _ => String::new(),
    };
    (name.to_string(), text)
}

/// Nanoseconds since the epoch as a ROS time (saturating past 2106).
pub(crate) fn nanos_to_time(ns: u64) -> RosTime {
    RosTime {
        sec: u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX),
        nsec: (ns % 1_000_000_000) as u32,
    }
}
