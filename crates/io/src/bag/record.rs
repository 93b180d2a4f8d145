//! The record layer of a ROS 1 bag (format 2.0): every record is
//! `header_len: u32 | header | data_len: u32 | data`, little-endian, and a header is a
//! sequence of `field_len: u32 | name=value` fields, `op` (one byte) naming the record type.
//! Everything here checks lengths against the bytes that are really there, so a truncated or
//! bit-flipped file gives a [`RecordError`], never a panic or a huge allocation.

use std::io::Read;

/// The first bytes of every ROS 1 bag of format 2.0.
pub const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// The record types of format 2.0 (the `op` header field).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Op {
    /// A serialised message (`conn`, `time`).
    MessageData,
    /// The bag header: where the index starts, connection and chunk counts.
    BagHeader,
    /// Per chunk and connection: the time and offset of each message in the chunk.
    IndexData,
    /// Compressed (or plain) records: connections and messages.
    Chunk,
    /// Per chunk: its position, time span and message count per connection.
    ChunkInfo,
    /// A topic with its message type, md5sum and definition.
    Connection,
}

impl Op {
    /// The record type of an `op` byte, `None` for a byte no 2.0 record has.
    pub fn from_byte(op: u8) -> Option<Self> {
        Some(match op {
            0x02 => Self::MessageData,
            0x03 => Self::BagHeader,
            0x04 => Self::IndexData,
            0x05 => Self::Chunk,
            0x06 => Self::ChunkInfo,
            0x07 => Self::Connection,
            _ => return None,
        })
    }
}

/// What is wrong with a record (the caller adds the file and the byte offset).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum RecordError {
    /// The bytes end inside a record.
    #[error("truncated: {0}")]
    Truncated(String),
    /// The bytes are there but do not make a valid record.
    #[error("{0}")]
    Malformed(String),
}

/// Reads a little-endian `u32` at `pos` of `bytes`.
pub(crate) fn u32_at(bytes: &[u8], pos: usize) -> Option<u32> {
    let b = bytes.get(pos..pos.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// The fields of a record header (or of a connection record's data, which has the same form).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fields<'a> {
    fields: Vec<(&'a [u8], &'a [u8])>,
}

impl<'a> Fields<'a> {
    /// Splits `bytes` into `name=value` fields.
    ///
    /// ```
    /// use slamkit_io::bag::record::Fields;
    ///
    /// let mut bytes = Vec::new();
    /// for field in [&b"op=\x07"[..], b"topic=/scan"] {
    ///     bytes.extend_from_slice(&(field.len() as u32).to_le_bytes());
    ///     bytes.extend_from_slice(field);
    /// }
    /// let fields = Fields::parse(&bytes)?;
    /// assert_eq!(fields.string("topic")?, "/scan");
    /// assert_eq!(fields.op()?, 7);
    /// # Ok::<(), slamkit_io::bag::record::RecordError>(())
    /// ```
    pub fn parse(bytes: &'a [u8]) -> Result<Self, RecordError> {
        let mut fields = Vec::new();
        let mut pos = 0;
        while pos < bytes.len() {
            let len = u32_at(bytes, pos)
                .ok_or_else(|| RecordError::Malformed("header field length cut off".into()))?
                as usize;
            let field = pos
                .checked_add(4)
                .and_then(|start| bytes.get(start..start.checked_add(len)?))
                .ok_or_else(|| {
                    RecordError::Malformed(format!(
                        "header field of {len} bytes runs past the header's end"
                    ))
                })?;
            let eq = field.iter().position(|&b| b == b'=').ok_or_else(|| {
                RecordError::Malformed("header field without '=' (not name=value)".into())
            })?;
            fields.push((&field[..eq], &field[eq + 1..]));
            pos += 4 + len;
        }
        Ok(Self { fields })
    }

    /// The value of field `name`, if present.
    pub fn get(&self, name: &str) -> Option<&'a [u8]> {
        self.fields
            .iter()
            .find(|(n, _)| *n == name.as_bytes())
            .map(|(_, v)| *v)
    }

    /// The value of field `name`, or an error naming it.
    pub fn require(&self, name: &str) -> Result<&'a [u8], RecordError> {
        self.get(name)
            .ok_or_else(|| RecordError::Malformed(format!("header has no '{name}' field")))
    }

    /// The `op` field: the record type byte.
    pub fn op(&self) -> Result<u8, RecordError> {
        match self.require("op")? {
            [op] => Ok(*op),
            other => Err(RecordError::Malformed(format!(
                "'op' field is {} bytes, not 1",
                other.len()
            ))),
        }
    }

    /// Field `name` as a little-endian `u32`.
    pub fn u32(&self, name: &str) -> Result<u32, RecordError> {
        let v = self.require(name)?;
        <[u8; 4]>::try_from(v)
            .map(u32::from_le_bytes)
            .map_err(|_| wrong_size(name, v.len(), 4))
    }

    /// Field `name` as a little-endian `u64`.
    pub fn u64(&self, name: &str) -> Result<u64, RecordError> {
        let v = self.require(name)?;
        <[u8; 8]>::try_from(v)
            .map(u64::from_le_bytes)
            .map_err(|_| wrong_size(name, v.len(), 8))
    }

    /// Field `name` as a ROS time (`sec: u32`, `nsec: u32`).
    pub fn time(&self, name: &str) -> Result<RosTime, RecordError> {
        let v = self.u64(name)?;
        Ok(RosTime {
            sec: (v & 0xffff_ffff) as u32,
            nsec: (v >> 32) as u32,
        })
    }

    /// Field `name` as UTF-8 text.
    pub fn string(&self, name: &str) -> Result<&'a str, RecordError> {
        std::str::from_utf8(self.require(name)?)
            .map_err(|_| RecordError::Malformed(format!("'{name}' field is not UTF-8 text")))
    }
}

fn wrong_size(name: &str, got: usize, want: usize) -> RecordError {
    RecordError::Malformed(format!("'{name}' field is {got} bytes, not {want}"))
}

/// A ROS 1 time: seconds and nanoseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
pub struct RosTime {
    /// Whole seconds.
    pub sec: u32,
    /// Nanoseconds (below 10⁹ in a valid time).
    pub nsec: u32,
}

impl RosTime {
    /// Seconds as `f64` (the form slamkit's timestamps take).
    ///
    /// ```
    /// use slamkit_io::bag::record::RosTime;
    /// assert_eq!(RosTime { sec: 70, nsec: 500_000_000 }.as_secs_f64(), 70.5);
    /// ```
    pub fn as_secs_f64(self) -> f64 {
        f64::from(self.sec) + f64::from(self.nsec) * 1e-9
    }

    /// Nanoseconds since the epoch, for exact ordering.
    pub fn as_nanos(self) -> u64 {
        u64::from(self.sec) * 1_000_000_000 + u64::from(self.nsec)
    }
}

/// One record read from the file, its header and data owned.
#[derive(Debug, Clone)]
pub(crate) struct OwnedRecord {
    pub(crate) header: Vec<u8>,
    pub(crate) data: Vec<u8>,
}

/// Reads one length-prefixed block of at most `remaining` bytes from `reader`.
fn read_block<R: Read>(
    reader: &mut R,
    remaining: &mut u64,
    what: &str,
) -> Result<Vec<u8>, RecordError> {
    let mut len = [0u8; 4];
    reader
        .read_exact(&mut len)
        .map_err(|_| RecordError::Truncated(format!("{what} length cut off")))?;
    *remaining = remaining.saturating_sub(4);
    let len = u64::from(u32::from_le_bytes(len));
    if len > *remaining {
        return Err(RecordError::Truncated(format!(
            "{what} of {len} bytes, only {remaining} left in the file"
        )));
    }
    let mut block = vec![0u8; len as usize];
    reader
        .read_exact(&mut block)
        .map_err(|e| RecordError::Truncated(format!("{what} cut off ({e})")))?;
    *remaining -= len;
    Ok(block)
}

/// Reads the record at the reader's position; `remaining` is the number of bytes left in the
/// file (lengths beyond it are truncation, not an allocation).
pub(crate) fn read_record<R: Read>(
    reader: &mut R,
    remaining: u64,
) -> Result<OwnedRecord, RecordError> {
    let mut left = remaining;
    let header = read_block(reader, &mut left, "record header")?;
    let data = read_block(reader, &mut left, "record data")?;
    Ok(OwnedRecord { header, data })
}

/// A record inside a decompressed chunk, borrowed from it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SliceRecord<'a> {
    /// Offset of the record in the chunk's bytes.
    pub(crate) offset: usize,
    pub(crate) header: &'a [u8],
    pub(crate) data: &'a [u8],
    /// Offset of the byte after the record.
    pub(crate) end: usize,
}

/// The record at `offset` of `bytes`.
pub(crate) fn slice_record(bytes: &[u8], offset: usize) -> Result<SliceRecord<'_>, RecordError> {
    let block = |pos: usize, what: &str| -> Result<(&[u8], usize), RecordError> {
        let len = u32_at(bytes, pos)
            .ok_or_else(|| RecordError::Truncated(format!("{what} length cut off")))?
            as usize;
        let start = pos + 4;
        let body = start
            .checked_add(len)
            .and_then(|end| bytes.get(start..end))
            .ok_or_else(|| {
                RecordError::Truncated(format!(
                    "{what} of {len} bytes runs past the end ({} bytes)",
                    bytes.len()
                ))
            })?;
        Ok((body, start + len))
    };
    let (header, next) = block(offset, "record header")?;
    let (data, end) = block(next, "record data")?;
    Ok(SliceRecord {
        offset,
        header,
        data,
        end,
    })
}

/// The records of a decompressed chunk, in order; the first broken one ends the sequence
/// with its error.
pub(crate) fn slice_records(
    bytes: &[u8],
) -> impl Iterator<Item = Result<SliceRecord<'_>, (usize, RecordError)>> {
    let mut pos = 0usize;
    let mut failed = false;
    std::iter::from_fn(move || {
        if failed || pos >= bytes.len() {
            return None;
        }
        match slice_record(bytes, pos) {
            Ok(record) => {
                pos = record.end;
                Some(Ok(record))
            }
            Err(e) => {
                failed = true;
                Some(Err((pos, e)))
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field(bytes: &mut Vec<u8>, f: &[u8]) {
        bytes.extend_from_slice(&(f.len() as u32).to_le_bytes());
        bytes.extend_from_slice(f);
    }

    #[test]
    fn fields_typed_and_checked() {
        let mut h = Vec::new();
        field(&mut h, b"op=\x02");
        field(&mut h, b"conn=\x03\x00\x00\x00");
        field(&mut h, b"time=\x46\x00\x00\x00\x00\x65\xcd\x1d");
        let f = Fields::parse(&h).unwrap();
        assert_eq!(Op::from_byte(f.op().unwrap()), Some(Op::MessageData));
        assert_eq!(f.u32("conn").unwrap(), 3);
        let t = f.time("time").unwrap();
        assert_eq!((t.sec, t.nsec), (70, 500_000_000));
        assert!(matches!(f.u64("conn"), Err(RecordError::Malformed(_))));
        assert!(f.get("topic").is_none());
        // a field length running past the end, and a field without '='
        assert!(Fields::parse(&h[..h.len() - 1]).is_err());
        let mut bad = Vec::new();
        field(&mut bad, b"noequals");
        assert!(Fields::parse(&bad).is_err());
    }

    #[test]
    fn slice_records_stop_at_truncation() {
        let mut bytes = Vec::new();
        for data in [&b"abc"[..], b"de"] {
            let mut h = Vec::new();
            field(&mut h, b"op=\x02");
            field(&mut bytes, &h);
            field(&mut bytes, data);
        }
        let all: Vec<_> = slice_records(&bytes).collect();
        assert_eq!(all.len(), 2);
        assert_eq!(all[1].as_ref().unwrap().data, b"de");
        let cut: Vec<_> = slice_records(&bytes[..bytes.len() - 1]).collect();
        assert!(matches!(cut[1], Err((_, RecordError::Truncated(_)))));
        let mut reader = &bytes[..];
        let rec = read_record(&mut reader, bytes.len() as u64).unwrap();
        assert_eq!(rec.data, b"abc");
        // a length larger than the file is truncation, not an allocation
        let huge = [0xff, 0xff, 0xff, 0x7f, 0, 0];
        assert!(matches!(
            read_record(&mut &huge[..], 6),
            Err(RecordError::Truncated(_))
        ));
    }
}
