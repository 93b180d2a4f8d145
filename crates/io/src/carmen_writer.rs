//! Writing CARMEN logs and benchmark relations files, the formats that [`crate::carmen`] and
//! [`crate::relations`] read (Kümmerle et al., "On measuring the accuracy of SLAM algorithms",
//! Autonomous Robots 27(4), 2009), so that simulated runs can be fed to any tool that reads the
//! Freiburg 2D SLAM benchmark.
//!
//! * A scan with odometry becomes a `ROBOTLASER1` line carrying the laser pose
//!   (`odometry · base_from_laser`) and the robot pose (`odometry`); one without becomes a
//!   `RAWLASER1` line. Velocities, safety distances and remissions are written as 0.
//! * Ranges and the beam layout (first angle, field of view, angular resolution, maximum
//!   range) are written in Rust's shortest round-trip form, so a scan reads back bit for bit
//!   (a rounded resolution turns the last beams of a 512-beam scan by 1e-7 rad, which moved a
//!   simulated drone flight's layered SLAM trajectory by up to 0.25 m); poses get 9 decimals;
//!   timestamps get 6 (CARMEN's microseconds), as the benchmark's relations files match log
//!   timestamps to the microsecond.
//! * Relations: `t1 t2 x y z roll pitch yaw` a line after a `#` header, the motion from the pose
//!   at `t1` to the pose at `t2` in the frame of the first.
//!
//! A non-finite value or a scan without beams is an error naming the scan or relation index;
//! nothing is written then.

use crate::relations::Relation;
use crate::IoError;
use slamkit_core::{LaserScan, Pose2};
use std::fmt::Write as _;
use std::path::Path;

/// Host name written in every log line.
const HOST: &str = "slamkit";

/// Writes `scans` as a CARMEN log at `path`, after a `#` comment naming the message layout.
pub fn write_carmen(path: &Path, scans: &[LaserScan]) -> Result<(), IoError> {
    let text = format_carmen(scans).map_err(|message| IoError::invalid(path.display(), message))?;
    std::fs::write(path, text).map_err(|e| IoError::io(path, e))
}

/// The CARMEN log text of `scans`, one message line each; the error names the bad scan.
pub fn format_carmen(scans: &[LaserScan]) -> Result<String, String> {
    let mut out = String::with_capacity(
        scans.len() * 16 * (scans.first().map_or(0, |s| s.ranges_m.len()) + 30),
    );
    out.push_str("# written by slamkit; ROBOTLASER1 when the scan has odometry, else RAWLASER1\n");
    for (i, scan) in scans.iter().enumerate() {
        carmen_line(&mut out, scan).map_err(|what| format!("scan {i}: {what}"))?;
    }
    Ok(out)
}

/// Appends one `RAWLASER1` or `ROBOTLASER1` line for `scan`.
fn carmen_line(out: &mut String, scan: &LaserScan) -> Result<(), String> {
    let n = scan.ranges_m.len();
    if n == 0 {
        return Err("no beams".into());
    }
    let fov = scan.angle_increment_rad * (n - 1) as f64;
    let header = [
        scan.angle_min_rad,
        fov,
        scan.angle_increment_rad,
        scan.max_range_m,
    ];
    check_finite(&header, "beam layout")?;
    check_finite(&scan.ranges_m, "range")?;
    check_finite(&[scan.timestamp], "timestamp")?;
    let name = if scan.odometry.is_some() {
        "ROBOTLASER1"
    } else {
        "RAWLASER1"
    };
    let [start, fov, res, max] = header;
    let _ = write!(out, "{name} 0 {start} {fov} {res} {max} 0.01 0 {n}");
    for r in &scan.ranges_m {
        let _ = write!(out, " {r}");
    }
    out.push_str(" 0");
    if let Some(robot) = scan.odometry {
        let laser = robot * scan.base_from_laser;
        let poses = [pose_fields(&laser), pose_fields(&robot)].concat();
        check_finite(&poses, "pose")?;
        for v in poses {
            let _ = write!(out, " {v:.9}");
        }
        out.push_str(" 0 0 0 0 0");
    }
    let t = scan.timestamp;
    let _ = writeln!(out, " {t:.6} {HOST} {t:.6}");
    Ok(())
}

fn pose_fields(p: &Pose2) -> [f64; 3] {
    [p.translation.x, p.translation.y, p.rotation.angle()]
}

fn check_finite(values: &[f64], what: &str) -> Result<(), String> {
    match values.iter().find(|v| !v.is_finite()) {
        Some(v) => Err(format!("{what} {v} is not finite")),
        None => Ok(()),
    }
}

/// Writes ground-truth relations at `path`: a `#` header, then `t1 t2 x y z roll pitch yaw`
/// (timestamps with 6 decimals, the rest with 9).
pub fn write_relations(path: &Path, relations: &[Relation]) -> Result<(), IoError> {
    let mut out = String::from("# timestamp1 timestamp2 x y z roll pitch yaw\n");
    for (i, r) in relations.iter().enumerate() {
        let t = r.t1_from_t2.translation.vector;
        let (roll, pitch, yaw) = r.t1_from_t2.rotation.euler_angles();
        let values = [r.t1, r.t2, t.x, t.y, t.z, roll, pitch, yaw];
        check_finite(&values, "value")
            .map_err(|m| IoError::invalid(path.display(), format!("relation {i}: {m}")))?;
        let _ = writeln!(
            out,
            "{:.6} {:.6} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}",
            r.t1, r.t2, t.x, t.y, t.z, roll, pitch, yaw
        );
    }
    std::fs::write(path, out).map_err(|e| IoError::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::carmen::parse_carmen;
    use crate::relations::read_relations;
    use nalgebra::{Translation3, UnitQuaternion, Vector2};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use slamkit_core::Pose3;

    /// Random scans with millimetre ranges, microsecond times, some without odometry.
    fn random_scans(n: usize) -> Vec<LaserScan> {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        (0..n)
            .map(|i| {
                let ranges_m = (0..512)
                    .map(|_| f64::from(rng.gen_range(0u32..=3000)) / 1000.0)
                    .collect();
                let odometry = (i % 3 != 0).then(|| {
                    Pose2::new(
                        Vector2::new(rng.gen_range(-5.0..5.0), rng.gen_range(-5.0..5.0)),
                        rng.gen_range(-3.0..3.0),
                    )
                });
                LaserScan {
                    timestamp: (1_000_000 + 100_000 * i as u64) as f64 / 1e6,
                    angle_min_rad: -2.356194490192345,
                    angle_increment_rad: 4.71238898038469 / 511.0,
                    ranges_m,
                    max_range_m: 3.0,
                    odometry,
                    base_from_laser: Pose2::new(Vector2::new(0.1, -0.02), 0.05),
                }
            })
            .collect()
    }

    #[test]
    fn carmen_round_trip_through_the_reader() {
        let scans = random_scans(20);
        let text = format_carmen(&scans).unwrap();
        let log = parse_carmen(text.as_bytes(), "<written>").unwrap();
        assert!(log.skipped.is_empty(), "{:?}", log.skipped);
        assert_eq!(log.comment_lines, 1);
        assert_eq!(log.scans.len(), scans.len());
        for (read, written) in log.scans.iter().zip(&scans) {
            assert_eq!(read.ranges_m, written.ranges_m);
            assert_eq!(read.timestamp, written.timestamp);
            assert_eq!(read.max_range_m, written.max_range_m);
            assert!((read.angle_min_rad - written.angle_min_rad).abs() < 1e-9);
            assert!((read.angle_increment_rad - written.angle_increment_rad).abs() < 1e-9);
            match (read.odometry, written.odometry) {
                (Some(r), Some(w)) => {
                    assert!((r.translation.vector - w.translation.vector).norm() < 1e-8);
                    assert!((r.rotation.angle() - w.rotation.angle()).abs() < 1e-8);
                    let m = read.base_from_laser.inverse() * written.base_from_laser;
                    assert!(m.translation.vector.norm() < 1e-8 && m.rotation.angle().abs() < 1e-8);
                }
                // the reader fills RAWLASER odometry from neighbouring lines only; there are
                // no ODOM lines here
                (None, None) => assert_eq!(read.base_from_laser, Pose2::identity()),
                other => panic!("odometry changed: {other:?}"),
            }
        }
    }

    #[test]
    fn bad_scans_are_errors_naming_the_scan() {
        let mut scans = random_scans(3);
        scans[2].ranges_m[7] = f64::NAN;
        let err = format_carmen(&scans).unwrap_err();
        assert!(err.starts_with("scan 2: range NaN"), "{err}");
        scans[2].ranges_m.clear();
        assert_eq!(format_carmen(&scans).unwrap_err(), "scan 2: no beams");
        let dir = tempfile::tempdir().unwrap();
        assert!(write_carmen(&dir.path().join("x.clf"), &scans).is_err());
    }

    #[test]
    fn relations_round_trip() {
        let relations: Vec<Relation> = (0..5)
            .map(|i| Relation {
                t1: f64::from(i) + 0.5,
                t2: f64::from(i) + 1.7,
                t1_from_t2: Pose3::from_parts(
                    Translation3::new(0.3 * f64::from(i), -0.2, 0.01),
                    UnitQuaternion::from_euler_angles(0.01, -0.02, 0.4 * f64::from(i) - 1.0),
                ),
            })
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("gt.relations");
        write_relations(&path, &relations).unwrap();
        let read = read_relations(&path).unwrap();
        assert_eq!(read.len(), 5);
        for (r, w) in read.iter().zip(&relations) {
            assert_eq!((r.t1, r.t2), (w.t1, w.t2));
            let err = w.t1_from_t2.inverse() * r.t1_from_t2;
            assert!(err.translation.vector.norm() < 1e-8 && err.rotation.angle() < 1e-8);
        }
        let mut bad = relations.clone();
        bad[1].t2 = f64::INFINITY;
        let err = write_relations(&path, &bad).unwrap_err();
        assert!(err.to_string().contains("relation 1"), "{err}");
    }
}
