//! The map file (`.skmap`): one self-describing, versioned file per map.
//!
//! ```text
//! magic        8 bytes   \x89 S K M A P \r \n   (the PNG trick: a text-mode copy or a 7-bit
//!                                                channel breaks it visibly)
//! version      u16 major, u16 minor              a reader refuses a newer major version
//! header       u32 length + JSON                 MapHeader: rig, units, frames, creation time,
//!                                                slamkit version, keyframes, extent
//! sections     u32 count, then per section:      tag (4 ASCII bytes), u64 raw length,
//!                                                u64 stored length, deflate-compressed bytes
//! checksum     u32                               CRC-32 of every byte before it
//! ```
//!
//! Sections hold what a session needs to localise in the map or continue it (keyframes, the
//! pose graph); grids and likelihood fields are rebuilt on load, so the file stays small. Each
//! session documents its own sections ([`crate::lidar::map`] for 2D lidar). A reader checks, in
//! this order, the magic, the version and the checksum before it parses anything, so a
//! truncated or bit-flipped file gives one clear error and never a panic. Writes go to a
//! temporary file beside the target that is renamed over it once complete and synced: a crash
//! leaves the old map or the new one, never half of one.
//! [`info`] describes a file (`slamkit map info`).

pub mod codec;
pub mod export;
pub mod info;

use flate2::read::DeflateDecoder;
use flate2::write::DeflateEncoder;
use flate2::Compression;
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};
use std::path::Path;

/// The first bytes of every map file.
pub const MAGIC: [u8; 8] = *b"\x89SKMAP\r\n";
/// Format version written; files of a newer major version are refused.
pub const FORMAT_VERSION: (u16, u16) = (1, 0);
/// Sections larger than this once decompressed are refused (a corrupt length, not a map).
const MAX_SECTION_BYTES: u64 = 1 << 32;
/// Headers longer than this are refused.
const MAX_HEADER_BYTES: usize = 1 << 20;

/// The robot rig a map was built with; a session refuses a map of another rig.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Rig {
    /// A planar lidar, with or without wheel odometry.
    Lidar2d,
    /// A drone: planar lidar and up/down range finders, one map per height layer.
    Drone,
    /// An RGB-D camera.
    Rgbd,
    /// A stereo camera.
    Stereo,
}

impl std::fmt::Display for Rig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Rig::Lidar2d => "lidar2d",
            Rig::Drone => "drone",
            Rig::Rgbd => "rgbd",
            Rig::Stereo => "stereo",
        })
    }
}

/// What a map file says about itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapHeader {
    /// The rig the map was built with.
    pub rig: Rig,
    /// Units of every quantity in the file.
    pub units: String,
    /// The frames the poses relate.
    pub frames: String,
    /// When the map was written \[s since 1970-01-01 UTC\].
    pub created_unix_s: u64,
    /// Version of the slamkit that wrote it.
    pub slamkit_version: String,
    /// Keyframes in the map.
    pub keyframes: usize,
    /// Bounding box of the keyframe poses and points, `[min x, min y, max x, max y]` \[m\]
    /// (`None` for an empty map).
    pub extent_m: Option<[f64; 4]>,
    /// Free-form facts about how the map was made (method, settings, input), for people.
    #[serde(default)]
    pub notes: serde_json::Value,
}

impl MapHeader {
    /// A header for a map of `rig` written now by this slamkit, with `keyframes` and `extent_m`.
    pub fn new(rig: Rig, keyframes: usize, extent_m: Option<[f64; 4]>) -> Self {
        let created_unix_s = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        Self {
            rig,
            units: "metres, radians, seconds".into(),
            frames: "map_from_base (keyframe poses); points in the keyframe's base frame".into(),
            created_unix_s,
            slamkit_version: env!("CARGO_PKG_VERSION").into(),
            keyframes,
            extent_m,
            notes: serde_json::Value::Null,
        }
    }

    /// The creation time as `YYYY-MM-DD HH:MM:SS UTC` (the civil-from-days algorithm of
    /// Howard Hinnant's date library; no time-zone database needed).
    ///
    /// ```
    /// use slamkit_slam::map_file::{MapHeader, Rig};
    /// let mut header = MapHeader::new(Rig::Lidar2d, 0, None);
    /// header.created_unix_s = 951_782_400;
    /// assert_eq!(header.created_utc(), "2000-02-29 00:00:00 UTC");
    /// ```
    pub fn created_utc(&self) -> String {
        let unix_s = self.created_unix_s;
        let days = (unix_s / 86_400) as i64;
        let secs = unix_s % 86_400;
        let z = days + 719_468;
        let era = z.div_euclid(146_097);
        let doe = z.rem_euclid(146_097);
        let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
        let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
        let mp = (5 * doy + 2) / 153;
        let day = doy - (153 * mp + 2) / 5 + 1;
        let month = if mp < 10 { mp + 3 } else { mp - 9 };
        let year = yoe + era * 400 + i64::from(month <= 2);
        format!(
            "{year:04}-{month:02}-{day:02} {:02}:{:02}:{:02} UTC",
            secs / 3600,
            secs / 60 % 60,
            secs % 60
        )
    }
}

/// One named block of a map file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Section {
    /// Four ASCII bytes naming the content.
    pub tag: [u8; 4],
    /// The content (stored compressed).
    pub data: Vec<u8>,
}

/// A whole map file in memory.
#[derive(Debug, Clone, PartialEq)]
pub struct MapFile {
    /// What the file says about itself.
    pub header: MapHeader,
    /// The content, in file order.
    pub sections: Vec<Section>,
}

/// Why a map file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum MapFileError {
    /// The file system refused.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The file does not start with the map file's magic bytes.
    #[error("not a slamkit map file (it does not start with the .skmap magic bytes)")]
    NotAMap,
    /// The file is shorter than its fixed parts.
    #[error("truncated: {0} bytes is too short for a map file")]
    TooShort(usize),
    /// Written by a newer slamkit with an incompatible format.
    #[error("format version {0}.{1} is newer than this slamkit reads ({2}.x); update slamkit")]
    NewerVersion(u16, u16, u16),
    /// The checksum does not match: the file was truncated or corrupted.
    #[error("checksum mismatch (stored {stored:08x}, computed {computed:08x}): the file is truncated or corrupted")]
    Checksum {
        /// Checksum at the end of the file.
        stored: u32,
        /// Checksum of the bytes read.
        computed: u32,
    },
    /// The content is not what the format allows.
    #[error("malformed: {0}")]
    Malformed(String),
    /// The map was built with another rig.
    #[error("the map was built for a {found} rig, not {expected}")]
    WrongRig {
        /// The rig the reader wanted.
        expected: Rig,
        /// The rig in the file.
        found: Rig,
    },
    /// A section the reader needs is missing.
    #[error("no {0} section")]
    MissingSection(String),
}

impl MapFile {
    /// The data of the first section tagged `tag`.
    pub fn section(&self, tag: &[u8; 4]) -> Result<&[u8], MapFileError> {
        self.sections
            .iter()
            .find(|s| &s.tag == tag)
            .map(|s| s.data.as_slice())
            .ok_or_else(|| MapFileError::MissingSection(String::from_utf8_lossy(tag).into()))
    }

    /// Fails unless the map was built with `rig`.
    pub fn expect_rig(&self, rig: Rig) -> Result<(), MapFileError> {
        if self.header.rig == rig {
            Ok(())
        } else {
            Err(MapFileError::WrongRig {
                expected: rig,
                found: self.header.rig,
            })
        }
    }

    /// The file's bytes.
    pub fn to_bytes(&self) -> Result<Vec<u8>, MapFileError> {
        let mut w = codec::Writer::new();
        w.bytes(&MAGIC);
        w.bytes(&FORMAT_VERSION.0.to_le_bytes());
        w.bytes(&FORMAT_VERSION.1.to_le_bytes());
        let header = serde_json::to_vec(&self.header)
            .map_err(|e| MapFileError::Malformed(format!("header: {e}")))?;
        w.len(header.len())?;
        w.bytes(&header);
        w.len(self.sections.len())?;
        for section in &self.sections {
            let mut encoder = DeflateEncoder::new(Vec::new(), Compression::default());
            encoder.write_all(&section.data)?;
            let stored = encoder.finish()?;
            w.bytes(&section.tag);
            w.u64(section.data.len() as u64);
            w.u64(stored.len() as u64);
            w.bytes(&stored);
        }
        let mut bytes = w.into_bytes();
        let crc = crc32fast::hash(&bytes);
        bytes.extend_from_slice(&crc.to_le_bytes());
        Ok(bytes)
    }

    /// Parses a map file's bytes: magic, version and checksum first, then the content.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, MapFileError> {
        let fixed = MAGIC.len() + 4 + 4 + 4 + 4;
        if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
            return Err(MapFileError::NotAMap);
        }
        if bytes.len() < fixed {
            return Err(MapFileError::TooShort(bytes.len()));
        }
        let (body, crc) = bytes.split_at(bytes.len() - 4);
        let mut r = codec::Reader::new(&body[MAGIC.len()..], "the file");
        let version = r.take(4)?;
        let major = u16::from_le_bytes([version[0], version[1]]);
        let minor = u16::from_le_bytes([version[2], version[3]]);
        if major > FORMAT_VERSION.0 {
            return Err(MapFileError::NewerVersion(major, minor, FORMAT_VERSION.0));
        }
        let stored = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
        let computed = crc32fast::hash(body);
        if stored != computed {
            return Err(MapFileError::Checksum { stored, computed });
        }
        let header_len = r.len(1)?;
        if header_len > MAX_HEADER_BYTES {
            return Err(MapFileError::Malformed("the header is too long".into()));
        }
        let header: MapHeader = serde_json::from_slice(r.take(header_len)?)
            .map_err(|e| MapFileError::Malformed(format!("header: {e}")))?;
        let count = r.len(20)?;
        let mut sections = Vec::with_capacity(count);
        for _ in 0..count {
            let mut tag = [0u8; 4];
            tag.copy_from_slice(r.take(4)?);
            let raw_len = r.u64()?;
            let stored_len = r.u64()?;
            if raw_len > MAX_SECTION_BYTES || stored_len > r.remaining() as u64 {
                return Err(MapFileError::Malformed(format!(
                    "section {} claims more bytes than the file holds",
                    String::from_utf8_lossy(&tag)
                )));
            }
            let stored = r.take(stored_len as usize)?;
            let mut data = Vec::new();
            DeflateDecoder::new(stored)
                .take(raw_len + 1)
                .read_to_end(&mut data)
                .map_err(|e| {
                    MapFileError::Malformed(format!(
                        "section {}: {e}",
                        String::from_utf8_lossy(&tag)
                    ))
                })?;
            if data.len() as u64 != raw_len {
                return Err(MapFileError::Malformed(format!(
                    "section {} decompresses to {} bytes, not {raw_len}",
                    String::from_utf8_lossy(&tag),
                    data.len()
                )));
            }
            sections.push(Section { tag, data });
        }
        r.finish()?;
        Ok(Self { header, sections })
    }

    /// Writes the file atomically: to a temporary file beside `path`, synced, then renamed over
    /// `path`.
    pub fn save(&self, path: &Path) -> Result<(), MapFileError> {
        let bytes = self.to_bytes()?;
        write_atomically(path, &bytes)?;
        Ok(())
    }

    /// Reads and checks a map file.
    pub fn load(path: &Path) -> Result<Self, MapFileError> {
        Self::from_bytes(&std::fs::read(path)?)
    }
}

/// True for a path naming a slamkit map file (extension `.skmap`, any case): what a program
/// that also takes other maps (a ROS map_server YAML) checks to choose the reader.
///
/// ```
/// use slamkit_slam::map_file::is_skmap;
/// use std::path::Path;
/// assert!(is_skmap(Path::new("office.SKMAP")));
/// assert!(!is_skmap(Path::new("office.yaml")));
/// ```
pub fn is_skmap(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("skmap"))
}

/// The format version a map file's bytes declare, when they start with the magic bytes.
pub fn peek_version(bytes: &[u8]) -> Option<(u16, u16)> {
    let head = bytes.get(..MAGIC.len() + 4)?;
    if head[..MAGIC.len()] != MAGIC {
        return None;
    }
    let v = &head[MAGIC.len()..];
    Some((
        u16::from_le_bytes([v[0], v[1]]),
        u16::from_le_bytes([v[2], v[3]]),
    ))
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename (the one
/// helper every output of slamkit goes through).
pub use slamkit_io::output_folder::write_atomically;

#[cfg(test)]
mod tests;
