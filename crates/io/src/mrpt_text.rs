//! Text dumps of MRPT rawlogs (`*.fromrawlog.txt`) and MRPT ground-truth files (`*.GT.txt`).
//!
//! MRPT (Blanco-Claraco et al., the Mobile Robot Programming Toolkit) stores datasets as
//! "rawlogs": alternating odometry actions and sensory frames. Its binary serialization was
//! decoded once into text, one object per line, in stream order:
//!
//! * `ODOM_INC t dx dy dphi`: the odometry increment in the previous robot frame (m, rad);
//!   scans get the composition of all increments before them, starting from the identity.
//! * `SCAN t label sensor_x sensor_y sensor_yaw aperture right_to_left max_range n r_1..r_n
//!   v_1..v_n`: beam `i` at `−aperture/2 + i·aperture/(n−1)` when `right_to_left` is 1 (mirrored
//!   when 0); the sensor pose gives `base_from_laser`. A beam flagged invalid (`v_i = 0`) keeps
//!   its range when that is a "no return" (≥ max range, as MRPT writes overflows such as 81.87 m)
//!   and becomes NaN (unknown: neither hit nor free space) otherwise.
//!
//! `t` is Unix seconds, 0 when the rawlog stored none. `max_range_m` follows
//! [`no_return_threshold`]. Broken lines are skipped and recorded, non-finite ranges kept as
//! beams without a return, and stamps stepping back counted (a log mostly out of order
//! refused), as for CARMEN logs.
//!
//! The ground-truth file of the simulated rawlog holds `t x y theta` lines: the true robot
//! pose at each scan time, read as a [`Trajectory`] of planar poses lifted to 3D.

use crate::carmen::{field_total, no_return_threshold, Fields, SkipReason, SkippedLine};
use crate::error::read_text;
use crate::relations::parse_numbers;
use crate::time_order::TimeOrder;
use crate::IoError;
use slamkit_core::pose::pose2_to_pose3;
use slamkit_core::{LaserScan, Pose2, Trajectory};
use std::path::Path;

/// Everything read from an MRPT rawlog text dump.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MrptLog {
    /// Laser scans in stream order, with accumulated odometry.
    pub scans: Vec<LaserScan>,
    /// Lines that could not be read, in file order.
    pub skipped: Vec<SkippedLine>,
    /// Number of `ODOM_INC` lines read.
    pub odometry_increments: usize,
    /// Number of `#` comment lines.
    pub comment_lines: usize,
    /// How often the scans' timestamps step back in file order.
    pub time_order: TimeOrder,
}

/// Reads an MRPT rawlog text dump; a file with no readable scan is an error.
pub fn read_mrpt_text(path: &Path) -> Result<MrptLog, IoError> {
    parse_mrpt_text(&read_text(path)?, &path.display().to_string())
}

/// Parses an MRPT rawlog text dump; `origin` names the input in errors.
pub fn parse_mrpt_text(text: &str, origin: &str) -> Result<MrptLog, IoError> {
    let mut log = MrptLog::default();
    let mut odom_from_base = Pose2::identity();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        if line.starts_with('#') {
            log.comment_lines += 1;
            continue;
        }
        let tokens: Vec<&str> = line.split_ascii_whitespace().collect();
        let name = tokens.first().copied().unwrap_or_default();
        let fields = Fields {
            name,
            tokens: &tokens,
        };
        let result = match name {
            "ODOM_INC" => parse_increment(&fields)
                .map(|increment| odom_from_base * increment)
                .and_then(|next| {
                    if next.translation.vector.iter().all(|v| v.is_finite()) {
                        odom_from_base = next;
                        log.odometry_increments += 1;
                        Ok(())
                    } else {
                        Err(SkipReason::OutOfRange("accumulated odometry overflows"))
                    }
                }),
            "SCAN" => parse_scan(&fields, odom_from_base).map(|scan| {
                log.time_order.add(scan.timestamp, i + 1);
                log.scans.push(scan);
            }),
            _ => Err(SkipReason::Garbage {
                start: name.chars().take(16).collect(),
            }),
        };
        if let Err(reason) = result {
            log.skipped.push(SkippedLine {
                line: i + 1,
                reason,
            });
        }
    }
    if log.scans.is_empty() {
        return Err(IoError::Empty {
            file: origin.to_string(),
            what: "MRPT SCAN lines".into(),
        });
    }
    log.time_order
        .check()
        .map_err(|reason| IoError::invalid(origin, reason))?;
    Ok(log)
}

fn parse_increment(f: &Fields) -> Result<Pose2, SkipReason> {
    f.expect_len(5)?;
    let d = f.nums(2, 3)?;
    Ok(Pose2::new([d[0], d[1]].into(), d[2]))
}

fn parse_scan(f: &Fields, odometry: Pose2) -> Result<LaserScan, SkipReason> {
    let n = f.count(9)?;
    if n < 2 {
        return Err(SkipReason::BadBeams("a scan needs at least 2 beams"));
    }
    f.expect_len(field_total(&[10, n, n])?)?;
    let sensor = f.nums(3, 3)?;
    let aperture_rad = f.num(6)?;
    let right_to_left = match f.tokens.get(7) {
        Some(&"1") => true,
        Some(&"0") => false,
        _ => return Err(SkipReason::BadBeams("right_to_left must be 0 or 1")),
    };
    let max_range_m = no_return_threshold(Some(f.num(8)?));
    let ranges = f.ranges(10, n)?;
    let valid = f.nums(10 + n, n)?;
    let ranges_m = ranges
        .iter()
        .zip(&valid)
        .map(|(&r, &v)| {
            if v != 0.0 || r >= max_range_m {
                r
            } else {
                f64::NAN
            }
        })
        .collect();
    let step = aperture_rad / (n - 1) as f64;
    let (angle_min_rad, angle_increment_rad) = if right_to_left {
        (-aperture_rad / 2.0, step)
    } else {
        (aperture_rad / 2.0, -step)
    };
    Ok(LaserScan {
        timestamp: f.num(1)?,
        angle_min_rad,
        angle_increment_rad,
        ranges_m,
        max_range_m,
        odometry: Some(odometry),
        base_from_laser: Pose2::new([sensor[0], sensor[1]].into(), sensor[2]),
    })
}

/// Reads an MRPT ground-truth file (`t x y theta` a line; `#` lines ignored) as a trajectory.
pub fn read_mrpt_ground_truth(path: &Path) -> Result<Trajectory, IoError> {
    parse_mrpt_ground_truth(&read_text(path)?, &path.display().to_string())
}

/// Parses MRPT ground-truth text; a malformed line is an error naming it.
pub fn parse_mrpt_ground_truth(text: &str, origin: &str) -> Result<Trajectory, IoError> {
    let mut trajectory = Trajectory::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let [t, x, y, theta] = parse_numbers(line)
            .ok_or_else(|| IoError::parse(origin, i + 1, "expected 4 finite numbers"))?;
        trajectory.push(t, pose2_to_pose3(&Pose2::new([x, y].into(), theta)));
    }
    if trajectory.is_empty() {
        return Err(IoError::Empty {
            file: origin.to_string(),
            what: "ground-truth poses".into(),
        });
    }
    Ok(trajectory)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    const SCAN: &str = "SCAN 5.5 LASER 0.2 0 0 3.141593 1 80.000 3 1.0 81.87 2.0 1 0 0";

    #[test]
    fn scan_layout_validity_and_mounting() {
        let log = parse_mrpt_text(SCAN, "<t>").unwrap();
        let s = &log.scans[0];
        assert_eq!(s.timestamp, 5.5);
        assert!((s.angle_min_rad + FRAC_PI_2).abs() < 1e-6);
        assert!((s.angle_increment_rad - FRAC_PI_2).abs() < 1e-6);
        assert_eq!(s.ranges_m[1], 81.87);
        assert!(s.ranges_m[2].is_nan());
        assert_eq!(s.hit_count(), 1);
        assert_eq!(s.base_from_laser.translation.x, 0.2);
        let mirrored = parse_mrpt_text(&SCAN.replace(" 1 80.000", " 0 80.000"), "<t>").unwrap();
        assert!((mirrored.scans[0].beam_angle_rad(2) + FRAC_PI_2).abs() < 1e-6);
    }

    #[test]
    fn odometry_accumulates_increments_in_robot_frame() {
        let text = format!(
            "{SCAN}\nODOM_INC 0 1 0 {}\n{SCAN}\nODOM_INC 0 1 0 0\n{SCAN}\n",
            FRAC_PI_2
        );
        let log = parse_mrpt_text(&text, "<t>").unwrap();
        assert_eq!(log.odometry_increments, 2);
        let o = log.scans[2].odometry.unwrap();
        assert!((o.translation.vector - nalgebra::Vector2::new(1.0, 1.0)).norm() < 1e-12);
        assert!(log.scans[0].odometry.unwrap().translation.vector.norm() == 0.0);
    }

    #[test]
    fn broken_lines_skipped_and_empty_is_error() {
        let text = format!(
            "# c\n{SCAN}\n{}\nSCAN 1 L 0 0 0 3.1 2 80 3 1 1 1 1 1 1\nODOM_INC 0 1 NaN 0\n\
             SCAN 1 L 0 0 0 3.1 1 80 99999999999999999999\nfoo\n",
            &SCAN[..40]
        );
        let log = parse_mrpt_text(&text, "<t>").unwrap();
        assert_eq!(log.scans.len(), 1);
        let lines: Vec<usize> = log.skipped.iter().map(|s| s.line).collect();
        assert_eq!(lines, vec![3, 4, 5, 6, 7]);
        assert!(matches!(
            parse_mrpt_text("# c\n", "<t>"),
            Err(IoError::Empty { .. })
        ));
    }

    /// Issue 25 (5, 6): non-finite ranges keep the scan; a reversed log is refused and
    /// steps back in an ordered one are counted.
    #[test]
    fn non_finite_ranges_kept_and_reversed_log_refused() {
        let log = parse_mrpt_text(&SCAN.replace(" 2.0 ", " inf "), "<t>").unwrap();
        assert!(log.skipped.is_empty());
        assert!(log.scans[0].ranges_m[2].is_infinite());
        let scans: Vec<String> = (0..8)
            .map(|i| SCAN.replace("SCAN 5.5", &format!("SCAN {i}")))
            .collect();
        let mut text = scans.join("\n");
        let log = parse_mrpt_text(&text.replacen("SCAN 3", "SCAN 1.5", 1), "<t>").unwrap();
        assert_eq!(log.time_order.backward_steps, 1);
        assert_eq!(log.time_order.first_backward_line, Some(4));
        text = scans.iter().rev().cloned().collect::<Vec<_>>().join("\n");
        let err = parse_mrpt_text(&text, "log.txt").unwrap_err().to_string();
        assert!(
            err.starts_with("log.txt: log is mostly out of time order"),
            "{err}"
        );
    }

    /// Regression: increments near f64::MAX made the accumulated odometry infinite.
    #[test]
    fn overflowing_increment_is_skipped() {
        let text = format!("ODOM_INC 0 1e308 0 0\nODOM_INC 0 1e308 0 0\n{SCAN}\n");
        let log = parse_mrpt_text(&text, "<t>").unwrap();
        assert_eq!(log.skipped.len(), 1);
        assert_eq!(log.scans[0].odometry.unwrap().translation.x, 1e308);
    }

    #[test]
    fn ground_truth_lines() {
        let gt = parse_mrpt_ground_truth("1.5 0 0 0\n2.5 1 2 2.5\n", "<t>").unwrap();
        assert_eq!(gt.len(), 2);
        let p = gt.poses[1].pose;
        assert_eq!(p.translation.y, 2.0);
        assert!((p.rotation.angle() - 2.5).abs() < 1e-9);
        match parse_mrpt_ground_truth("1 0 0 0\n1 0 0\n", "gt.txt") {
            Err(IoError::Parse { line, .. }) => assert_eq!(line, 2),
            other => panic!("{other:?}"),
        }
    }
}
