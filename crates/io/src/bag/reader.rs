//! Opening a bag and reading its messages: the bag header, the index at its end (connections
//! and chunk infos), and the chunks, in storage order or in time order.
//!
//! *Storage order* is the order the messages were written: what `rosbag record` received, in
//! arrival order, and what a converter wrote. *Time order* is rosbag's playback order: by
//! record time, ties in storage order. The two differ when a writer gave times out of order:
//! the Intel benchmark bag (converted from its CARMEN log) stores its scans in the physical
//! order of the log, whose stamps step back 631 times; in time order those scans would be
//! shuffled. A bag without an index (a recording that was never closed: `index_pos` 0) or with
//! an unreadable one is read all the same, by walking its chunks, as `rosbag reindex` does.
//! A chunk that cannot be decompressed or parsed is skipped and counted ([`ReadStats`]), and
//! so is a file that ends inside a record (a recording cut short: what came before is read);
//! other damage to the record framing (a header that does not parse, an unknown record type)
//! stops the read with an error naming the byte offset.

use super::chunk::{decompress, Compression};
use super::connection::Connection;
use super::record::{
    read_record, slice_records, Fields, Op, OwnedRecord, RecordError, RosTime, MAGIC,
};
use super::BagError;
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

/// Connections by id.
pub type Connections = BTreeMap<u32, Connection>;

/// Messages of one connection and their time span, counted by a walk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ConnectionSpan {
    pub(crate) messages: usize,
    pub(crate) start: RosTime,
    pub(crate) end: RosTime,
}

/// The fields of the bag header record.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct BagHeader {
    /// Offset of the index (connections and chunk infos); 0 while a recording is open.
    pub index_pos: u64,
    /// Connections the index holds.
    pub conn_count: u32,
    /// Chunks the index describes.
    pub chunk_count: u32,
}

/// One chunk as the index describes it.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct ChunkInfo {
    /// Offset of the chunk record.
    pub chunk_pos: u64,
    /// Earliest message time in the chunk.
    pub start: RosTime,
    /// Latest message time in the chunk.
    pub end: RosTime,
    /// Messages per connection id.
    pub counts: Vec<(u32, u32)>,
}

/// The state of a bag's index.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
#[serde(tag = "state", content = "reason", rename_all = "snake_case")]
pub enum IndexState {
    /// Read at `index_pos`.
    Indexed,
    /// `index_pos` is 0: the recording was not closed.
    NotIndexed,
    /// There is an index but it cannot be read (the reason); the chunks are walked instead.
    Unreadable(String),
}

/// Where messages are read in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Order {
    /// As stored (written).
    Storage,
    /// By record time, ties in storage order (rosbag's playback order).
    Time,
}

/// A message record: its connection, record time and serialised bytes.
#[derive(Debug, Clone, Copy)]
pub struct MessageRecord<'a> {
    /// Connection id.
    pub conn: u32,
    /// Record time (when it was recorded; usually its arrival).
    pub time: RosTime,
    /// ROS 1 serialised message.
    pub data: &'a [u8],
}

/// A chunk that was skipped.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct DamagedChunk {
    /// Offset of the chunk record in the file.
    pub offset: u64,
    /// What is wrong with it.
    pub error: String,
}

/// What a read went through.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct ReadStats {
    /// Messages handed to the caller.
    pub messages: usize,
    /// Chunks read.
    pub chunks: usize,
    /// Chunks skipped because they could not be decompressed or parsed.
    pub damaged_chunks: Vec<DamagedChunk>,
    /// Messages whose connection the bag never defines (skipped).
    pub orphan_messages: usize,
    /// Where the file ends inside a record (a recording cut short): everything before it was
    /// read, the record there is lost.
    pub truncated: Option<DamagedChunk>,
    /// Compression of the chunks read.
    pub compressions: Vec<Compression>,
}

/// An open ROS 1 bag (format 2.0) over any seekable byte source.
#[derive(Debug)]
pub struct Bag<R> {
    reader: R,
    name: String,
    len: u64,
    data_start: u64,
    header: BagHeader,
    connections: Connections,
    chunk_infos: Vec<ChunkInfo>,
    index: IndexState,
}

impl Bag<BufReader<File>> {
    /// Opens the bag file at `path` and reads its header and index.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let name = path.display().to_string();
        let file = File::open(path).map_err(|error| BagError::Open {
            file: name.clone(),
            error,
        })?;
        Self::from_reader(BufReader::new(file), &name)
    }
}

/// Where a message record lies, for reading it again in time order.
#[derive(Debug, Clone, Copy)]
struct Location {
    time: RosTime,
    /// File offset of the chunk (or of the top-level message record).
    record_pos: u64,
    /// Offset of the message record inside the decompressed chunk (`None`: top level).
    in_chunk: Option<usize>,
}

impl<R: Read + Seek> Bag<R> {
    /// Reads the header and index of a bag from `reader`; `name` names it in errors.
    ///
    /// ```
    /// use slamkit_io::bag::{Bag, BagError};
    ///
    /// let err = Bag::from_reader(std::io::Cursor::new(b"SQLite format 3\0"), "x.db3").unwrap_err();
    /// assert!(err.to_string().contains("SQLite"), "{err}");
    /// ```
    pub fn from_reader(mut reader: R, name: &str) -> Result<Self, BagError> {
        let len = reader
            .seek(SeekFrom::End(0))
            .and_then(|len| reader.seek(SeekFrom::Start(0)).map(|_| len))
            .map_err(|error| BagError::Open {
                file: name.to_string(),
                error,
            })?;
        // 16 bytes: enough to tell the magic of the other kinds of bag apart.
        let mut head = [0u8; 16];
        let got = read_up_to(&mut reader, &mut head);
        if !head[..got].starts_with(MAGIC) {
            return Err(BagError::NotABag {
                file: name.to_string(),
                what: describe_magic(&head[..got]),
            });
        }
        let mut bag = Self {
            reader,
            name: name.to_string(),
            len,
            data_start: 0,
            header: BagHeader::default(),
            connections: BTreeMap::new(),
            chunk_infos: Vec::new(),
            index: IndexState::NotIndexed,
        };
        let pos = MAGIC.len() as u64;
        let rec = bag.record_at(pos)?;
        let fields = Fields::parse(&rec.header).map_err(|e| bag.damaged(pos, e))?;
        if fields.op().map_err(|e| bag.damaged(pos, e))? != 0x03 {
            return Err(bag.damaged(pos, RecordError::Malformed("no bag header record".into())));
        }
        let field = |e| bag.damaged(pos, e);
        bag.header = BagHeader {
            index_pos: fields.u64("index_pos").map_err(field)?,
            conn_count: fields.u32("conn_count").map_err(field)?,
            chunk_count: fields.u32("chunk_count").map_err(field)?,
        };
        bag.data_start = pos + 8 + rec.header.len() as u64 + rec.data.len() as u64;
        bag.index = bag.read_index();
        Ok(bag)
    }

    /// The bag's name in errors (its path).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The bag header.
    pub fn header(&self) -> BagHeader {
        self.header
    }

    /// The state of the index.
    pub fn index_state(&self) -> &IndexState {
        &self.index
    }

    /// Connections known so far: all of them once the index is read, else those met by a
    /// read.
    pub fn connections(&self) -> &Connections {
        &self.connections
    }

    /// The chunk infos of the index (empty without one).
    pub fn chunk_infos(&self) -> &[ChunkInfo] {
        &self.chunk_infos
    }

    fn damaged(&self, offset: u64, error: RecordError) -> BagError {
        BagError::Damaged {
            file: self.name.clone(),
            offset,
            error,
        }
    }

    fn record_at(&mut self, pos: u64) -> Result<OwnedRecord, BagError> {
        self.reader
            .seek(SeekFrom::Start(pos))
            .map_err(|e| self.damaged(pos, RecordError::Truncated(e.to_string())))?;
        let remaining = self.len.saturating_sub(pos);
        read_record(&mut self.reader, remaining).map_err(|e| self.damaged(pos, e))
    }

    /// Reads connections and chunk infos from `index_pos` to the end of the file.
    fn read_index(&mut self) -> IndexState {
        let start = self.header.index_pos;
        if start == 0 {
            return IndexState::NotIndexed;
        }
        if start < self.data_start || start >= self.len {
            return IndexState::Unreadable(format!(
                "index_pos {start} lies outside the data ({} to {} bytes)",
                self.data_start, self.len
            ));
        }
        let mut connections = BTreeMap::new();
        let mut chunks = Vec::new();
        let mut pos = start;
        while pos < self.len {
            let parsed = self
                .record_at(pos)
                .map_err(|e| e.to_string())
                .and_then(|rec| {
                    let next = pos + 8 + rec.header.len() as u64 + rec.data.len() as u64;
                    index_record(&rec, &mut connections, &mut chunks)
                        .map(|()| next)
                        .map_err(|e| self.damaged(pos, e).to_string())
                });
            match parsed {
                Ok(next) => pos = next,
                Err(reason) => return IndexState::Unreadable(reason),
            }
        }
        if chunks.len() != self.header.chunk_count as usize
            || connections.len() != self.header.conn_count as usize
        {
            return IndexState::Unreadable(format!(
                "the index holds {} chunks and {} connections, the bag header says {} and {}",
                chunks.len(),
                connections.len(),
                self.header.chunk_count,
                self.header.conn_count
            ));
        }
        self.connections = connections;
        self.chunk_infos = chunks;
        IndexState::Indexed
    }

    /// Reads every message in `order`, calling `visit` with its connection; returns what was
    /// read and skipped.
    pub fn read_messages(
        &mut self,
        order: Order,
        mut visit: impl FnMut(&Connection, &MessageRecord),
    ) -> Result<ReadStats, BagError> {
        match order {
            Order::Storage => self.walk(&mut |conns, _, msg| {
                if let Some(conn) = conns.get(&msg.conn) {
                    visit(conn, msg);
                }
            }),
            Order::Time => self.read_in_time_order(&mut visit),
        }
    }

    /// Walks the data section in storage order, handing each message with its location to
    /// `each` (messages without a connection are counted, not handed).
    fn walk(
        &mut self,
        each: &mut dyn FnMut(&Connections, Location, &MessageRecord),
    ) -> Result<ReadStats, BagError> {
        let mut stats = ReadStats::default();
        let mut pos = self.data_start;
        let end = if self.index == IndexState::Indexed {
            self.header.index_pos
        } else {
            self.len
        };
        while pos < end {
            let rec = match self.record_at(pos) {
                Ok(rec) => rec,
                Err(BagError::Damaged {
                    error: RecordError::Truncated(what),
                    ..
                }) => {
                    // A recording cut short: what was written before the cut is read.
                    stats.truncated = Some(DamagedChunk {
                        offset: pos,
                        error: what,
                    });
                    break;
                }
                Err(e) => return Err(e),
            };
            let next = pos + 8 + rec.header.len() as u64 + rec.data.len() as u64;
            let fields = Fields::parse(&rec.header).map_err(|e| self.damaged(pos, e))?;
            let op = fields.op().map_err(|e| self.damaged(pos, e))?;
            match Op::from_byte(op) {
                Some(Op::Chunk) => {
                    stats.chunks += 1;
                    let result = decompress(&fields, &rec.data).and_then(|bytes| {
                        if let Ok(c) = Compression::parse(fields.string("compression")?) {
                            if !stats.compressions.contains(&c) {
                                stats.compressions.push(c);
                            }
                        }
                        chunk_messages(&bytes, &mut self.connections, &mut |conns, offset, msg| {
                            if conns.contains_key(&msg.conn) {
                                stats.messages += 1;
                                let at = Location {
                                    time: msg.time,
                                    record_pos: pos,
                                    in_chunk: Some(offset),
                                };
                                each(conns, at, msg);
                            } else {
                                stats.orphan_messages += 1;
                            }
                        })
                    });
                    if let Err(e) = result {
                        stats.damaged_chunks.push(DamagedChunk {
                            offset: pos,
                            error: e.to_string(),
                        });
                    }
                }
                Some(Op::Connection) => {
                    let conn =
                        Connection::parse(&fields, &rec.data).map_err(|e| self.damaged(pos, e))?;
                    self.connections.entry(conn.id).or_insert(conn);
                }
                Some(Op::MessageData) => {
                    let msg =
                        message_record(&fields, &rec.data).map_err(|e| self.damaged(pos, e))?;
                    if self.connections.contains_key(&msg.conn) {
                        stats.messages += 1;
                        let at = Location {
                            time: msg.time,
                            record_pos: pos,
                            in_chunk: None,
                        };
                        each(&self.connections, at, &msg);
                    } else {
                        stats.orphan_messages += 1;
                    }
                }
                Some(Op::IndexData | Op::ChunkInfo) => {}
                Some(Op::BagHeader) | None => {
                    return Err(self.damaged(
                        pos,
                        RecordError::Malformed(format!("unexpected record op {op:#04x}")),
                    ))
                }
            }
            pos = next;
        }
        Ok(stats)
    }

    /// Time order: a first walk notes where each message lies, they are sorted by time
    /// (stable, so ties stay in storage order), then read again chunk by chunk.
    fn read_in_time_order(
        &mut self,
        visit: &mut dyn FnMut(&Connection, &MessageRecord),
    ) -> Result<ReadStats, BagError> {
        let mut locations = Vec::new();
        let stats = self.walk(&mut |_, at, _| locations.push(at))?;
        locations.sort_by_key(|at| at.time);
        let mut cache: Option<(u64, Vec<u8>)> = None;
        for at in locations {
            let rec = self.record_at(at.record_pos)?;
            let fields = Fields::parse(&rec.header).map_err(|e| self.damaged(at.record_pos, e))?;
            let bytes = match at.in_chunk {
                None => {
                    let msg = message_record(&fields, &rec.data)
                        .map_err(|e| self.damaged(at.record_pos, e))?;
                    if let Some(conn) = self.connections.get(&msg.conn) {
                        visit(conn, &msg);
                    }
                    continue;
                }
                Some(_) if cache.as_ref().is_some_and(|(p, _)| *p == at.record_pos) => {
                    cache.take().map(|(_, b)| b).unwrap_or_default()
                }
                Some(_) => {
                    decompress(&fields, &rec.data).map_err(|e| self.damaged(at.record_pos, e))?
                }
            };
            let offset = at.in_chunk.unwrap_or_default();
            let record = super::record::slice_record(&bytes, offset)
                .and_then(|r| {
                    let f = Fields::parse(r.header)?;
                    message_record(&f, r.data)
                })
                .map_err(|e| self.damaged(at.record_pos, e))?;
            if let Some(conn) = self.connections.get(&record.conn) {
                visit(conn, &record);
            }
            cache = Some((at.record_pos, bytes));
        }
        Ok(stats)
    }
}

/// Reads into `buf` as far as the source goes.
fn read_up_to<R: Read>(reader: &mut R, buf: &mut [u8]) -> usize {
    let mut got = 0;
    while got < buf.len() {
        match reader.read(&mut buf[got..]) {
            Ok(0) | Err(_) => break,
            Ok(n) => got += n,
        }
    }
    got
}

/// What a file that is not a ROS 1 bag 2.0 looks like.
fn describe_magic(head: &[u8]) -> String {
    if head.starts_with(b"#ROSBAG V") {
        let version: String = head[9..]
            .iter()
            .take_while(|b| **b != b'\n')
            .map(|b| *b as char)
            .collect();
        format!("a ROS 1 bag of format {version}, which slamkit does not read (`rosbag fix` converts it)")
    } else if head.starts_with(b"\x89MCAP") {
        "an MCAP file (a ROS 2 bag: read it through `bag::open`)".into()
    } else if head.starts_with(b"SQLite format 3") {
        "an SQLite file (a ROS 2 .db3 bag: read it through `bag::open`)".into()
    } else {
        "no '#ROSBAG V2.0' magic".into()
    }
}

/// Adds an index record (connection or chunk info) to the tables.
fn index_record(
    rec: &OwnedRecord,
    connections: &mut Connections,
    chunks: &mut Vec<ChunkInfo>,
) -> Result<(), RecordError> {
    let fields = Fields::parse(&rec.header)?;
    match Op::from_byte(fields.op()?) {
        Some(Op::Connection) => {
            let conn = Connection::parse(&fields, &rec.data)?;
            connections.insert(conn.id, conn);
        }
        Some(Op::ChunkInfo) => chunks.push(chunk_info(&fields, &rec.data)?),
        _ => {
            return Err(RecordError::Malformed(
                "the index holds a record that is neither a connection nor a chunk info".into(),
            ))
        }
    }
    Ok(())
}

/// A chunk info record.
fn chunk_info(fields: &Fields, data: &[u8]) -> Result<ChunkInfo, RecordError> {
    let count = fields.u32("count")? as usize;
    if data.len() != count.saturating_mul(8) {
        return Err(RecordError::Malformed(format!(
            "chunk info lists {count} connections in {} bytes",
            data.len()
        )));
    }
    let counts = data
        .chunks_exact(8)
        .filter_map(|c| Some((super::record::u32_at(c, 0)?, super::record::u32_at(c, 4)?)))
        .collect();
    Ok(ChunkInfo {
        chunk_pos: fields.u64("chunk_pos")?,
        start: fields.time("start_time")?,
        end: fields.time("end_time")?,
        counts,
    })
}

/// The message of a message data record.
fn message_record<'a>(fields: &Fields, data: &'a [u8]) -> Result<MessageRecord<'a>, RecordError> {
    Ok(MessageRecord {
        conn: fields.u32("conn")?,
        time: fields.time("time")?,
        data,
    })
}

/// The connections and messages of a decompressed chunk: connections are added to the
/// table, messages handed to `each` with their offset in the chunk.
fn chunk_messages(
    bytes: &[u8],
    connections: &mut Connections,
    each: &mut dyn FnMut(&Connections, usize, &MessageRecord),
) -> Result<(), RecordError> {
    for record in slice_records(bytes) {
        let record = record.map_err(|(offset, e)| at_chunk_offset(offset, e))?;
        let fields = Fields::parse(record.header).map_err(|e| at_chunk_offset(record.offset, e))?;
        match Op::from_byte(fields.op().map_err(|e| at_chunk_offset(record.offset, e))?) {
            Some(Op::Connection) => {
                let conn = Connection::parse(&fields, record.data)
                    .map_err(|e| at_chunk_offset(record.offset, e))?;
                connections.entry(conn.id).or_insert(conn);
            }
            Some(Op::MessageData) => {
                let msg = message_record(&fields, record.data)
                    .map_err(|e| at_chunk_offset(record.offset, e))?;
                each(connections, record.offset, &msg);
            }
            _ => {
                return Err(at_chunk_offset(
                    record.offset,
                    RecordError::Malformed(
                        "a chunk holds a record other than a connection or message".into(),
                    ),
                ))
            }
        }
    }
    Ok(())
}

fn at_chunk_offset(offset: usize, e: RecordError) -> RecordError {
    RecordError::Malformed(format!("at byte {offset} of the decompressed chunk: {e}"))
}

/// Messages per connection counted by a walk (for a bag without a usable index).
pub(crate) fn count_by_connection<R: Read + Seek>(
    bag: &mut Bag<R>,
) -> Result<(HashMap<u32, ConnectionSpan>, ReadStats), BagError> {
    let mut counts: HashMap<u32, ConnectionSpan> = HashMap::new();
    let stats = bag.walk(&mut |_, _, msg| {
        let entry = counts.entry(msg.conn).or_insert(ConnectionSpan {
            messages: 0,
            start: msg.time,
            end: msg.time,
        });
        entry.messages += 1;
        entry.start = entry.start.min(msg.time);
        entry.end = entry.end.max(msg.time);
    })?;
    Ok((counts, stats))
}
