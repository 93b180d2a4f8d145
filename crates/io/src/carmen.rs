//! CARMEN robot logs (`.clf`, plain or gzip): laser scans with their wheel odometry.
//!
//! CARMEN (Montemerlo, Roy, Thrun, "Perspectives on standardization in mobile robot
//! programming: the Carnegie Mellon Navigation (CARMEN) toolkit", IROS 2003) writes one message
//! per line, fields separated by spaces. The 2D SLAM benchmark logs of Kümmerle et al.
//! ("On measuring the accuracy of SLAM algorithms", Autonomous Robots 27(4), 2009: Intel,
//! ACES, MIT CSAIL, ...) use this format. Read here:
//!
//! * `FLASER n r_1..r_n x y theta odom_x odom_y odom_theta ipc_ts host logger_ts`: `n` beams
//!   spread over 180° from right to left (step π/(n−1), first beam at −π/2); the scan's
//!   odometry is `odom_*`. `x y theta` is the laser pose, which in corrected logs is not
//!   odometry, so `base_from_laser` is taken as identity.
//! * `RAWLASER1..4 type start fov res max_range accuracy remission_mode n r_1..r_n m rem_1..rem_m
//!   ipc_ts host logger_ts`: beam `i` at `start + i·res` (the Intel and ACES logs: 180 beams at
//!   −90°, −89°, …, +89°; spreading them over `fov` instead bends the map). All four laser
//!   numbers are read alike, so a log with several lasers gives their scans interleaved.
//! * `ROBOTLASER1`: the RAWLASER fields followed by `laser_x laser_y laser_theta robot_x
//!   robot_y robot_theta tv rv forward_safety side_safety turn_axis ipc_ts host logger_ts`;
//!   odometry is the robot pose and `base_from_laser = robot⁻¹ · laser` (its rotation
//!   renormalised to unit length).
//! * `ODOM x y theta tv rv accel ipc_ts host logger_ts`: scans without odometry of their own
//!   get it from the ODOM lines just before and just after them in file order, interpolated
//!   by timestamp when the scan's time lies between theirs, else from the nearer in time.
//!
//! The file order is kept and never sorted: the Intel log's timestamps step backwards 631 times
//! while its file order is the physical order. The backward steps are counted
//! ([`CarmenLog::time_order`]); a log mostly out of order (reversed, halves swapped: see
//! [`TimeOrder::is_mostly_out_of_order`]) is an error. Other message types (`PARAM`, `SYNC`,
//! ...) and `#` comments are counted and ignored. A broken line (truncated, wrong beam count,
//! NaN in a pose or stamp, garbage) is skipped and recorded with its line number. A file that
//! cannot be read to its end (a gzip stream truncated or corrupted mid-file) is an error naming
//! the line where reading stopped, never a shorter log that looks complete; so is a file with
//! no readable scan at all.
//!
//! A non-finite range (`inf`, `nan`) is kept as it is: like a negative one it is a beam with no
//! usable return ([`LaserScan::is_hit`] is false), not a reason to drop the scan.
//!
//! "No return" readings: SICK scanners report an overflow code as the range (81.83 m in the
//! Intel log, 81.91 m in MIT CSAIL, 50.00 m in ACES), while a log's `max_range` field may be a
//! converter setting (Intel's reads 30.00 and is not measured). The rule used here is
//! [`no_return_threshold`]: `max_range_m = min(max_range field, 80 m)`, 80 m when the message
//! has no such field (FLASER) or it is not a positive number. Checked on the data: Intel's
//! largest real reading is 26.x m (threshold 30), ACES' 49.91 m with 50.00 as no return
//! (threshold 50), MIT CSAIL's 42.40 m with 81.91 as no return (threshold 80).

use crate::odometry_bracket::{OdomSample, OdometryBracket};
use crate::time_order::TimeOrder;
use flate2::bufread::MultiGzDecoder;
use slamkit_core::{LaserScan, Pose2};
use std::f64::consts::{FRAC_PI_2, PI};
use std::io::{BufRead, BufReader};
use std::path::Path;

/// Readings at or beyond this are "no return" whatever a log's `max_range` field says \[m\]:
/// below the SICK overflow codes (81.83 m, 81.91 m) and above any real 2D-lidar reading in
/// the benchmark logs (at most 42.4 m).
pub const NO_RETURN_FLOOR_M: f64 = 80.0;

/// The `max_range_m` given to a scan: the log's `max_range` field when it is a positive number,
/// capped at [`NO_RETURN_FLOOR_M`] so that overflow codes are never taken as hits.
pub fn no_return_threshold(max_range_field_m: Option<f64>) -> f64 {
    match max_range_field_m {
        Some(m) if m.is_finite() && m > 0.0 => m.min(NO_RETURN_FLOOR_M),
        _ => NO_RETURN_FLOOR_M,
    }
}

/// Everything read from a CARMEN log.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CarmenLog {
    /// Laser scans in file order, each with odometry when the log has any.
    pub scans: Vec<LaserScan>,
    /// Lines that could not be read, in file order.
    pub skipped: Vec<SkippedLine>,
    /// Number of `ODOM` lines read.
    pub odometry_lines: usize,
    /// Number of `#` comment lines.
    pub comment_lines: usize,
    /// Number of well-formed lines of message types not read here (`PARAM`, `SYNC`, ...).
    pub other_message_lines: usize,
    /// How often the scans' timestamps step back in file order.
    pub time_order: TimeOrder,
}

/// A line of a log that was skipped, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct SkippedLine {
    /// 1-based line number (in the decompressed text).
    pub line: usize,
    /// What is wrong with it.
    pub reason: SkipReason,
}

/// Why a log line was skipped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SkipReason {
    /// The line is not valid UTF-8.
    #[error("not UTF-8 text")]
    NotUtf8,
    /// The line does not start with a message name.
    #[error("not a message line (starts with {start:?})")]
    Garbage {
        /// The first characters of the line.
        start: String,
    },
    /// The message has the wrong number of fields (truncated or garbled).
    #[error("{message}: expected {expected} fields, got {got}")]
    FieldCount {
        /// Message name.
        message: String,
        /// Fields the message's counts call for (at least this many when the count is
        /// itself unreadable).
        expected: usize,
        /// Fields on the line.
        got: usize,
    },
    /// A field is not a finite number (or not a count where a count is due).
    #[error("field {field}: {token:?} is not a valid {what}")]
    BadField {
        /// 0-based field index (the message name is field 0).
        field: usize,
        /// The first characters of the field.
        token: String,
        /// What was expected there.
        what: &'static str,
    },
    /// The beam layout cannot describe a scan (too few beams, zero angular step).
    #[error("bad beam layout: {0}")]
    BadBeams(&'static str),
    /// Values are finite but so large that a derived pose overflows.
    #[error("values out of range: {0}")]
    OutOfRange(&'static str),
    /// A bag message that does not decode as its type (the log was read from a bag: the
    /// "line" is the message's number, see [`crate::bag::scans`]).
    #[error("{topic}: {what}")]
    Undecodable {
        /// The message's topic.
        topic: String,
        /// What is wrong with it.
        what: String,
    },
}

impl SkipReason {
    /// A short name for the reason, the same for every line it applies to (for counting
    /// skipped lines by reason in a report).
    ///
    /// ```
    /// use slamkit_io::carmen::SkipReason;
    ///
    /// assert_eq!(SkipReason::BadBeams("no beams").key(), "bad_beams");
    /// ```
    pub fn key(&self) -> &'static str {
        match self {
            Self::NotUtf8 => "not_utf8",
            Self::Garbage { .. } => "garbage",
            Self::FieldCount { .. } => "wrong_field_count",
            Self::BadField { .. } => "bad_field",
            Self::BadBeams(_) => "bad_beams",
            Self::OutOfRange(_) => "out_of_range",
            Self::Undecodable { .. } => "undecodable_message",
        }
    }
}

/// A CARMEN log that cannot be read at all.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CarmenError {
    /// The file could not be opened.
    #[error("{file}: {error}")]
    Open {
        /// The log file.
        file: String,
        /// The operating system's error (in the message, not a `source()`, so that an error
        /// chain does not print it twice).
        error: std::io::Error,
    },
    /// Reading stopped before the end of the file (a gzip stream truncated or corrupted,
    /// a disk error): the log is incomplete, so none of it is returned.
    #[error(
        "{file}:{line}: the log is damaged or truncated here ({error}); {scans} scans were \
         read before it"
    )]
    Read {
        /// The log file.
        file: String,
        /// 1-based line number (of the decompressed text) where reading failed.
        line: usize,
        /// Scans read before the damage.
        scans: usize,
        /// The reading or decompression error (in the message, not a `source()`).
        error: std::io::Error,
    },
    /// The scans' timestamps are mostly out of order (a reversed log, swapped parts).
    #[error("{file}: {reason}")]
    OutOfOrder {
        /// The log file.
        file: String,
        /// How far out of order, and the limit.
        reason: String,
    },
    /// The file holds no readable laser scan.
    #[error("{file}: no readable laser scan in {lines} lines ({skipped} broken lines skipped)")]
    NoScans {
        /// The log file.
        file: String,
        /// Lines read.
        lines: usize,
        /// Lines skipped as broken.
        skipped: usize,
    },
}

/// Reads a CARMEN log file, plain or gzip-compressed (told by its magic bytes).
pub fn read_carmen(path: &Path) -> Result<CarmenLog, CarmenError> {
    let file = std::fs::File::open(path).map_err(|error| CarmenError::Open {
        file: path.display().to_string(),
        error,
    })?;
    parse_carmen(BufReader::new(file), &path.display().to_string())
}

/// Parses a CARMEN log from `reader`, plain or gzip-compressed (told by its magic bytes);
/// `origin` names the input in errors.
pub fn parse_carmen<R: BufRead>(mut reader: R, origin: &str) -> Result<CarmenLog, CarmenError> {
    let head = reader.fill_buf().map_err(|error| CarmenError::Read {
        file: origin.to_string(),
        line: 1,
        scans: 0,
        error,
    })?;
    if head.starts_with(&[0x1f, 0x8b]) {
        parse_lines(BufReader::new(MultiGzDecoder::new(reader)), origin)
    } else {
        parse_lines(reader, origin)
    }
}

/// One parsed message line.
enum Message {
    Scan(LaserScan),
    Odom(OdomSample),
    Other,
}

/// Reads the lines of a decompressed log, tying each scan to odometry as it goes.
fn parse_lines<R: BufRead>(mut reader: R, origin: &str) -> Result<CarmenLog, CarmenError> {
    let mut log = CarmenLog::default();
    let mut odometry = OdometryBracket::default();
    let mut buf = Vec::new();
    let mut line_no = 0;
    loop {
        buf.clear();
        line_no += 1;
        match reader.read_until(b'\n', &mut buf) {
            Ok(0) => break,
            Ok(_) => {}
            Err(error) => {
                return Err(CarmenError::Read {
                    file: origin.to_string(),
                    line: line_no,
                    scans: log.scans.len(),
                    error,
                })
            }
        }
        if let Err(reason) = add_line(&mut log, &mut odometry, &buf, line_no) {
            log.skipped.push(SkippedLine {
                line: line_no,
                reason,
            });
        }
    }
    odometry.finish(&mut log.scans);
    if log.scans.is_empty() {
        return Err(CarmenError::NoScans {
            file: origin.to_string(),
            lines: line_no - 1,
            skipped: log.skipped.len(),
        });
    }
    log.time_order
        .check()
        .map_err(|reason| CarmenError::OutOfOrder {
            file: origin.to_string(),
            reason,
        })?;
    Ok(log)
}

/// Reads line `line_no` into `log`.
fn add_line(
    log: &mut CarmenLog,
    odometry: &mut OdometryBracket,
    bytes: &[u8],
    line_no: usize,
) -> Result<(), SkipReason> {
    let text = std::str::from_utf8(bytes)
        .map_err(|_| SkipReason::NotUtf8)?
        .trim();
    if text.is_empty() {
        return Ok(());
    }
    if text.starts_with('#') {
        log.comment_lines += 1;
        return Ok(());
    }
    match parse_message(text)? {
        Message::Scan(scan) => {
            log.time_order.add(scan.timestamp, line_no);
            odometry.add_scan(&mut log.scans, scan);
        }
        Message::Odom(sample) => {
            log.odometry_lines += 1;
            odometry.add_odom(&mut log.scans, sample);
        }
        Message::Other => log.other_message_lines += 1,
    }
    Ok(())
}

/// Parses one non-comment line.
fn parse_message(text: &str) -> Result<Message, SkipReason> {
    let tokens: Vec<&str> = text.split_ascii_whitespace().collect();
    let name = tokens.first().copied().unwrap_or_default();
    let fields = Fields {
        name,
        tokens: &tokens,
    };
    match name {
        "FLASER" => parse_flaser(&fields).map(Message::Scan),
        "RAWLASER1" | "RAWLASER2" | "RAWLASER3" | "RAWLASER4" => {
            parse_rawlaser(&fields).map(Message::Scan)
        }
        "ROBOTLASER1" => parse_robotlaser(&fields).map(Message::Scan),
        "ODOM" => parse_odom(&fields).map(Message::Odom),
        _ if is_message_name(name) => Ok(Message::Other),
        _ => Err(SkipReason::Garbage {
            start: name.chars().take(16).collect(),
        }),
    }
}

/// CARMEN message names are upper-case letters, digits and underscores.
fn is_message_name(name: &str) -> bool {
    name.starts_with(|c: char| c.is_ascii_uppercase())
        && name
            .chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
}

/// The fields of one message line, with typed, bounds-checked access.
pub(crate) struct Fields<'a> {
    /// Message name (field 0).
    pub(crate) name: &'a str,
    /// All fields, the name included.
    pub(crate) tokens: &'a [&'a str],
}

impl Fields<'_> {
    /// Field `i` as a finite number.
    pub(crate) fn num(&self, i: usize) -> Result<f64, SkipReason> {
        let token = self.token(i)?;
        match token.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(bad_field(i, token, "finite number")),
        }
    }

    /// Field `i` as a count.
    pub(crate) fn count(&self, i: usize) -> Result<usize, SkipReason> {
        let token = self.token(i)?;
        token
            .parse::<usize>()
            .map_err(|_| bad_field(i, token, "count"))
    }

    /// Fields `start..start + n` as finite numbers.
    pub(crate) fn nums(&self, start: usize, n: usize) -> Result<Vec<f64>, SkipReason> {
        (start..start + n).map(|i| self.num(i)).collect()
    }

    /// Fields `start..start + n` as ranges: any number, `inf` and `nan` included (a beam
    /// without a usable return, like a negative one).
    pub(crate) fn ranges(&self, start: usize, n: usize) -> Result<Vec<f64>, SkipReason> {
        (start..start + n)
            .map(|i| {
                let token = self.token(i)?;
                token
                    .parse::<f64>()
                    .map_err(|_| bad_field(i, token, "range"))
            })
            .collect()
    }

    /// Fails unless the line has exactly `expected` fields.
    pub(crate) fn expect_len(&self, expected: usize) -> Result<(), SkipReason> {
        if self.tokens.len() == expected {
            Ok(())
        } else {
            Err(self.field_count(expected))
        }
    }

    /// Field `i` as text.
    fn token(&self, i: usize) -> Result<&str, SkipReason> {
        self.tokens
            .get(i)
            .copied()
            .ok_or_else(|| self.field_count(i + 1))
    }

    fn field_count(&self, expected: usize) -> SkipReason {
        SkipReason::FieldCount {
            message: self.name.to_string(),
            expected,
            got: self.tokens.len(),
        }
    }
}

fn bad_field(field: usize, token: &str, what: &'static str) -> SkipReason {
    SkipReason::BadField {
        field,
        token: token.chars().take(24).collect(),
        what,
    }
}

/// `a + b + ...` for field counts read from the input, failing instead of overflowing.
pub(crate) fn field_total(parts: &[usize]) -> Result<usize, SkipReason> {
    parts
        .iter()
        .try_fold(0usize, |acc, &p| acc.checked_add(p))
        .ok_or(SkipReason::BadBeams("beam count overflows"))
}

fn parse_flaser(f: &Fields) -> Result<LaserScan, SkipReason> {
    let n = f.count(1)?;
    if n < 2 {
        return Err(SkipReason::BadBeams("FLASER needs at least 2 beams"));
    }
    f.expect_len(field_total(&[n, 11])?)?;
    let ranges_m = f.ranges(2, n)?;
    let pose = f.nums(2 + n, 6)?;
    Ok(LaserScan {
        timestamp: f.num(8 + n)?,
        angle_min_rad: -FRAC_PI_2,
        angle_increment_rad: PI / (n - 1) as f64,
        ranges_m,
        max_range_m: no_return_threshold(None),
        odometry: Some(Pose2::new([pose[3], pose[4]].into(), pose[5])),
        base_from_laser: Pose2::identity(),
    })
}

/// The laser fields shared by RAWLASER and ROBOTLASER1, up to the remissions.
struct RawLaser {
    angle_min_rad: f64,
    angle_increment_rad: f64,
    max_range_field_m: f64,
    ranges_m: Vec<f64>,
    /// Index of the first field after the remissions.
    next_field: usize,
}

fn parse_raw_fields(f: &Fields, trailing_fields: usize) -> Result<RawLaser, SkipReason> {
    let n = f.count(8)?;
    if n == 0 {
        return Err(SkipReason::BadBeams("no beams"));
    }
    let n_rem_field = field_total(&[9, n])?;
    let m = f.count(n_rem_field)?;
    let next_field = field_total(&[n_rem_field, 1, m])?;
    f.expect_len(field_total(&[next_field, trailing_fields])?)?;
    let angular_res = f.num(4)?;
    if angular_res == 0.0 {
        return Err(SkipReason::BadBeams("zero angular resolution"));
    }
    Ok(RawLaser {
        angle_min_rad: f.num(2)?,
        angle_increment_rad: angular_res,
        max_range_field_m: f.num(5)?,
        ranges_m: f.ranges(9, n)?,
        next_field,
    })
}

fn parse_rawlaser(f: &Fields) -> Result<LaserScan, SkipReason> {
    let raw = parse_raw_fields(f, 3)?;
    Ok(LaserScan {
        timestamp: f.num(raw.next_field)?,
        angle_min_rad: raw.angle_min_rad,
        angle_increment_rad: raw.angle_increment_rad,
        max_range_m: no_return_threshold(Some(raw.max_range_field_m)),
        ranges_m: raw.ranges_m,
        odometry: None,
        base_from_laser: Pose2::identity(),
    })
}

fn parse_robotlaser(f: &Fields) -> Result<LaserScan, SkipReason> {
    let raw = parse_raw_fields(f, 14)?;
    let poses = f.nums(raw.next_field, 6)?;
    let world_from_laser = Pose2::new([poses[0], poses[1]].into(), poses[2]);
    let world_from_robot = Pose2::new([poses[3], poses[4]].into(), poses[5]);
    // robot⁻¹ · laser leaves the rotation's length 1 ± 1 ulp (cos² + sin² of the robot's
    // heading), which every point of the scan would then be scaled by: a simulated flight's
    // layered SLAM drifted 1 mm from the same scans in memory (office, seed 3).
    let mut base_from_laser = world_from_robot.inverse() * world_from_laser;
    base_from_laser.rotation.renormalize();
    if !base_from_laser
        .translation
        .vector
        .iter()
        .all(|v| v.is_finite())
    {
        return Err(SkipReason::OutOfRange(
            "laser and robot poses too far apart",
        ));
    }
    Ok(LaserScan {
        timestamp: f.num(raw.next_field + 11)?,
        angle_min_rad: raw.angle_min_rad,
        angle_increment_rad: raw.angle_increment_rad,
        max_range_m: no_return_threshold(Some(raw.max_range_field_m)),
        ranges_m: raw.ranges_m,
        odometry: Some(world_from_robot),
        base_from_laser,
    })
}

fn parse_odom(f: &Fields) -> Result<OdomSample, SkipReason> {
    f.expect_len(10)?;
    let pose = f.nums(1, 3)?;
    Ok(OdomSample {
        timestamp: f.num(7)?,
        pose: Pose2::new([pose[0], pose[1]].into(), pose[2]),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn parse(text: &str) -> Result<CarmenLog, CarmenError> {
        parse_carmen(text.as_bytes(), "<test>")
    }

    /// A RAWLASER1 line with `ranges` and the Intel-style beam layout.
    fn rawlaser(ranges: &[f64], t: f64) -> String {
        let r: Vec<String> = ranges.iter().map(|r| format!("{r:.2}")).collect();
        format!(
            "RAWLASER1 0 -1.570796 3.141593 0.017453 30.00 0.01 0 {} {} 0 {t:.6} bag 0",
            ranges.len(),
            r.join(" ")
        )
    }

    fn odom(x: f64, theta: f64, t: f64) -> String {
        format!("ODOM {x} 0 {theta} 0 0 0 {t:.6} bag 0")
    }

    #[test]
    fn flaser_layout_odometry_and_no_return() {
        let log = parse("FLASER 3 1.0 81.91 2.5 9 9 9 1 2 0.5 100.25 host 0.1\n").unwrap();
        let s = &log.scans[0];
        assert_eq!(s.timestamp, 100.25);
        assert_eq!(s.angle_min_rad, -FRAC_PI_2);
        assert!((s.angle_increment_rad - FRAC_PI_2).abs() < 1e-12);
        assert!((s.beam_angle_rad(2) - FRAC_PI_2).abs() < 1e-12);
        let o = s.odometry.unwrap();
        assert_eq!((o.translation.x, o.translation.y), (1.0, 2.0));
        assert!((o.rotation.angle() - 0.5).abs() < 1e-12);
        assert!(s.is_hit(0) && !s.is_hit(1) && s.is_hit(2));
    }

    #[test]
    fn rawlaser_step_is_angular_res_and_max_range_capped() {
        let log = parse(&rawlaser(&[1.0; 180], 5.0)).unwrap();
        let s = &log.scans[0];
        assert!((s.angle_increment_rad - 0.017453).abs() < 1e-12);
        assert!((s.beam_angle_rad(179) - s.angle_min_rad - 179.0 * 0.017453).abs() < 1e-12);
        assert_eq!(s.max_range_m, 30.0);
        assert_eq!(s.odometry, None);
        assert_eq!(no_return_threshold(Some(120.0)), NO_RETURN_FLOOR_M);
        assert_eq!(no_return_threshold(Some(-1.0)), NO_RETURN_FLOOR_M);
        assert_eq!(no_return_threshold(Some(50.0)), 50.0);
    }

    #[test]
    fn robotlaser_gives_robot_odometry_and_mounting() {
        let line = "ROBOTLASER1 0 -1.5 3.0 1.5 20 0.01 0 3 1 2 3 0 \
                    1.5 0 0.1 1 0 0.1 0 0 0 0 0 7.5 host 7.5";
        let s = parse(line).unwrap().scans.remove(0);
        assert_eq!(s.timestamp, 7.5);
        assert_eq!(s.max_range_m, 20.0);
        assert_eq!(s.odometry.unwrap().translation.x, 1.0);
        let m = s.base_from_laser;
        assert!((m.translation.x - 0.5 * 0.1f64.cos()).abs() < 1e-12, "{m}");
        assert!(m.rotation.angle().abs() < 1e-12);
    }

    #[test]
    fn odometry_interpolated_between_bracketing_odom_lines() {
        let text = [
            odom(0.0, 3.0, 10.0),
            rawlaser(&[1.0; 4], 10.5),
            odom(2.0, -3.0, 11.0),
        ]
        .join("\n");
        let o = parse(&text).unwrap().scans[0].odometry.unwrap();
        assert!((o.translation.x - 1.0).abs() < 1e-12);
        // shorter arc from 3 to -3 rad passes through pi
        assert!((o.rotation.angle().abs() - PI).abs() < 1e-9, "{o}");
    }

    #[test]
    fn inconsistent_bracket_takes_nearer_odom_and_file_order_kept() {
        let text = [
            rawlaser(&[1.0; 4], 3.0),
            odom(1.0, 0.0, 10.0),
            rawlaser(&[1.0; 4], 9.0),
            odom(2.0, 0.0, 8.5),
            rawlaser(&[1.0; 4], 20.0),
        ]
        .join("\n");
        let log = parse(&text).unwrap();
        let xs: Vec<f64> = log
            .scans
            .iter()
            .map(|s| s.odometry.unwrap().translation.x)
            .collect();
        assert_eq!(xs, vec![1.0, 2.0, 2.0]);
        let ts: Vec<f64> = log.scans.iter().map(|s| s.timestamp).collect();
        assert_eq!(ts, vec![3.0, 9.0, 20.0]);
        assert_eq!(log.odometry_lines, 2);
    }

    /// Regression (found by review while fuzzing): stamps near ±f64::MAX made the bracket
    /// weight inf / inf = NaN, and poses that far apart an infinite laser mounting.
    #[test]
    fn extreme_values_give_finite_odometry_or_a_skip() {
        let text = [
            odom(-1e308, 0.0, -1e308),
            rawlaser(&[1.0; 2], 1e308),
            odom(1.7e308, 0.0, 1.7e308),
        ]
        .join("\n");
        let o = parse(&text).unwrap().scans[0].odometry.unwrap();
        assert!(
            o.translation.x.is_finite() && o.rotation.angle().is_finite(),
            "{o}"
        );
        let robot = "ROBOTLASER1 0 -1.5 3.0 1.5 20 0.01 0 3 1 2 3 0 \
                     1e308 0 0 -1e308 0 0 0 0 0 0 0 7.5 host 7.5";
        let log = parse(&format!("{robot}\n{}", rawlaser(&[1.0; 2], 1.0))).unwrap();
        assert_eq!(log.skipped.len(), 1);
        assert_eq!(log.skipped[0].line, 1);
    }

    #[test]
    fn broken_lines_are_skipped_with_line_numbers() {
        let good = rawlaser(&[1.0; 4], 1.0);
        let text = [
            "# comment".to_string(),
            good.clone(),
            good[..good.len() - 10].to_string(), // truncated
            good.replace(" 1.000000 bag", " NaN bag"), // NaN timestamp
            good.replace(" 4 ", " 5 "),          // wrong count
            "FLASER 1 2.0 0 0 0 0 0 0 1 h 1".into(), // too few beams
            "FLASER 99999999999999999999 1".into(), // count overflow
            "RAWLASER1 0 0 0 0.01 30 0 0 18446744073709551615 1".into(),
            "\u{1}\u{7f}garbage".into(),
            "PARAM robot_width 0.5".into(),
            good.replace("0.017453", "0"), // zero step
            "ODOM 1 2".into(),
        ]
        .join("\n");
        let log = parse(&text).unwrap();
        assert_eq!(log.scans.len(), 1);
        assert_eq!(log.comment_lines, 1);
        assert_eq!(log.other_message_lines, 1);
        let lines: Vec<usize> = log.skipped.iter().map(|s| s.line).collect();
        assert_eq!(lines, vec![3, 4, 5, 6, 7, 8, 9, 11, 12]);
        assert!(matches!(log.skipped[1].reason, SkipReason::BadField { .. }));
    }

    /// Issue 25 (6): one `inf` beam dropped the whole scan. Non-finite beams are beams
    /// without a usable return, as negative ones are; the scan is kept.
    #[test]
    fn non_finite_beams_are_no_return_not_a_broken_scan() {
        let line = rawlaser(&[1.0, 2.0, 3.0, 4.0], 1.0)
            .replace(" 2.00 ", " inf ")
            .replace(" 3.00 ", " NaN ");
        let flaser = "FLASER 3 -inf 81.91 2.5 9 9 9 1 2 0.5 100.25 host 0.1";
        let log = parse(&format!("{line}\n{flaser}")).unwrap();
        assert!(log.skipped.is_empty(), "{:?}", log.skipped);
        let s = &log.scans[0];
        assert!(s.ranges_m[1].is_infinite() && s.ranges_m[2].is_nan());
        assert_eq!(s.hit_count(), 2);
        assert_eq!(log.scans[1].hit_count(), 1);
        // a token that is not a number is still a broken line
        let log = parse(&format!("{line}\n{}", line.replace(" inf ", " 1.2.3 "))).unwrap();
        assert_eq!(log.scans.len(), 1);
        assert!(matches!(
            log.skipped[0].reason,
            SkipReason::BadField { what: "range", .. }
        ));
    }

    /// Issue 25 (5): stamps stepping back are counted with the first line; a reversed log
    /// and one with its halves swapped are refused.
    #[test]
    fn backward_timestamps_counted_and_disordered_logs_refused() {
        let mut lines: Vec<String> = (0..40).map(|i| rawlaser(&[1.0; 2], f64::from(i))).collect();
        lines.swap(10, 11);
        let log = parse(&lines.join("\n")).unwrap();
        assert_eq!(log.time_order.backward_steps, 1);
        assert_eq!(log.time_order.first_backward_line, Some(12));
        lines.swap(10, 11);
        lines.reverse();
        let err = parse(&lines.join("\n")).unwrap_err();
        assert!(matches!(err, CarmenError::OutOfOrder { .. }), "{err}");
        lines.reverse();
        lines.rotate_left(20);
        let err = parse(&lines.join("\n")).unwrap_err().to_string();
        assert!(
            err.contains("step back 1 times") && err.contains("line 21"),
            "{err}"
        );
    }

    #[test]
    fn non_utf8_line_skipped() {
        let mut bytes = rawlaser(&[1.0; 2], 1.0).into_bytes();
        bytes.extend_from_slice(b"\n\xff\xfe ODOM\n");
        let log = parse_carmen(bytes.as_slice(), "<test>").unwrap();
        assert_eq!(log.skipped[0].reason, SkipReason::NotUtf8);
        assert_eq!(log.skipped[0].line, 2);
    }

    #[test]
    fn unreadable_inputs_are_errors() {
        assert!(matches!(parse(""), Err(CarmenError::NoScans { .. })));
        assert!(matches!(
            parse("# only\nODOM 0 0 0 0 0 0 1 h 0"),
            Err(CarmenError::NoScans { .. })
        ));
        assert!(matches!(
            parse_carmen(&[0x1f, 0x8b, 0, 1][..], "x"),
            Err(CarmenError::Read { .. })
        ));
        let missing = read_carmen(Path::new("/nonexistent/log.clf"));
        assert!(matches!(missing, Err(CarmenError::Open { .. })));
    }

    /// Issue 25 (3): a gzip log cut or corrupted mid-file is an error naming the file and
    /// the line where reading stopped, not a shorter log.
    #[test]
    fn gzip_detected_by_magic_and_damage_is_an_error() {
        let text: String = (0..400)
            .map(|i| rawlaser(&[1.0 + f64::from(i % 2); 3], f64::from(i)) + "\n")
            .collect();
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        enc.write_all(text.as_bytes()).unwrap();
        let gz = enc.finish().unwrap();
        let log = parse_carmen(gz.as_slice(), "<gz>").unwrap();
        assert_eq!(log.scans.len(), 400);
        assert!(log.skipped.is_empty());
        let cut = parse_carmen(&gz[..gz.len() - 20], "<gz>").unwrap_err();
        assert!(matches!(cut, CarmenError::Read { .. }), "{cut}");
        assert!(cut.to_string().starts_with("<gz>:"), "{cut}");
        let mut flipped = gz.clone();
        let middle = flipped.len() / 2;
        flipped[middle] ^= 0xff;
        assert!(parse_carmen(flipped.as_slice(), "<gz>").is_err());
    }
}
