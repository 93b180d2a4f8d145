//! A drone's non-lidar signals as CSV files: range finders, attitude and gyro, optical flow.
//!
//! Layered drone SLAM (`slamkit_slam::drone`) needs, besides the planar scans of a CARMEN log,
//! the up/down range finders, the flight controller's attitude with its gyro-integrated heading,
//! and, when the drone has one, a downward optical-flow sensor. `slamkit sim --sensors
//! lidar2d,range,imu,flow` writes them in these files, and any flight log can be converted to
//! them: one reading a line, after a header line, comma separated, SI units, in time order.
//!
//! | file | columns | units |
//! |------|---------|-------|
//! | `ranges.csv` | `timestamp,up_m,down_m` | s, m, m |
//! | `imu.csv` | `timestamp,roll_rad,pitch_rad,gyro_yaw_rad` | s, rad, rad, rad |
//! | `flow.csv` | `timestamp,integration_s,forward_mps,left_mps` | s, s, m/s, m/s |
//!
//! * `timestamp`: the sensor's time \[s\], on the same clock as the log's scans; it must not
//!   decrease from one line to the next. A reading stamped exactly at a scan's time is used for
//!   that scan.
//! * `up_m`, `down_m`: distance from the up- and down-looking range finder to the nearest
//!   surface; empty, `nan` or `inf` when the sensor saw nothing in range.
//! * `roll_rad`, `pitch_rad`: attitude of the drone's base (x forward, y left, z up), as the
//!   flight controller estimates it; `gyro_yaw_rad`: the heading integrated from the yaw-rate
//!   gyro, from any origin and not wrapped (only its change between scans is used); empty (or
//!   `nan`) when there is no gyro.
//! * `integration_s`: length of the period the flow reading averages, ending at `timestamp`;
//!   `forward_mps`, `left_mps`: the mean horizontal velocity over it in the body frame (a PX4
//!   `OPTICAL_FLOW_RAD` message's integrated flow times the distance to the ground, over its
//!   integration time); both empty (or `nan`) when the sensor saw no surface.
//!
//! Values are written in Rust's shortest round-trip form, so a file reads back bit for bit.
//! Blank lines and lines starting with `#` are skipped. A line that cannot be read (wrong
//! number of fields, a field that is not a number, a timestamp that is not finite or goes
//! back in time, a negative range, an infinite or missing attitude, heading or velocity, a
//! non-positive integration time)
//! is an error naming the file and line.

use crate::error::read_text;
use crate::IoError;
use nalgebra::Vector2;
use slamkit_core::observation::{FlowSample, ImuSample, RangePair};
use slamkit_core::Observation;
use std::fmt::Write as _;
use std::path::Path;

/// Header of `ranges.csv`.
pub const RANGES_HEADER: &str = "timestamp,up_m,down_m";
/// Header of `imu.csv`.
pub const IMU_HEADER: &str = "timestamp,roll_rad,pitch_rad,gyro_yaw_rad";
/// Header of `flow.csv`.
pub const FLOW_HEADER: &str = "timestamp,integration_s,forward_mps,left_mps";

/// Reads `ranges.csv`.
pub fn read_ranges(path: &Path) -> Result<Vec<RangePair>, IoError> {
    parse_ranges(&read_text(path)?, &path.display().to_string())
}

/// Reads `imu.csv`.
pub fn read_imu(path: &Path) -> Result<Vec<ImuSample>, IoError> {
    parse_imu(&read_text(path)?, &path.display().to_string())
}

/// Reads `flow.csv`.
pub fn read_flow(path: &Path) -> Result<Vec<FlowSample>, IoError> {
    parse_flow(&read_text(path)?, &path.display().to_string())
}

/// A drone's CSV files read as observations (not yet in time order with the scans), and how
/// many readings each file gave.
#[derive(Debug, Clone, Default)]
pub struct DroneReadings {
    /// Range pairs, then attitude samples, then flow samples.
    pub observations: Vec<Observation>,
    /// Readings per file.
    pub counts: ReadingCounts,
}

/// Readings per file of a [`DroneReadings`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ReadingCounts {
    /// Lines of `ranges.csv`.
    pub ranges: usize,
    /// Lines of `imu.csv` (0 without one).
    pub imu: usize,
    /// Lines of `flow.csv` (0 without one).
    pub flow: usize,
}

/// Reads `ranges.csv` and, when given, `imu.csv` and `flow.csv` as observations.
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// let ranges = dir.path().join("ranges.csv");
/// std::fs::write(&ranges, "timestamp,up_m,down_m\n0.1,1.5,0.8\n").unwrap();
/// let read = slamkit_io::drone_csv::read_observations(&ranges, None, None).unwrap();
/// assert_eq!((read.counts.ranges, read.counts.imu), (1, 0));
/// ```
pub fn read_observations(
    ranges: &Path,
    imu: Option<&Path>,
    flow: Option<&Path>,
) -> Result<DroneReadings, IoError> {
    let mut observations: Vec<Observation> = read_ranges(ranges)?
        .into_iter()
        .map(Observation::Range)
        .collect();
    let mut counts = ReadingCounts {
        ranges: observations.len(),
        ..ReadingCounts::default()
    };
    if let Some(path) = imu {
        let samples = read_imu(path)?;
        counts.imu = samples.len();
        observations.extend(samples.into_iter().map(Observation::Imu));
    }
    if let Some(path) = flow {
        let samples = read_flow(path)?;
        counts.flow = samples.len();
        observations.extend(samples.into_iter().map(Observation::Flow));
    }
    Ok(DroneReadings {
        observations,
        counts,
    })
}

/// Parses the text of a `ranges.csv`; `file` names it in errors.
pub fn parse_ranges(text: &str, file: &str) -> Result<Vec<RangePair>, IoError> {
    parse_rows(text, file, RANGES_HEADER, |f| {
        Ok(RangePair {
            timestamp: f.timestamp,
            up_m: f.range(1, "up_m")?,
            down_m: f.range(2, "down_m")?,
        })
    })
}

/// Parses the text of an `imu.csv`; `file` names it in errors.
pub fn parse_imu(text: &str, file: &str) -> Result<Vec<ImuSample>, IoError> {
    parse_rows(text, file, IMU_HEADER, |f| {
        Ok(ImuSample {
            timestamp: f.timestamp,
            roll_rad: f.finite(1, "roll_rad")?,
            pitch_rad: f.finite(2, "pitch_rad")?,
            gyro_yaw_rad: f.optional(3, "gyro_yaw_rad")?,
        })
    })
}

/// Parses the text of a `flow.csv`; `file` names it in errors.
pub fn parse_flow(text: &str, file: &str) -> Result<Vec<FlowSample>, IoError> {
    parse_rows(text, file, FLOW_HEADER, |f| {
        let integration_s = f.finite(1, "integration_s")?;
        if integration_s <= 0.0 {
            return Err(format!("integration_s {integration_s} is not positive"));
        }
        let forward = f.optional(2, "forward_mps")?;
        let left = f.optional(3, "left_mps")?;
        let velocity_mps = match (forward, left) {
            (Some(x), Some(y)) => Some(Vector2::new(x, y)),
            (None, None) => None,
            _ => return Err("forward_mps and left_mps must both be given or both be empty".into()),
        };
        Ok(FlowSample {
            timestamp: f.timestamp,
            integration_s,
            velocity_mps,
        })
    })
}

/// The text of a `ranges.csv` holding `readings`.
pub fn format_ranges(readings: &[RangePair]) -> Result<String, String> {
    format_rows(RANGES_HEADER, readings, |r| {
        (r.timestamp, vec![field(r.up_m), field(r.down_m)])
    })
}

/// The text of an `imu.csv` holding `samples`.
pub fn format_imu(samples: &[ImuSample]) -> Result<String, String> {
    format_rows(IMU_HEADER, samples, |s| {
        let values = vec![
            s.roll_rad.to_string(),
            s.pitch_rad.to_string(),
            field(s.gyro_yaw_rad),
        ];
        (s.timestamp, values)
    })
}

/// The text of a `flow.csv` holding `samples`.
pub fn format_flow(samples: &[FlowSample]) -> Result<String, String> {
    format_rows(FLOW_HEADER, samples, |s| {
        let v = s.velocity_mps;
        let values = vec![
            s.integration_s.to_string(),
            field(v.map(|v| v.x)),
            field(v.map(|v| v.y)),
        ];
        (s.timestamp, values)
    })
}

/// Writes `ranges.csv` at `path`.
pub fn write_ranges(path: &Path, readings: &[RangePair]) -> Result<(), IoError> {
    write_text(path, format_ranges(readings))
}

/// Writes `imu.csv` at `path`.
pub fn write_imu(path: &Path, samples: &[ImuSample]) -> Result<(), IoError> {
    write_text(path, format_imu(samples))
}

/// Writes `flow.csv` at `path`.
pub fn write_flow(path: &Path, samples: &[FlowSample]) -> Result<(), IoError> {
    write_text(path, format_flow(samples))
}

fn write_text(path: &Path, text: Result<String, String>) -> Result<(), IoError> {
    let text = text.map_err(|message| IoError::invalid(path.display(), message))?;
    std::fs::write(path, text).map_err(|e| IoError::io(path, e))
}

/// An optional value as a field: empty when there is none.
fn field(value: Option<f64>) -> String {
    value.map(|v| v.to_string()).unwrap_or_default()
}

/// The header, then one line per item: its timestamp and its other fields. A non-finite
/// timestamp is refused, naming the item.
fn format_rows<T>(
    header: &str,
    items: &[T],
    fields: impl Fn(&T) -> (f64, Vec<String>),
) -> Result<String, String> {
    let mut out = format!("{header}\n");
    for (i, item) in items.iter().enumerate() {
        let (timestamp, values) = fields(item);
        if !timestamp.is_finite() {
            return Err(format!("reading {i}: timestamp {timestamp} is not finite"));
        }
        let _ = writeln!(out, "{timestamp},{}", values.join(","));
    }
    Ok(out)
}

/// The fields of one data line, its timestamp already checked.
struct Fields<'a> {
    timestamp: f64,
    values: Vec<&'a str>,
}

impl Fields<'_> {
    /// Field `i` as a number (NaN and infinities included); `None` when it is empty.
    fn number(&self, i: usize, name: &str) -> Result<Option<f64>, String> {
        let text = self.values.get(i).copied().unwrap_or("").trim();
        if text.is_empty() {
            return Ok(None);
        }
        text.parse()
            .map(Some)
            .map_err(|_| format!("{name} {text:?} is not a number"))
    }

    /// Field `i` as a finite number; `None` when it is empty or `nan`, an error when infinite.
    fn optional(&self, i: usize, name: &str) -> Result<Option<f64>, String> {
        match self.number(i, name)? {
            Some(v) if v.is_infinite() => Err(format!("{name} {v} is not finite")),
            v => Ok(v.filter(|v| !v.is_nan())),
        }
    }

    /// Field `i`, which must be a finite number.
    fn finite(&self, i: usize, name: &str) -> Result<f64, String> {
        match self.number(i, name)? {
            Some(v) if v.is_finite() => Ok(v),
            Some(v) => Err(format!("{name} {v} is not finite")),
            None => Err(format!("{name} is missing")),
        }
    }

    /// Field `i` as a range: `None` when empty or not finite (nothing in range); a negative
    /// range is an error.
    fn range(&self, i: usize, name: &str) -> Result<Option<f64>, String> {
        match self.number(i, name)? {
            Some(v) if v < 0.0 => Err(format!("{name} {v} is negative")),
            Some(v) if v.is_finite() => Ok(Some(v)),
            _ => Ok(None),
        }
    }
}

/// Parses every data line of `text` with `row`: the first line is skipped when it is
/// `header`, blank and `#` lines always; every line must have as many fields as the header and
/// a finite timestamp no smaller than the previous line's.
fn parse_rows<T>(
    text: &str,
    file: &str,
    header: &str,
    row: impl Fn(&Fields) -> Result<T, String>,
) -> Result<Vec<T>, IoError> {
    let columns = header.split(',').count();
    let mut out = Vec::new();
    let mut previous = f64::NEG_INFINITY;
    for (index, line) in text.lines().enumerate() {
        let number = index + 1;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || (index == 0 && line == header) {
            continue;
        }
        let values: Vec<&str> = line.split(',').collect();
        if values.len() != columns {
            return Err(IoError::parse(
                file,
                number,
                format!("{} fields, expected {columns} ({header})", values.len()),
            ));
        }
        let first = Fields {
            timestamp: 0.0,
            values,
        };
        let timestamp = first
            .finite(0, "timestamp")
            .map_err(|m| IoError::parse(file, number, m))?;
        if timestamp < previous {
            return Err(IoError::parse(
                file,
                number,
                format!("timestamp {timestamp} is before the previous line's {previous}"),
            ));
        }
        previous = timestamp;
        let fields = Fields {
            timestamp,
            values: first.values,
        };
        out.push(row(&fields).map_err(|m| IoError::parse(file, number, m))?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_file_reads_back_bit_for_bit() {
        let ranges = [
            RangePair {
                timestamp: 0.025,
                up_m: Some(1.0 / 3.0),
                down_m: None,
            },
            RangePair {
                timestamp: 0.05,
                up_m: None,
                down_m: Some(0.1 + 0.2),
            },
        ];
        let text = format_ranges(&ranges).unwrap();
        assert_eq!(parse_ranges(&text, "r").unwrap(), ranges);
        let imu = [ImuSample {
            timestamp: 1e-6,
            roll_rad: -0.001_234_567_890_123,
            pitch_rad: std::f64::consts::PI / 7.0,
            gyro_yaw_rad: Some(12.345_678_901_234_5),
        }];
        let text = format_imu(&imu).unwrap();
        assert_eq!(parse_imu(&text, "i").unwrap(), imu);
        let flow = [
            FlowSample {
                timestamp: 0.01,
                integration_s: 0.01,
                velocity_mps: Some(Vector2::new(0.3, -1.0 / 7.0)),
            },
            FlowSample {
                timestamp: 0.02,
                integration_s: 0.01,
                velocity_mps: None,
            },
        ];
        let text = format_flow(&flow).unwrap();
        assert_eq!(parse_flow(&text, "f").unwrap(), flow);
    }

    #[test]
    fn missing_readings_nan_and_inf() {
        let text = "timestamp,up_m,down_m\n# comment\n\n1.0,nan,inf\n2.0,,0.5\n";
        let r = parse_ranges(text, "r").unwrap();
        assert_eq!((r[0].up_m, r[0].down_m), (None, None));
        assert_eq!((r[1].up_m, r[1].down_m), (None, Some(0.5)));
        let imu = parse_imu("0,0.1,0.2,\n", "i").unwrap();
        assert_eq!(imu[0].gyro_yaw_rad, None);
        let flow = parse_flow("0,0.1,NaN,nan\n", "f").unwrap();
        assert_eq!(flow[0].velocity_mps, None);
    }

    #[test]
    fn bad_lines_name_the_file_and_line() {
        let cases = [
            (
                parse_ranges("timestamp,up_m,down_m\n1,2\n", "r.csv").err(),
                "r.csv:2:",
            ),
            (
                parse_ranges("1,x,2\n", "r.csv").err(),
                "r.csv:1: up_m \"x\"",
            ),
            (parse_ranges("1,-2,2\n", "r.csv").err(), "negative"),
            (
                parse_ranges("2,1,1\n1,1,1\n", "r.csv").err(),
                "r.csv:2: timestamp 1 is before",
            ),
            (
                parse_ranges("nan,1,1\n", "r.csv").err(),
                "timestamp NaN is not finite",
            ),
            (
                parse_imu("1,nan,0,0\n", "i.csv").err(),
                "i.csv:1: roll_rad NaN is not finite",
            ),
            (
                parse_imu("1,inf,0,0\n", "i.csv").err(),
                "roll_rad inf is not finite",
            ),
            (
                parse_flow("1,0,1,1\n", "f.csv").err(),
                "integration_s 0 is not positive",
            ),
            (parse_flow("1,0.1,1,\n", "f.csv").err(), "both"),
            (
                parse_flow("1,0.1,inf,0\n", "f.csv").err(),
                "forward_mps inf is not finite",
            ),
            (
                parse_imu("1,0,0,-inf\n", "i.csv").err(),
                "gyro_yaw_rad -inf is not finite",
            ),
        ];
        for (err, expected) in cases {
            let message = err.expect(expected).to_string();
            assert!(message.contains(expected), "{message} lacks {expected}");
        }
    }

    #[test]
    fn a_non_finite_timestamp_is_not_written() {
        let r = RangePair {
            timestamp: f64::NAN,
            up_m: None,
            down_m: None,
        };
        assert!(format_ranges(&[r]).unwrap_err().contains("reading 0"));
    }
}
