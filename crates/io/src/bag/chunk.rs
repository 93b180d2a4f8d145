//! Chunks: the records of a bag's data section stored plain (`none`), bzip2- (`bz2`) or
//! LZ4-frame-compressed (`lz4`, roslz4's frames), each with its decompressed `size` in the
//! header. Decompression is bounded by that size, so a forged size cannot exhaust memory
//! beyond [`MAX_CHUNK_BYTES`], and a chunk that decompresses to another size is refused.

use super::record::{Fields, RecordError};
use std::io::Read;

/// Largest decompressed chunk accepted \[bytes\]; rosbag's default chunk is 768 KiB, and
/// `rosbag record --chunksize` takes at most a few MiB in practice.
pub const MAX_CHUNK_BYTES: u32 = 1 << 30;

/// The compression of a chunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Compression {
    /// Stored as is.
    None,
    /// bzip2.
    Bz2,
    /// LZ4 frames.
    Lz4,
    /// Zstandard (MCAP chunks of ROS 2 bags).
    Zstd,
}

impl Compression {
    /// The compression a chunk header's `compression` field names.
    pub fn parse(name: &str) -> Result<Self, RecordError> {
        match name {
            "none" => Ok(Self::None),
            "bz2" => Ok(Self::Bz2),
            "lz4" => Ok(Self::Lz4),
            other => Err(RecordError::Malformed(format!(
                "unknown chunk compression {:?} (ROS 1 bags use none, bz2 or lz4)",
                other.chars().take(16).collect::<String>()
            ))),
        }
    }
}

/// The records of a chunk record (`header`, `data`) as plain bytes.
///
/// ```
/// use slamkit_io::bag::chunk::decompress;
/// use slamkit_io::bag::record::Fields;
///
/// let mut header = Vec::new();
/// for field in [&b"compression=none"[..], b"size=\x03\x00\x00\x00"] {
///     header.extend_from_slice(&(field.len() as u32).to_le_bytes());
///     header.extend_from_slice(field);
/// }
/// let fields = Fields::parse(&header)?;
/// assert_eq!(decompress(&fields, b"abc")?, b"abc");
/// assert!(decompress(&fields, b"abcd").is_err()); // not the size the header says
/// # Ok::<(), slamkit_io::bag::record::RecordError>(())
/// ```
pub fn decompress(header: &Fields, data: &[u8]) -> Result<Vec<u8>, RecordError> {
    let compression = Compression::parse(header.string("compression")?)?;
    let size = header.u32("size")?;
    if size > MAX_CHUNK_BYTES {
        return Err(RecordError::Malformed(format!(
            "chunk claims {size} bytes, more than the {MAX_CHUNK_BYTES} accepted"
        )));
    }
    decompress_exact(compression, data, u64::from(size))
}

/// `data` decompressed to exactly `size` bytes (ROS 1 and MCAP chunks alike); more or fewer is
/// an error, and no more than `size + 1` bytes are ever produced.
pub(crate) fn decompress_exact(
    compression: Compression,
    data: &[u8],
    size: u64,
) -> Result<Vec<u8>, RecordError> {
    let out = match compression {
        Compression::None => data.to_vec(),
        Compression::Bz2 => read_bounded(bzip2::read::BzDecoder::new(data), size, "bz2")?,
        Compression::Lz4 => read_bounded(lz4_flex::frame::FrameDecoder::new(data), size, "lz4")?,
        Compression::Zstd => {
            let decoder = ruzstd::decoding::StreamingDecoder::new(data).map_err(|e| {
                RecordError::Malformed(format!("zstd chunk cannot be decompressed: {e}"))
            })?;
            read_bounded(decoder, size, "zstd")?
        }
    };
    if out.len() as u64 != size {
        return Err(RecordError::Malformed(format!(
            "chunk holds {} bytes once decompressed, its header says {size}",
            out.len()
        )));
    }
    Ok(out)
}

/// Reads at most `size + 1` bytes from the decoder (one more shows a size mismatch).
fn read_bounded<R: Read>(decoder: R, size: u64, name: &str) -> Result<Vec<u8>, RecordError> {
    let mut out = Vec::with_capacity((size as usize).min(1 << 24));
    decoder
        .take(size + 1)
        .read_to_end(&mut out)
        .map_err(|e| RecordError::Malformed(format!("{name} chunk cannot be decompressed: {e}")))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn header(compression: &str, size: u32) -> Vec<u8> {
        let mut h = Vec::new();
        let c = format!("compression={compression}");
        let mut s = b"size=".to_vec();
        s.extend_from_slice(&size.to_le_bytes());
        for f in [c.as_bytes(), &s] {
            h.extend_from_slice(&(f.len() as u32).to_le_bytes());
            h.extend_from_slice(f);
        }
        h
    }

    #[test]
    fn bz2_and_lz4_round_trip_and_damage_is_an_error() {
        let plain: Vec<u8> = (0..5000u32).flat_map(|i| (i % 251).to_le_bytes()).collect();
        let mut bz = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::default());
        bz.write_all(&plain).unwrap();
        let bz = bz.finish().unwrap();
        let mut lz = lz4_flex::frame::FrameEncoder::new(Vec::new());
        lz.write_all(&plain).unwrap();
        let lz = lz.finish().unwrap();
        let n = plain.len() as u32;
        for (name, bytes) in [("bz2", &bz), ("lz4", &lz)] {
            let h = header(name, n);
            let f = Fields::parse(&h).unwrap();
            assert_eq!(decompress(&f, bytes).unwrap(), plain, "{name}");
            let short = header(name, n - 1);
            let err = decompress(&Fields::parse(&short).unwrap(), bytes).unwrap_err();
            assert!(err.to_string().contains("says"), "{name}: {err}");
            let cut = decompress(&f, &bytes[..bytes.len() / 2]);
            assert!(cut.is_err(), "{name}");
        }
        let mut flipped = bz.clone();
        flipped[bz.len() / 2] ^= 0x10;
        let f = header("bz2", n);
        assert!(decompress(&Fields::parse(&f).unwrap(), &flipped).is_err());
        let zstd = header("zstd", 3);
        assert!(decompress(&Fields::parse(&zstd).unwrap(), b"abc")
            .unwrap_err()
            .to_string()
            .contains("unknown chunk compression"));
    }
}
