//! The two wire formats of ROS messages, behind one interface the message model reads
//! through: ROS 1 serialisation ([`super::ros1::Cursor`]) and ROS 2's CDR
//! ([`super::cdr::CdrCursor`]). A message type is written once, as a sequence of [`Wire`]
//! reads, and decodes from either; the only layout differences between the two for the types
//! slamkit reads are ROS 1's `seq` in `std_msgs/Header` and the signedness of a time's
//! seconds, which [`Wire::header_seq`] and [`Wire::time`] carry.

use super::record::RosTime;

pub use super::ros1::DecodeError;

/// How a connection's messages are serialised.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Serialization {
    /// ROS 1 serialisation (a `.bag`).
    Ros1,
    /// CDR (XCDR1), ROS 2's serialisation.
    Cdr,
    /// Another encoding (named), which slamkit does not decode.
    Other(String),
}

/// The primitive reads a message is made of.
pub trait Wire {
    /// `std_msgs/Header`'s `seq`: read in ROS 1, absent (`None`) in ROS 2.
    fn header_seq(&mut self) -> Result<Option<u32>, DecodeError>;
    /// A `uint8` (or `bool`).
    fn u8(&mut self) -> Result<u8, DecodeError>;
    /// A `uint32`.
    fn u32(&mut self) -> Result<u32, DecodeError>;
    /// A `float32`.
    fn f32(&mut self) -> Result<f32, DecodeError>;
    /// A `float64`.
    fn f64(&mut self) -> Result<f64, DecodeError>;
    /// A `time` (ROS 1) or `builtin_interfaces/Time` (ROS 2; negative seconds are an error).
    fn time(&mut self) -> Result<RosTime, DecodeError>;
    /// A `string` (UTF-8 checked).
    fn string(&mut self) -> Result<String, DecodeError>;
    /// The count of a variable-length array of `elem_bytes`-byte elements, checked against
    /// the bytes left before anything is allocated.
    fn count(&mut self, elem_bytes: usize) -> Result<usize, DecodeError>;
    /// `n` raw bytes (the body of a `uint8[]`).
    fn bytes(&mut self, n: usize) -> Result<Vec<u8>, DecodeError>;
    /// Fails unless the message used its bytes (CDR allows up to 3 bytes of end padding).
    fn finish(&self) -> Result<(), DecodeError>;

    /// A `float32[]`.
    fn f32_array(&mut self) -> Result<Vec<f32>, DecodeError> {
        let n = self.count(4)?;
        (0..n).map(|_| self.f32()).collect()
    }

    /// A `float64[]`.
    fn f64_array(&mut self) -> Result<Vec<f64>, DecodeError> {
        let n = self.count(8)?;
        (0..n).map(|_| self.f64()).collect()
    }

    /// A `uint8[]`.
    fn u8_array(&mut self) -> Result<Vec<u8>, DecodeError> {
        let n = self.count(1)?;
        self.bytes(n)
    }

    /// A `float64[N]` of fixed length.
    fn f64_fixed<const N: usize>(&mut self) -> Result<[f64; N], DecodeError> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64()?;
        }
        Ok(out)
    }
}
