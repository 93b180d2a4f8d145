//! ROS 2's CDR serialisation (OMG XCDR version 1, the encoding of `rmw_fastrtps`,
//! `rmw_cyclonedds` and rosbag2), read. A serialised message starts with a 4-byte
//! encapsulation header: `00 00` big-endian or `00 01` little-endian plain CDR, then two
//! option bytes. The body follows; every primitive is aligned to its own size (1, 2, 4 or 8
//! bytes) counted from the start of the body, strings are a `u32` length that includes a
//! terminating NUL, then the bytes and the NUL; sequences are a `u32` count then the
//! elements; fixed arrays have no count. A message may end with up to 3 bytes of padding.

use super::record::RosTime;
use super::wire::{DecodeError, Wire};

/// A read position in one CDR-serialised message.
#[derive(Debug, Clone)]
pub struct CdrCursor<'a> {
    /// The body (after the encapsulation header): alignment is counted from its start.
    body: &'a [u8],
    pos: usize,
    little_endian: bool,
}

impl<'a> CdrCursor<'a> {
    /// A cursor at the start of a message's body, its encapsulation header checked.
    ///
    /// ```
    /// use slamkit_io::bag::cdr::CdrCursor;
    /// use slamkit_io::bag::wire::Wire;
    ///
    /// // little endian; a u8 then a u32, which is aligned to 4 bytes
    /// let bytes = [0, 1, 0, 0, 7, 0xAA, 0xAA, 0xAA, 5, 0, 0, 0];
    /// let mut c = CdrCursor::new(&bytes)?;
    /// assert_eq!((c.u8()?, c.u32()?), (7, 5));
    /// c.finish()?;
    /// assert!(CdrCursor::new(&[0, 7, 0, 0]).is_err()); // XCDR2: not read
    /// # Ok::<(), slamkit_io::bag::wire::DecodeError>(())
    /// ```
    pub fn new(bytes: &'a [u8]) -> Result<Self, DecodeError> {
        let err = |what: String| DecodeError { offset: 0, what };
        let Some(head) = bytes.get(..4) else {
            return Err(err(format!(
                "{} bytes: too short for the CDR encapsulation header",
                bytes.len()
            )));
        };
        let little_endian = match (head[0], head[1]) {
            (0, 0) => false,
            (0, 1) => true,
            (a, b) => {
                return Err(err(format!(
                    "encapsulation {a:02x} {b:02x} is not plain CDR (00 00 or 00 01); \
                     XCDR2 and parameter lists are not read"
                )))
            }
        };
        Ok(Self {
            body: &bytes[4..],
            pos: 0,
            little_endian,
        })
    }

    fn error(&self, what: impl Into<String>) -> DecodeError {
        DecodeError {
            // offsets in errors count the encapsulation header, as a hex dump would
            offset: self.pos + 4,
            what: what.into(),
        }
    }

    fn align(&mut self, n: usize) -> Result<(), DecodeError> {
        let pad = (n - self.pos % n) % n;
        if self.pos + pad > self.body.len() {
            return Err(self.error("message ends inside alignment padding"));
        }
        self.pos += pad;
        Ok(())
    }

    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], DecodeError> {
        self.align(N)?;
        let b = self
            .body
            .get(self.pos..self.pos + N)
            .and_then(|b| <[u8; N]>::try_from(b).ok())
            .ok_or_else(|| self.error(format!("message ends inside a {what}")))?;
        self.pos += N;
        Ok(b)
    }

    fn i32(&mut self) -> Result<i32, DecodeError> {
        let b = self.take("int32")?;
        Ok(if self.little_endian {
            i32::from_le_bytes(b)
        } else {
            i32::from_be_bytes(b)
        })
    }
}

impl Wire for CdrCursor<'_> {
    fn header_seq(&mut self) -> Result<Option<u32>, DecodeError> {
        Ok(None)
    }

    fn u8(&mut self) -> Result<u8, DecodeError> {
        self.take::<1>("uint8").map(|b| b[0])
    }

    fn u32(&mut self) -> Result<u32, DecodeError> {
        let b = self.take("uint32")?;
        Ok(if self.little_endian {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }

    fn f32(&mut self) -> Result<f32, DecodeError> {
        self.u32().map(f32::from_bits)
    }

    fn f64(&mut self) -> Result<f64, DecodeError> {
        let b = self.take("float64")?;
        Ok(f64::from_bits(if self.little_endian {
            u64::from_le_bytes(b)
        } else {
            u64::from_be_bytes(b)
        }))
    }

    fn time(&mut self) -> Result<RosTime, DecodeError> {
        let sec = self.i32()?;
        let nsec = self.u32()?;
        let sec = u32::try_from(sec)
            .map_err(|_| self.error(format!("time has negative seconds ({sec})")))?;
        Ok(RosTime { sec, nsec })
    }

    fn string(&mut self) -> Result<String, DecodeError> {
        let n = self.count(1)?;
        if n == 0 {
            // some writers send an empty string as a bare zero length
            return Ok(String::new());
        }
        let bytes = &self.body[self.pos..self.pos + n];
        let Some((&0, text)) = bytes.split_last() else {
            return Err(self.error("string lacks its terminating NUL"));
        };
        let s = std::str::from_utf8(text).map_err(|_| self.error("string is not UTF-8"))?;
        self.pos += n;
        Ok(s.to_string())
    }

    fn count(&mut self, elem_bytes: usize) -> Result<usize, DecodeError> {
        let n = self.u32()? as usize;
        let left = self.body.len() - self.pos;
        if n.saturating_mul(elem_bytes.max(1)) > left {
            return Err(self.error(format!(
                "array of {n} elements of {elem_bytes} bytes, only {left} bytes left"
            )));
        }
        Ok(n)
    }

    fn bytes(&mut self, n: usize) -> Result<Vec<u8>, DecodeError> {
        let b = self
            .body
            .get(self.pos..self.pos.saturating_add(n))
            .ok_or_else(|| self.error(format!("message ends inside {n} bytes of data")))?;
        self.pos += n;
        Ok(b.to_vec())
    }

    fn finish(&self) -> Result<(), DecodeError> {
        let left = self.body.len() - self.pos;
        if left <= 3 {
            Ok(())
        } else {
            Err(self.error(format!(
                "{left} bytes left over after the message (not the type the topic names?)"
            )))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bytes worked out by hand from the XCDR1 rules: a u8, a f64 (aligned to 8 from the
    /// body's start), a string "ab" (u32 length 3 with its NUL), a u32 sequence count 2 and
    /// two f32s, in both byte orders.
    #[test]
    fn alignment_strings_and_sequences_in_both_byte_orders() {
        let le: Vec<u8> = [
            &[0u8, 1, 0, 0][..],
            &[9, 0, 0, 0, 0, 0, 0, 0],
            &1.5f64.to_le_bytes(),
            &3u32.to_le_bytes(),
            b"ab\0",
            &[0],
            &2u32.to_le_bytes(),
            &0.5f32.to_le_bytes(),
            &(-2.0f32).to_le_bytes(),
        ]
        .concat();
        let be: Vec<u8> = [
            &[0u8, 0, 0, 0][..],
            &[9, 0, 0, 0, 0, 0, 0, 0],
            &1.5f64.to_be_bytes(),
            &3u32.to_be_bytes(),
            b"ab\0",
            &[0],
            &2u32.to_be_bytes(),
            &0.5f32.to_be_bytes(),
            &(-2.0f32).to_be_bytes(),
        ]
        .concat();
        for bytes in [le, be] {
            let mut c = CdrCursor::new(&bytes).unwrap();
            assert_eq!(c.u8().unwrap(), 9);
            assert_eq!(c.f64().unwrap(), 1.5);
            assert_eq!(c.string().unwrap(), "ab");
            assert_eq!(c.f32_array().unwrap(), vec![0.5, -2.0]);
            c.finish().unwrap();
        }
    }

    #[test]
    fn damage_is_an_error_not_a_panic() {
        // a string without its NUL, a count beyond the message, a negative time
        let mut s = vec![0u8, 1, 0, 0];
        s.extend_from_slice(&2u32.to_le_bytes());
        s.extend_from_slice(b"ab");
        assert!(CdrCursor::new(&s).unwrap().string().is_err());
        let mut big = vec![0u8, 1, 0, 0];
        big.extend_from_slice(&u32::MAX.to_le_bytes());
        let err = CdrCursor::new(&big).unwrap().f64_array().unwrap_err();
        assert!(err.what.contains("only 0 bytes left"), "{err}");
        let mut t = vec![0u8, 1, 0, 0];
        t.extend_from_slice(&(-1i32).to_le_bytes());
        t.extend_from_slice(&0u32.to_le_bytes());
        assert!(CdrCursor::new(&t).unwrap().time().is_err());
        // 3 bytes of end padding are accepted, 4 are not
        let mut c = CdrCursor::new(&[0, 1, 0, 0, 1, 0, 0, 0]).unwrap();
        c.u8().unwrap();
        c.finish().unwrap();
        let c = CdrCursor::new(&[0, 1, 0, 0, 1, 0, 0, 0]).unwrap();
        assert!(c.finish().is_err());
        assert!(CdrCursor::new(&[0, 1]).is_err());
    }
}
