//! What a map file holds, as `slamkit map info` shows it: the file read, checked and decoded
//! as a session loading it would, and timed.

use super::{peek_version, MapFile, MapHeader, Rig};
use crate::lidar::LidarMap;
use crate::SlamError;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A map file's description; its JSON is `slamkit map info --json`'s.
#[derive(Debug, Clone, Serialize)]
pub struct MapInfo {
    /// The file.
    pub file: PathBuf,
    /// Format version, `MAJOR.MINOR`.
    pub format_version: String,
    /// The header's fields (rig, slamkit version, creation time, keyframes, extent, units,
    /// frames, notes).
    #[serde(flatten)]
    pub header: MapHeader,
    /// Pose-graph edges of a 2D lidar map.
    pub edges: Option<usize>,
    /// Scans of a 2D lidar map.
    pub scans: Option<usize>,
    /// Size of the file \[bytes\].
    pub file_bytes: u64,
    /// Time to read, check and decode the whole map \[s\].
    pub load_seconds: f64,
    /// The sections in file order: tag and bytes.
    pub sections: Vec<SectionInfo>,
}

/// One section of a [`MapInfo`].
#[derive(Debug, Clone, Serialize)]
pub struct SectionInfo {
    /// The four-letter tag.
    pub tag: String,
    /// Bytes of its (uncompressed) data.
    pub bytes: usize,
}

impl MapInfo {
    /// Reads, checks and decodes `path`.
    ///
    /// # Errors
    /// [`SlamError::MapFile`] naming the file for one that cannot be read or is damaged.
    pub fn read(path: &Path) -> Result<Self, SlamError> {
        let started = Instant::now();
        let wrap = |source| SlamError::MapFile {
            path: path.to_path_buf(),
            source,
        };
        let bytes = std::fs::read(path).map_err(|e| wrap(e.into()))?;
        let map = MapFile::from_bytes(&bytes).map_err(wrap)?;
        let lidar = match map.header.rig {
            Rig::Lidar2d => Some(LidarMap::from_file(&map).map_err(wrap)?),
            _ => None,
        };
        let (major, minor) = peek_version(&bytes).unwrap_or_default();
        Ok(Self {
            file: path.to_path_buf(),
            format_version: format!("{major}.{minor}"),
            edges: lidar.as_ref().map(|m| m.edges.len()),
            scans: lidar.as_ref().map(|m| m.scans.len()),
            file_bytes: bytes.len() as u64,
            load_seconds: started.elapsed().as_secs_f64(),
            sections: map
                .sections
                .iter()
                .map(|s| SectionInfo {
                    tag: String::from_utf8_lossy(&s.tag).into(),
                    bytes: s.data.len(),
                })
                .collect(),
            header: map.header,
        })
    }
}

impl std::fmt::Display for MapInfo {
    /// `slamkit map info`'s text: the file, then one aligned `label value` line per fact.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let h = &self.header;
        writeln!(f, "{}", self.file.display())?;
        let (format, version) = (&self.format_version, &h.slamkit_version);
        writeln!(f, "  format      {format} (slamkit {version})")?;
        writeln!(f, "  rig         {}", h.rig)?;
        writeln!(f, "  created     {}", h.created_utc())?;
        writeln!(f, "  keyframes   {}", h.keyframes)?;
        if let (Some(edges), Some(scans)) = (self.edges, self.scans) {
            writeln!(f, "  edges       {edges}")?;
            writeln!(f, "  scans       {scans}")?;
        }
        if let Some([x0, y0, x1, y1]) = h.extent_m {
            let (w, d) = (x1 - x0, y1 - y0);
            writeln!(
                f,
                "  extent      x {x0:.2} .. {x1:.2} m, y {y0:.2} .. {y1:.2} m ({w:.1} × {d:.1} m)"
            )?;
        }
        writeln!(f, "  size        {:.2} MB", self.file_bytes as f64 / 1e6)?;
        writeln!(f, "  loaded in   {:.3} s", self.load_seconds)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn describes_what_the_file_holds() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cam.skmap");
        let file = MapFile {
            header: MapHeader::new(Rig::Stereo, 3, Some([0.0, -1.0, 2.0, 1.0])),
            sections: vec![super::super::Section {
                tag: *b"KEYF",
                data: vec![7; 100],
            }],
        };
        file.save(&path).unwrap();
        let info = MapInfo::read(&path).unwrap();
        assert_eq!(info.format_version, "1.0");
        assert_eq!(
            (info.header.keyframes, info.edges, info.scans),
            (3, None, None)
        );
        assert_eq!(info.sections.len(), 1);
        assert_eq!(
            (info.sections[0].tag.as_str(), info.sections[0].bytes),
            ("KEYF", 100)
        );
        assert_eq!(info.file_bytes, std::fs::metadata(&path).unwrap().len());
        let json = serde_json::to_value(&info).unwrap();
        assert_eq!(json["rig"], "stereo");
        assert_eq!(json["extent_m"][3], 1.0);
        let text = info.to_string();
        assert!(text.contains("  keyframes   3\n"), "{text}");
        assert!(text.contains("(2.0 × 2.0 m)"), "{text}");
    }

    #[test]
    fn a_damaged_file_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.skmap");
        std::fs::write(&path, b"not a map").unwrap();
        let err = MapInfo::read(&path).unwrap_err().to_string();
        assert!(err.contains("bad.skmap"), "{err}");
    }
}
