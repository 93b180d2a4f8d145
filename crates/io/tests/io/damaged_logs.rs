//! Issue 25, reader side: damaged copies of the real lidar logs under `$SLAMKIT_DATA` (Intel
//! and MRPT Telecom Faculty, see `lidar2d/SOURCES.md`), made in a temporary folder, must give
//! an error naming the file and place, or a counted and flagged result, never a shorter or
//! reordered log that looks complete.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use slamkit_io::carmen::{read_carmen, CarmenError};
use slamkit_io::mrpt_text::read_mrpt_text;

const INTEL: &str = "intel/intel.fromrosbag.clf.gz";
const TELECOM: &str = "mrpt/2006-01ENE-21-SENA_Telecom_Faculty_one_loop_only.fromrawlog.txt";

fn lidar_file(test: &str, relative: &str) -> Option<PathBuf> {
    slamkit_testdata::data(test, &format!("lidar2d/{relative}"))
}

/// The Intel log's text, decompressed.
fn intel_lines(path: &Path) -> Vec<String> {
    let mut text = String::new();
    flate2::read::MultiGzDecoder::new(std::fs::File::open(path).unwrap())
        .read_to_string(&mut text)
        .unwrap();
    text.lines().map(str::to_string).collect()
}

fn write_gz(path: &Path, lines: &[String]) {
    let mut enc = flate2::write::GzEncoder::new(
        std::fs::File::create(path).unwrap(),
        flate2::Compression::fast(),
    );
    enc.write_all(lines.join("\n").as_bytes()).unwrap();
    enc.finish().unwrap();
}

/// Item 3: the gzip log cut at 60 % of its bytes, or with one byte flipped in the middle.
#[test]
fn truncated_or_corrupted_gzip_log_is_an_error_naming_the_place() {
    let Some(intel) = lidar_file(
        "truncated_or_corrupted_gzip_log_is_an_error_naming_the_place",
        INTEL,
    ) else {
        return;
    };
    let bytes = std::fs::read(&intel).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let cut = tmp.path().join("cut.clf.gz");
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let err = read_carmen(&cut).unwrap_err();
    let CarmenError::Read { line, scans, .. } = &err else {
        panic!("{err}");
    };
    assert!(*line > 1000 && *scans > 1000 && *scans < 13631, "{err}");
    let msg = err.to_string();
    assert!(
        msg.starts_with(&format!("{}:{line}: ", cut.display())),
        "{msg}"
    );
    assert!(
        !msg.contains('\n') && msg.contains("damaged or truncated"),
        "{msg}"
    );

    let flipped = tmp.path().join("flipped.clf.gz");
    let mut damaged = bytes.clone();
    let middle = damaged.len() / 2;
    damaged[middle] ^= 0x55;
    std::fs::write(&flipped, &damaged).unwrap();
    let err = read_carmen(&flipped).unwrap_err();
    assert!(matches!(err, CarmenError::Read { .. }), "{err}");
}

/// Item 5: the Intel log reversed, or with its halves swapped, is refused; one scan line
/// moved back is read in file order and counted.
#[test]
fn out_of_order_intel_logs_are_refused_or_counted() {
    let Some(intel) = lidar_file("out_of_order_intel_logs_are_refused_or_counted", INTEL) else {
        return;
    };
    let lines = intel_lines(&intel);
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("damaged.clf.gz");

    let mut reversed = lines.clone();
    reversed.reverse();
    write_gz(&path, &reversed);
    let err = read_carmen(&path).unwrap_err();
    assert!(matches!(err, CarmenError::OutOfOrder { .. }), "{err}");
    assert!(
        err.to_string().contains("mostly out of time order"),
        "{err}"
    );

    let mut swapped = lines.clone();
    swapped.rotate_left(lines.len() / 2);
    write_gz(&path, &swapped);
    let err = read_carmen(&path).unwrap_err().to_string();
    assert!(err.contains("step back 632 times"), "{err}");
}

/// Item 6: one `inf` beam (and one `nan`) in the 5000th scan of the Intel log: every scan is
/// still read, the beams are not hits.
#[test]
fn non_finite_beams_keep_the_intel_scan() {
    let Some(intel) = lidar_file("non_finite_beams_keep_the_intel_scan", INTEL) else {
        return;
    };
    let mut lines = intel_lines(&intel);
    let (line, _) = lines
        .iter()
        .enumerate()
        .filter(|(_, l)| l.starts_with("RAWLASER1"))
        .nth(4999)
        .unwrap();
    let mut fields: Vec<String> = lines[line].split(' ').map(str::to_string).collect();
    fields[9 + 10] = "inf".into();
    fields[9 + 20] = "nan".into();
    lines[line] = fields.join(" ");
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("inf.clf.gz");
    write_gz(&path, &lines);
    let log = read_carmen(&path).unwrap();
    assert_eq!(log.scans.len(), 13631);
    assert!(log.skipped.is_empty(), "{:?}", log.skipped.first());
    let scan = &log.scans[4999];
    assert!(scan.ranges_m[10].is_infinite() && scan.ranges_m[20].is_nan());
    assert!(!scan.is_hit(10) && !scan.is_hit(20) && scan.hit_count() > 100);
}

/// Items 5 and 6 for MRPT text: the real Telecom Faculty log reversed is refused.
#[test]
fn reversed_mrpt_log_is_refused() {
    let Some(telecom) = lidar_file("reversed_mrpt_log_is_refused", TELECOM) else {
        return;
    };
    let text = std::fs::read_to_string(&telecom).unwrap();
    assert_eq!(
        read_mrpt_text(&telecom).unwrap().time_order.backward_steps,
        0
    );
    let reversed: Vec<&str> = text.lines().rev().collect();
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("reversed.txt");
    std::fs::write(&path, reversed.join("\n")).unwrap();
    let err = read_mrpt_text(&path).unwrap_err().to_string();
    assert!(
        err.starts_with(&format!("{}: log is mostly out", path.display())),
        "{err}"
    );
}
