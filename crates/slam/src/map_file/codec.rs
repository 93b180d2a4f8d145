//! Little-endian binary encoding for the map file's records, with a reader that checks every
//! length against the bytes left, so a corrupt count is an error and never a huge allocation or
//! a panic.

use super::MapFileError;

/// Appends values to a byte buffer.
#[derive(Debug, Default)]
pub struct Writer {
    buf: Vec<u8>,
}

impl Writer {
    /// An empty buffer.
    pub fn new() -> Self {
        Self::default()
    }

    /// The bytes written.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }

    /// One byte.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// A `u32`.
    pub fn u32(&mut self, v: u32) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `u64`.
    pub fn u64(&mut self, v: u64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An `i32`.
    pub fn i32(&mut self, v: i32) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An `f64`.
    pub fn f64(&mut self, v: f64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A count or length (stored as `u32`; counts beyond are an error).
    pub fn len(&mut self, n: usize) -> Result<(), MapFileError> {
        let n =
            u32::try_from(n).map_err(|_| MapFileError::Malformed("a count beyond 2^32".into()))?;
        self.u32(n);
        Ok(())
    }

    /// Raw bytes.
    pub fn bytes(&mut self, v: &[u8]) {
        self.buf.extend_from_slice(v);
    }

    /// A `u64` in LEB128: seven bits a byte, low bits first, so small numbers take one byte.
    pub fn varint(&mut self, mut v: u64) {
        while v >= 0x80 {
            self.buf.push((v as u8 & 0x7f) | 0x80);
            v >>= 7;
        }
        self.buf.push(v as u8);
    }

    /// An `i64` as a zigzag-mapped varint (0, −1, 1, −2, ... → 0, 1, 2, 3, ...), so small
    /// magnitudes of either sign take one byte.
    pub fn signed_varint(&mut self, v: i64) {
        self.varint(((v << 1) ^ (v >> 63)) as u64);
    }
}

/// Reads values back, failing on anything past the end.
#[derive(Debug)]
pub struct Reader<'a> {
    data: &'a [u8],
    what: &'static str,
}

impl<'a> Reader<'a> {
    /// A reader over `data`, which holds `what` (named in errors).
    pub fn new(data: &'a [u8], what: &'static str) -> Self {
        Self { data, what }
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.data.len()
    }

    /// The next `n` bytes.
    pub fn take(&mut self, n: usize) -> Result<&'a [u8], MapFileError> {
        if n > self.data.len() {
            return Err(MapFileError::Malformed(format!(
                "{} ends early ({} bytes wanted, {} left)",
                self.what,
                n,
                self.data.len()
            )));
        }
        let (head, tail) = self.data.split_at(n);
        self.data = tail;
        Ok(head)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], MapFileError> {
        let mut out = [0u8; N];
        out.copy_from_slice(self.take(N)?);
        Ok(out)
    }

    /// One byte.
    pub fn u8(&mut self) -> Result<u8, MapFileError> {
        Ok(self.array::<1>()?[0])
    }

    /// A `u32`.
    pub fn u32(&mut self) -> Result<u32, MapFileError> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    /// A `u64`.
    pub fn u64(&mut self) -> Result<u64, MapFileError> {
        Ok(u64::from_le_bytes(self.array()?))
    }

    /// An `i32`.
    pub fn i32(&mut self) -> Result<i32, MapFileError> {
        Ok(i32::from_le_bytes(self.array()?))
    }

    /// An `f64` that must be finite.
    pub fn f64(&mut self) -> Result<f64, MapFileError> {
        let v = f64::from_le_bytes(self.array()?);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(MapFileError::Malformed(format!(
                "{} holds a value that is not a finite number",
                self.what
            )))
        }
    }

    /// A LEB128 `u64` ([`Writer::varint`]).
    pub fn varint(&mut self) -> Result<u64, MapFileError> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = self.u8()?;
            v |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(MapFileError::Malformed(format!(
            "{} holds a variable-length number longer than 64 bits",
            self.what
        )))
    }

    /// A zigzag-mapped `i64` ([`Writer::signed_varint`]).
    pub fn signed_varint(&mut self) -> Result<i64, MapFileError> {
        let v = self.varint()?;
        Ok((v >> 1) as i64 ^ -((v & 1) as i64))
    }

    /// A count of items of at least `item_bytes` bytes each, checked against the bytes left.
    pub fn len(&mut self, item_bytes: usize) -> Result<usize, MapFileError> {
        let n = self.u32()? as usize;
        if n.saturating_mul(item_bytes.max(1)) > self.data.len() {
            return Err(MapFileError::Malformed(format!(
                "{} claims {n} items, more than its {} bytes hold",
                self.what,
                self.data.len()
            )));
        }
        Ok(n)
    }

    /// Fails unless every byte was read.
    pub fn finish(self) -> Result<(), MapFileError> {
        if self.data.is_empty() {
            Ok(())
        } else {
            Err(MapFileError::Malformed(format!(
                "{} has {} bytes left over",
                self.what,
                self.data.len()
            )))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_round_trip_and_overruns_are_errors() {
        let mut w = Writer::new();
        w.u8(7);
        w.u32(0xdead_beef);
        w.i32(-5);
        w.f64(1.25);
        w.len(2).unwrap();
        w.u64(9);
        let bytes = w.into_bytes();
        let mut r = Reader::new(&bytes, "test");
        assert_eq!(r.u8().unwrap(), 7);
        assert_eq!(r.u32().unwrap(), 0xdead_beef);
        assert_eq!(r.i32().unwrap(), -5);
        assert_eq!(r.f64().unwrap(), 1.25);
        // two items of 8 bytes do not fit in the 8 left
        assert!(r.len(8).is_err());
        let mut r = Reader::new(&bytes[..3], "test");
        assert!(r.u8().is_ok() && r.u32().is_err());
        let mut w = Writer::new();
        for v in [0, 1, -1, 63, -64, 64, 1 << 40, i64::MAX, i64::MIN] {
            w.signed_varint(v);
        }
        w.varint(u64::MAX);
        let bytes = w.into_bytes();
        // one byte for magnitudes under 64, ten for the extremes
        assert_eq!(bytes[..5], [0, 2, 1, 126, 127]);
        let mut r = Reader::new(&bytes, "test");
        for v in [0, 1, -1, 63, -64, 64, 1 << 40, i64::MAX, i64::MIN] {
            assert_eq!(r.signed_varint().unwrap(), v);
        }
        assert_eq!(r.varint().unwrap(), u64::MAX);
        r.finish().unwrap();
        // eleven continuation bytes overflow 64 bits; a cut-off varint is an error
        assert!(Reader::new(&[0xff; 11], "test").varint().is_err());
        assert!(Reader::new(&[0x80], "test").varint().is_err());
        let nan = f64::NAN.to_le_bytes();
        assert!(Reader::new(&nan, "test").f64().is_err());
    }
}
