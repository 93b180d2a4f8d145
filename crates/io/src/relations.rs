//! Ground-truth relations of the 2D SLAM benchmark (`*.relations`).
//!
//! Kümmerle et al., "On measuring the accuracy of SLAM algorithms", Autonomous Robots 27(4),
//! 2009, score a SLAM estimate by the relative motions between pairs of scan times, manually
//! verified from the aligned scans. Each line is `t1 t2 x y z roll pitch yaw`: the motion from
//! the pose at `t1` to the pose at `t2`, in the frame of the pose at `t1` (m, rad; z, roll and
//! pitch are 0 in the 2D logs). `t1` and `t2` equal laser timestamps of the log exactly. A
//! `#` header line may come first. Being ground truth, a malformed line is an error, not
//! skipped.

use crate::error::read_text;
use crate::IoError;
use nalgebra::{Translation3, UnitQuaternion};
use slamkit_core::Pose3;
use std::path::Path;

/// One ground-truth relative motion between two scan times.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relation {
    /// Time of the first pose \[s\].
    pub t1: f64,
    /// Time of the second pose \[s\].
    pub t2: f64,
    /// Motion from the pose at `t1` to the pose at `t2`, in the frame of the first.
    pub t1_from_t2: Pose3,
}

/// Parses relations text; errors name the line (file `<input>`).
pub fn parse_relations(text: &str) -> Result<Vec<Relation>, IoError> {
    parse_relations_named(text, "<input>")
}

/// Reads a `.relations` file; errors name the file and line.
pub fn read_relations(path: &Path) -> Result<Vec<Relation>, IoError> {
    parse_relations_named(&read_text(path)?, &path.display().to_string())
}

/// The benchmark's relations file beside a log, when it exists: `<stem>.relations` in the log's
/// folder, the stem being the name up to its first dot (`intel.fromrosbag.clf.gz` →
/// `intel.relations`).
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// let log = dir.path().join("intel.fromrosbag.clf.gz");
/// assert_eq!(slamkit_io::relations::beside_log(&log), None);
/// std::fs::write(dir.path().join("intel.relations"), "").unwrap();
/// assert_eq!(slamkit_io::relations::beside_log(&log), Some(dir.path().join("intel.relations")));
/// ```
pub fn beside_log(log: &Path) -> Option<std::path::PathBuf> {
    let name = log.file_name()?.to_str()?;
    let stem = name.split('.').next()?;
    let candidate = log.with_file_name(format!("{stem}.relations"));
    candidate.exists().then_some(candidate)
}

fn parse_relations_named(text: &str, file: &str) -> Result<Vec<Relation>, IoError> {
    let mut relations = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let values = parse_numbers(line)
            .ok_or_else(|| IoError::parse(file, i + 1, "expected 8 finite numbers"))?;
        let [t1, t2, x, y, z, roll, pitch, yaw] = values;
        relations.push(Relation {
            t1,
            t2,
            t1_from_t2: Pose3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_euler_angles(roll, pitch, yaw),
            ),
        });
    }
    if relations.is_empty() {
        return Err(IoError::Empty {
            file: file.to_string(),
            what: "relations".into(),
        });
    }
    Ok(relations)
}

/// Exactly `N` finite numbers separated by white space.
pub(crate) fn parse_numbers<const N: usize>(line: &str) -> Option<[f64; N]> {
    let mut values = [0.0; N];
    let mut tokens = line.split_ascii_whitespace();
    for v in values.iter_mut() {
        *v = tokens
            .next()?
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())?;
    }
    tokens.next().is_none().then_some(values)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_header_and_yaw() {
        let text = "# timestamp1 timestamp2 x y z roll pitch yaw\n\
                    976052857.337530 976052858.341312 0.5 -0.1 0 0 0 1.5707963\n";
        let r = parse_relations(text).unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].t1, 976052857.337530);
        let p = r[0].t1_from_t2 * nalgebra::Point3::new(1.0, 0.0, 0.0);
        assert!(
            (p - nalgebra::Point3::new(0.5, 0.9, 0.0)).norm() < 1e-6,
            "{p}"
        );
    }

    #[test]
    fn malformed_lines_name_the_line() {
        for bad in [
            "1 2 3 4 5 6 7",
            "1 2 3 4 5 6 7 8 9",
            "1 2 3 NaN 5 6 7 8",
            "1 2 x 4 5 6 7 8",
        ] {
            let text = format!("1 2 0 0 0 0 0 0\n{bad}\n");
            match parse_relations(&text) {
                Err(IoError::Parse { line, .. }) => assert_eq!(line, 2),
                other => panic!("{bad}: {other:?}"),
            }
        }
        assert!(matches!(
            parse_relations("# only\n"),
            Err(IoError::Empty { .. })
        ));
        let missing = read_relations(Path::new("/nonexistent.relations"));
        assert!(matches!(missing, Err(IoError::Io { .. })));
    }
}
