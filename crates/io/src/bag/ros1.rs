//! ROS 1 serialisation, read: little-endian primitives packed without padding, `time` as two
//! `u32`, strings and variable-length arrays prefixed with a `u32` count, fixed-length arrays
//! without one. Counts are checked against the bytes left before anything is allocated, and a
//! message must use its bytes exactly (left-over bytes mean the type is not what the
//! connection said).

use super::record::RosTime;
use super::wire::Wire;

/// Why a message could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("byte {offset}: {what}")]
pub struct DecodeError {
    /// Offset in the message where decoding failed.
    pub offset: usize,
    /// What was expected there.
    pub what: String,
}

/// A read position in one serialised message.
#[derive(Debug, Clone)]
pub struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    fn error(&self, what: impl Into<String>) -> DecodeError {
        DecodeError {
            offset: self.pos,
            what: what.into(),
        }
    }

    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], DecodeError> {
        let b = self
            .bytes
            .get(self.pos..self.pos + N)
            .and_then(|b| <[u8; N]>::try_from(b).ok())
            .ok_or_else(|| self.error(format!("message ends inside a {what}")))?;
        self.pos += N;
        Ok(b)
    }
}

impl Wire for Cursor<'_> {
    fn header_seq(&mut self) -> Result<Option<u32>, DecodeError> {
        self.u32().map(Some)
    }

    fn u8(&mut self) -> Result<u8, DecodeError> {
        self.take::<1>("uint8").map(|b| b[0])
    }

    fn u32(&mut self) -> Result<u32, DecodeError> {
        self.take("uint32").map(u32::from_le_bytes)
    }

    fn f32(&mut self) -> Result<f32, DecodeError> {
        self.take("float32").map(f32::from_le_bytes)
    }

    fn f64(&mut self) -> Result<f64, DecodeError> {
        self.take("float64").map(f64::from_le_bytes)
    }

    fn time(&mut self) -> Result<RosTime, DecodeError> {
        Ok(RosTime {
            sec: self.u32()?,
            nsec: self.u32()?,
        })
    }

    fn count(&mut self, elem_bytes: usize) -> Result<usize, DecodeError> {
        let n = self.u32()? as usize;
        let left = self.bytes.len() - self.pos;
        if n.saturating_mul(elem_bytes.max(1)) > left {
            return Err(self.error(format!(
                "array of {n} elements of {elem_bytes} bytes, only {left} bytes left"
            )));
        }
        Ok(n)
    }

    fn string(&mut self) -> Result<String, DecodeError> {
        let n = self.count(1)?;
        let bytes = &self.bytes[self.pos..self.pos + n];
        let s = std::str::from_utf8(bytes).map_err(|_| self.error("string is not UTF-8"))?;
        self.pos += n;
        Ok(s.to_string())
    }

    fn bytes(&mut self, n: usize) -> Result<Vec<u8>, DecodeError> {
        let b = self
            .bytes
            .get(self.pos..self.pos.saturating_add(n))
            .ok_or_else(|| self.error(format!("message ends inside {n} bytes of data")))?;
        self.pos += n;
        Ok(b.to_vec())
    }

    fn finish(&self) -> Result<(), DecodeError> {
        let left = self.bytes.len() - self.pos;
        if left == 0 {
            Ok(())
        } else {
            Err(self.error(format!(
                "{left} bytes left over after the message (not the type the connection names?)"
            )))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitives_strings_and_arrays() {
        let mut b = Vec::new();
        b.extend_from_slice(&7u32.to_le_bytes());
        b.extend_from_slice(&3u32.to_le_bytes());
        b.extend_from_slice(b"abc");
        b.extend_from_slice(&2u32.to_le_bytes());
        b.extend_from_slice(&1.5f32.to_le_bytes());
        b.extend_from_slice(&(-2.0f32).to_le_bytes());
        b.extend_from_slice(&0.25f64.to_le_bytes());
        let mut c = Cursor::new(&b);
        assert_eq!(c.u32().unwrap(), 7);
        assert_eq!(c.string().unwrap(), "abc");
        assert_eq!(c.f32_array().unwrap(), vec![1.5, -2.0]);
        assert!(c.finish().is_err());
        assert_eq!(c.f64().unwrap(), 0.25);
        c.finish().unwrap();
        assert!(c.u8().is_err());
    }

    #[test]
    fn counts_beyond_the_message_are_errors_not_allocations() {
        let b = u32::MAX.to_le_bytes();
        let err = Cursor::new(&b).f32_array().unwrap_err();
        assert!(err.what.contains("only 0 bytes left"), "{err}");
        let mut s = 2u32.to_le_bytes().to_vec();
        s.extend_from_slice(&[0xff, 0xfe]);
        assert!(Cursor::new(&s).string().is_err());
    }
}
