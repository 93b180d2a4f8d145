//! Trajectory files in the three formats benchmarks exchange, with the format told from the
//! content:
//!
//! * **TUM** (Sturm et al., "A Benchmark for the Evaluation of RGB-D SLAM Systems", IROS 2012):
//!   `t tx ty tz qx qy qz qw` per line, `#` comments.
//! * **KITTI odometry** (Geiger et al., CVPR 2012): a 3×4 row-major `[R|t]` per line and no
//!   timestamp; the pose's line index (0, 1, 2, …) is used as its timestamp.
//! * **EuRoC ground truth CSV** (Burri et al., IJRR 2016): `#timestamp` header, then
//!   `t_ns, p_x, p_y, p_z, q_w, q_x, q_y, q_z, …` (note the quaternion order w, x, y, z);
//!   nanoseconds are converted to seconds.
//!
//! Quaternions are normalised and rotation matrices re-orthonormalised (polar decomposition by
//! SVD), so every pose read is a proper rigid transform. Writers print enough digits for a read
//! back to agree with the original to 1e-9.

use std::io::Write;
use std::path::Path;

use nalgebra::{Matrix3, Matrix3x4, Quaternion, Rotation3, Translation3, UnitQuaternion};
use slamkit_core::{Pose3, Trajectory};

use crate::error::{read_text, IoError};

/// Name used in errors for text that did not come from a file.
const NO_FILE: &str = "<input>";

/// Largest accepted distance of a rotation matrix's singular values from 1 before
/// re-orthonormalisation; farther means the matrix is not a rotation at all.
const MAX_SINGULAR_VALUE_ERROR: f64 = 0.05;

/// The file formats [`parse_trajectory`] recognises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrajectoryFormat {
    /// `t tx ty tz qx qy qz qw`, timestamps in seconds.
    Tum,
    /// 3×4 row-major `[R|t]` per line; timestamps are line indices.
    Kitti,
    /// EuRoC ground-truth CSV: `t_ns, p_xyz, q_wxyz, …`.
    EurocCsv,
}

/// Parses a trajectory, telling the format from the content: 8 numbers a line is TUM, 12 is
/// KITTI, comma-separated lines are EuRoC CSV.
///
/// Errors name the offending line (file `<input>`); an empty text is an error.
pub fn parse_trajectory(text: &str) -> Result<(Trajectory, TrajectoryFormat), IoError> {
    parse_named(text, NO_FILE)
}

/// Reads a trajectory file in any of the [`TrajectoryFormat`]s; errors name the file and line.
pub fn read_trajectory(path: &Path) -> Result<(Trajectory, TrajectoryFormat), IoError> {
    let text = read_text(path)?;
    parse_named(&text, &path.display().to_string())
}

/// Writes `traj` in TUM format (`t tx ty tz qx qy qz qw`), with a `#` header line.
///
/// Timestamps get 9 decimals (ns) and pose values 12, so reading the file back gives the same
/// poses to 1e-9. A non-finite value is an error naming the pose index.
pub fn write_tum(path: &Path, traj: &Trajectory) -> Result<(), IoError> {
    let mut out = String::with_capacity(traj.len() * 120);
    out.push_str("# timestamp tx ty tz qx qy qz qw\n");
    for (i, sp) in traj.poses.iter().enumerate() {
        let t = &sp.pose.translation.vector;
        let q = sp.pose.rotation.coords; // x, y, z, w
        let values = [sp.timestamp, t.x, t.y, t.z, q.x, q.y, q.z, q.w];
        check_finite(path, i, &values)?;
        out.push_str(&format!(
            "{:.9} {:.12} {:.12} {:.12} {:.12} {:.12} {:.12} {:.12}\n",
            values[0], values[1], values[2], values[3], values[4], values[5], values[6], values[7]
        ));
    }
    write_text(path, &out)
}

/// Writes `traj` in KITTI format: the 3×4 row-major `[R|t]` of each pose, one per line, 12
/// decimals each. Timestamps are not written (KITTI keeps them in a separate `times.txt`).
pub fn write_kitti(path: &Path, traj: &Trajectory) -> Result<(), IoError> {
    let mut out = String::with_capacity(traj.len() * 200);
    for (i, sp) in traj.poses.iter().enumerate() {
        let m = sp.pose.to_homogeneous();
        let values: Vec<f64> = (0..3)
            .flat_map(|r| (0..4).map(move |c| m[(r, c)]))
            .collect();
        check_finite(path, i, &values)?;
        let line: Vec<String> = values.iter().map(|v| format!("{v:.12}")).collect();
        out.push_str(&line.join(" "));
        out.push('\n');
    }
    write_text(path, &out)
}

/// Builds a pose from a 3×4 `[R|t]`, re-orthonormalising R by polar decomposition (SVD,
/// R ← U Vᵀ). Fails when a value is not finite or R is far from a rotation (a singular value
/// off 1 by more than 5 %, or a reflection).
pub(crate) fn pose_from_matrix(m: &Matrix3x4<f64>) -> Result<Pose3, String> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err("matrix has a non-finite value".into());
    }
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let svd = r.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err("rotation SVD failed".into());
    };
    // A NaN distance (SVD overflow on huge entries, found by fuzzing) counts as too far.
    let far_from_rotation = svd
        .singular_values
        .iter()
        .any(|s| (s - 1.0).abs().is_nan() || (s - 1.0).abs() > MAX_SINGULAR_VALUE_ERROR);
    if far_from_rotation || r.determinant().is_nan() || r.determinant() <= 0.0 {
        return Err(format!(
            "not a rotation matrix (singular values {:?}, det {:.4})",
            svd.singular_values.as_slice(),
            r.determinant()
        ));
    }
    let rotation = Rotation3::from_matrix_unchecked(u * v_t);
    if rotation.matrix().iter().any(|v| !v.is_finite()) {
        return Err("rotation is not finite after re-orthonormalisation".into());
    }
    let t = m.column(3);
    Ok(Pose3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_rotation_matrix(&rotation),
    ))
}

/// Parses a 4×4 homogeneous `[R t; 0 0 0 1]` written as four lines of four numbers
/// (7-Scenes `.pose.txt`, Redwood `.log` blocks) into a re-orthonormalised pose.
///
/// `rows` are (1-based line number, text); errors name the line at fault.
pub(crate) fn pose_from_rows(rows: &[(usize, &str)], file: &str) -> Result<Pose3, IoError> {
    let mut values = Vec::with_capacity(16);
    for &(no, line) in rows {
        let v = parse_numbers(line, file, no)?;
        if v.len() != 4 {
            return Err(IoError::parse(
                file,
                no,
                format!("{} numbers, a matrix row needs 4", v.len()),
            ));
        }
        values.extend(v);
    }
    let last_no = rows.last().map_or(0, |r| r.0);
    if values.len() != 16 {
        return Err(IoError::parse(file, last_no, "a 4x4 matrix needs 4 rows"));
    }
    if values[12..]
        .iter()
        .zip([0.0, 0.0, 0.0, 1.0])
        .any(|(v, w)| (v - w).abs() > 1e-6)
    {
        return Err(IoError::parse(
            file,
            last_no,
            "last matrix row must be 0 0 0 1",
        ));
    }
    let m = Matrix3x4::from_row_slice(&values[..12]);
    pose_from_matrix(&m).map_err(|msg| IoError::parse(file, rows.first().map_or(0, |r| r.0), msg))
}

/// Builds a unit quaternion from (w, x, y, z), normalising it, as every trajectory reader
/// does (TUM, EuRoC, and the Python binding's arrays). Fails on a zero-length or non-finite
/// quaternion.
///
/// ```
/// let q = slamkit_io::trajectory_file::unit_quaternion(2.0, 0.0, 0.0, 0.0).unwrap();
/// assert_eq!(q.w, 1.0);
/// assert!(slamkit_io::trajectory_file::unit_quaternion(0.0, 0.0, 0.0, 0.0).is_err());
/// ```
pub fn unit_quaternion(w: f64, x: f64, y: f64, z: f64) -> Result<UnitQuaternion<f64>, String> {
    let q = Quaternion::new(w, x, y, z);
    let norm = q.norm();
    if !norm.is_finite() || norm < 1e-9 {
        return Err(format!(
            "quaternion (w {w}, x {x}, y {y}, z {z}) cannot be normalised"
        ));
    }
    Ok(UnitQuaternion::from_quaternion(q))
}

/// Parses every whitespace- or comma-separated token of `line` as a finite number.
pub(crate) fn parse_numbers(line: &str, file: &str, line_no: usize) -> Result<Vec<f64>, IoError> {
    line.split(|c: char| c.is_whitespace() || c == ',')
        .filter(|s| !s.is_empty())
        .map(|tok| match tok.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(IoError::parse(
                file,
                line_no,
                format!("non-finite value {tok:?}"),
            )),
            Err(_) => Err(IoError::parse(
                file,
                line_no,
                format!("not a number: {tok:?}"),
            )),
        })
        .collect()
}

/// Converts an integer nanosecond timestamp (EuRoC) to seconds without losing the
/// sub-second digits to f64 rounding of the large integer.
pub(crate) fn parse_ns_as_s(tok: &str) -> Option<f64> {
    tok.trim().parse().ok().map(ns_to_s)
}

/// Nanoseconds to seconds, splitting off whole seconds first to keep the fraction exact.
pub(crate) fn ns_to_s(ns: u64) -> f64 {
    (ns / 1_000_000_000) as f64 + (ns % 1_000_000_000) as f64 * 1e-9
}

/// The lines holding data: not blank, not `#` comments; with 1-based line numbers.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

fn parse_named(text: &str, file: &str) -> Result<(Trajectory, TrajectoryFormat), IoError> {
    let Some((first_no, first)) = data_lines(text).next() else {
        return Err(IoError::Empty {
            file: file.to_string(),
            what: "no pose line".into(),
        });
    };
    if first.contains(',') {
        let columns = EurocColumns::from_header(text);
        return Ok((
            parse_euroc(text, file, &columns)?,
            TrajectoryFormat::EurocCsv,
        ));
    }
    match parse_numbers(first, file, first_no)?.len() {
        8 => Ok((parse_tum(text, file)?, TrajectoryFormat::Tum)),
        12 => Ok((parse_kitti(text, file)?, TrajectoryFormat::Kitti)),
        n => Err(IoError::parse(
            file,
            first_no,
            format!("{n} numbers: expected 8 (TUM t tx ty tz qx qy qz qw) or 12 (KITTI 3x4)"),
        )),
    }
}

fn parse_tum(text: &str, file: &str) -> Result<Trajectory, IoError> {
    let mut traj = Trajectory::new();
    for (no, line) in data_lines(text) {
        let v = parse_numbers(line, file, no)?;
        let [t, x, y, z, qx, qy, qz, qw] = v[..] else {
            return Err(IoError::parse(
                file,
                no,
                format!("{} numbers, TUM needs 8", v.len()),
            ));
        };
        let q = unit_quaternion(qw, qx, qy, qz).map_err(|m| IoError::parse(file, no, m))?;
        traj.push(t, Pose3::from_parts(Translation3::new(x, y, z), q));
    }
    Ok(traj)
}

fn parse_kitti(text: &str, file: &str) -> Result<Trajectory, IoError> {
    let mut traj = Trajectory::new();
    for (index, (no, line)) in data_lines(text).enumerate() {
        let v = parse_numbers(line, file, no)?;
        if v.len() != 12 {
            return Err(IoError::parse(
                file,
                no,
                format!("{} numbers, KITTI needs 12", v.len()),
            ));
        }
        let m = Matrix3x4::from_row_slice(&v);
        let pose = pose_from_matrix(&m).map_err(|msg| IoError::parse(file, no, msg))?;
        traj.push(index as f64, pose);
    }
    Ok(traj)
}

/// Column indices of the EuRoC ground-truth CSV, from its header when it names them.
struct EurocColumns {
    /// p_x, p_y, p_z.
    position: [usize; 3],
    /// q_w, q_x, q_y, q_z.
    quaternion: [usize; 4],
}

impl EurocColumns {
    /// Reads `p_RS_R_x` / `q_RS_w` (official) positions from the last `#` header line before
    /// the data; falls back to the official layout (columns 1–3 position, 4–7 w x y z).
    fn from_header(text: &str) -> Self {
        let default = Self {
            position: [1, 2, 3],
            quaternion: [4, 5, 6, 7],
        };
        let header = text
            .lines()
            .map(str::trim)
            .take_while(|l| l.is_empty() || l.starts_with('#'))
            .filter(|l| l.starts_with('#'))
            .last();
        let Some(header) = header else {
            return default;
        };
        let names: Vec<&str> = header.split(',').map(str::trim).collect();
        let find = |name: &str| names.iter().position(|n| n.starts_with(name));
        match (find("p_RS_R_x"), find("q_RS_w")) {
            (Some(p), Some(q)) => Self {
                position: [p, p + 1, p + 2],
                quaternion: [q, q + 1, q + 2, q + 3],
            },
            _ => default,
        }
    }
}

fn parse_euroc(text: &str, file: &str, cols: &EurocColumns) -> Result<Trajectory, IoError> {
    let needed = 1 + cols
        .position
        .iter()
        .chain(&cols.quaternion)
        .max()
        .unwrap_or(&0);
    let mut traj = Trajectory::new();
    for (no, line) in data_lines(text) {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() < needed {
            return Err(IoError::parse(
                file,
                no,
                format!(
                    "{} columns, EuRoC ground truth needs at least {needed}",
                    fields.len()
                ),
            ));
        }
        let t = fields
            .first()
            .and_then(|f| parse_ns_as_s(f))
            .ok_or_else(|| {
                IoError::parse(
                    file,
                    no,
                    "timestamp is not an integer number of nanoseconds",
                )
            })?;
        let num = |i: usize| -> Result<f64, IoError> {
            let tok = fields.get(i).copied().unwrap_or("");
            match tok.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(IoError::parse(
                    file,
                    no,
                    format!("column {}: bad value {tok:?}", i + 1),
                )),
            }
        };
        let [px, py, pz] = cols.position;
        let [qw, qx, qy, qz] = cols.quaternion;
        let q = unit_quaternion(num(qw)?, num(qx)?, num(qy)?, num(qz)?)
            .map_err(|m| IoError::parse(file, no, m))?;
        traj.push(
            t,
            Pose3::from_parts(Translation3::new(num(px)?, num(py)?, num(pz)?), q),
        );
    }
    Ok(traj)
}

fn check_finite(path: &Path, index: usize, values: &[f64]) -> Result<(), IoError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(IoError::invalid(
            path.display(),
            format!("pose {index} has a non-finite value, not written"),
        ))
    }
}

fn write_text(path: &Path, text: &str) -> Result<(), IoError> {
    let mut file = std::fs::File::create(path).map_err(|e| IoError::io(path, e))?;
    file.write_all(text.as_bytes())
        .map_err(|e| IoError::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Found by the `tum` fuzz target: a huge entry made the SVD's singular values NaN, which
    /// slipped past the "close to a rotation" check and gave a NaN quaternion.
    #[test]
    fn kitti_line_with_huge_entry_is_rejected() {
        let text =
            "0114036608.669 1e308 0.6305 1.6380 0.6132 0.5962 -0.3 1.6380 0.6132 0.5962 -01 -0\n";
        assert!(parse_trajectory(text).is_err());
    }

    fn random_trajectory(seed: u64, n: usize) -> Trajectory {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut traj = Trajectory::new();
        for i in 0..n {
            let t = Vector3::new(
                rng.gen_range(-50.0..50.0),
                rng.gen_range(-5.0..5.0),
                rng.gen_range(-50.0..50.0),
            );
            let axis = Vector3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            );
            let r = UnitQuaternion::from_scaled_axis(axis * 3.0);
            traj.push(1.3e9 + i as f64 * 0.0333, Pose3::from_parts(t.into(), r));
        }
        traj
    }

    #[test]
    fn tum_round_trip_is_exact_to_1e9() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.tum");
        let traj = random_trajectory(7, 200);
        write_tum(&path, &traj).unwrap();
        let (back, format) = read_trajectory(&path).unwrap();
        assert_eq!(format, TrajectoryFormat::Tum);
        assert!(
            traj.max_difference(&back).unwrap() < 1e-9,
            "{}",
            traj.max_difference(&back).unwrap()
        );
    }

    #[test]
    fn kitti_round_trip_is_exact_to_1e9_with_index_timestamps() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("k.txt");
        let mut traj = random_trajectory(8, 100);
        for (i, p) in traj.poses.iter_mut().enumerate() {
            p.timestamp = i as f64;
        }
        write_kitti(&path, &traj).unwrap();
        let (back, format) = read_trajectory(&path).unwrap();
        assert_eq!(format, TrajectoryFormat::Kitti);
        assert!(traj.max_difference(&back).unwrap() < 1e-9);
    }

    #[test]
    fn tum_quaternion_is_normalised_and_comments_skipped() {
        let text = "# header\n\n1.5 1 2 3 0 0 0 2\n# mid comment\n2.5 1 2 3 0 0 2 0\n";
        let (traj, format) = parse_trajectory(text).unwrap();
        assert_eq!(format, TrajectoryFormat::Tum);
        assert_eq!(traj.len(), 2);
        assert!((traj.poses[0].pose.rotation.angle()).abs() < 1e-12);
        assert!((traj.poses[1].pose.rotation.angle() - std::f64::consts::PI).abs() < 1e-12);
        assert_eq!(traj.poses[1].timestamp, 2.5);
    }

    #[test]
    fn euroc_csv_reorders_quaternion_and_converts_ns() {
        let text = "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []\n\
                    1403715524907143168,0.5,2.0,0.9,0.0,1.0,0.0,0.0\n";
        let (traj, format) = parse_trajectory(text).unwrap();
        assert_eq!(format, TrajectoryFormat::EurocCsv);
        let p = &traj.poses[0];
        assert!((p.timestamp - 1_403_715_524.907_143).abs() < 1e-6);
        // q = (w 0, x 1): a half turn about x.
        let axis = p.pose.rotation.axis().unwrap();
        assert!((axis.x.abs() - 1.0).abs() < 1e-12);
        assert_eq!(p.pose.translation.vector, Vector3::new(0.5, 2.0, 0.9));
    }

    #[test]
    fn kitti_rotation_is_reorthonormalised() {
        let text = "1.0002 0 0 1  0 0.9999 0 2  0 0 1.0001 3\n";
        let (traj, _) = parse_trajectory(text).unwrap();
        let r = traj.poses[0].pose.rotation.to_rotation_matrix();
        assert!(
            (r.matrix() * r.matrix().transpose() - Matrix3::identity())
                .abs()
                .max()
                < 1e-12
        );
        assert_eq!(traj.poses[0].timestamp, 0.0);
    }

    fn parse_error_line(text: &str) -> usize {
        match parse_trajectory(text) {
            Err(IoError::Parse { line, .. }) => line,
            other => panic!("expected a parse error, got {other:?}"),
        }
    }

    #[test]
    fn broken_inputs_name_the_line() {
        assert_eq!(parse_error_line("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n"), 2);
        assert_eq!(
            parse_error_line("# c\n1 0 0 0 0 0 0 1\n2 0 nan 0 0 0 0 1\n"),
            3
        );
        assert_eq!(parse_error_line("1 0 0 0 0 0 0 1\n2 0 0 inf 0 0 0 1\n"), 2);
        assert_eq!(parse_error_line("1 0 0 0 0 0 0 0\n"), 1);
        assert_eq!(parse_error_line("1 0 0 0 0 x 0 1\n"), 1);
        assert_eq!(parse_error_line("1 2 3\n"), 1);
        assert_eq!(
            parse_error_line("1 0 0 0 0 1 0 0 0 0 1 0\n0 0 0 0 0 0 0 0 0 0 0 0\n"),
            2
        );
        assert_eq!(parse_error_line("-1 0 0 0 0 1 0 0 0 0 1 0\n"), 1);
        assert_eq!(parse_error_line("#timestamp\n1.5,0,0,0,1,0,0,0\n"), 2);
        assert_eq!(parse_error_line("#timestamp\n1,0,0,0,1,0,0\n"), 2);
    }

    #[test]
    fn empty_input_is_an_error() {
        assert!(matches!(parse_trajectory(""), Err(IoError::Empty { .. })));
        assert!(matches!(
            parse_trajectory("# only\n\n"),
            Err(IoError::Empty { .. })
        ));
    }

    #[test]
    fn missing_file_and_nan_pose_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let err = read_trajectory(&dir.path().join("none.txt")).unwrap_err();
        assert!(err.to_string().contains("none.txt"));
        let mut traj = Trajectory::new();
        traj.push(f64::NAN, Pose3::identity());
        assert!(write_tum(&dir.path().join("x.tum"), &traj).is_err());
    }
}
