//! What every command shares for its outputs: the output folder, progress bars, report.json,
//! peak memory, and one-line error messages.

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};

/// Formats an error and its causes on one line: `outer: cause: root cause`.
pub fn error_chain(err: &anyhow::Error) -> String {
    err.chain()
        .map(|e| e.to_string())
        .collect::<Vec<_>>()
        .join(": ")
}

/// A run that finished and wrote its outputs but did not do what it was asked: the goal not
/// reached, localisation that never found the robot. `main` exits with
/// [`UNSUCCESSFUL_EXIT`] for it, so a script can tell it from an error (1) or bad arguments
/// (2) without reading the report.
#[derive(Debug)]
pub struct Unsuccessful(pub String);

impl std::fmt::Display for Unsuccessful {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Unsuccessful {}

/// Exit code of an [`Unsuccessful`] run.
pub const UNSUCCESSFUL_EXIT: u8 = 3;

/// Creates the output folder (and its parents) and checks that files can be written in it,
/// so a run does not fail at its end for want of a place to put its results.
pub fn prepare_out_dir(dir: &Path) -> anyhow::Result<PathBuf> {
    anyhow::ensure!(
        !dir.exists() || dir.is_dir(),
        "output folder {} is a file",
        dir.display()
    );
    std::fs::create_dir_all(dir)
        .with_context(|| format!("creating output folder {}", dir.display()))?;
    let probe = dir.join(".slamkit-write-check");
    std::fs::write(&probe, b"")
        .with_context(|| format!("output folder {} is not writable", dir.display()))?;
    std::fs::remove_file(&probe)
        .with_context(|| format!("output folder {} is not writable", dir.display()))?;
    Ok(dir.to_path_buf())
}

/// A progress bar over `len` items, drawn on stderr; hidden when stderr is not a terminal.
pub fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    let style = ProgressStyle::with_template(
        "{msg:>10} [{elapsed_precise}] {wide_bar} {pos}/{len} ({per_sec}, eta {eta})",
    )
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar.set_message(what.to_owned());
    bar
}

/// Peak resident memory of this process in bytes (VmHWM from /proc), when the OS tells it.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Writes `report` as pretty JSON to `dir/report.json`, atomically (a reader sees the old
/// report or the whole new one). A report whose `metrics.error` is set (scoring failed) is
/// written, then returned as the run's error.
pub fn write_report(dir: &Path, report: &serde_json::Value) -> anyhow::Result<()> {
    let path = dir.join("report.json");
    let text = serde_json::to_string_pretty(report).context("serialising report")?;
    slamkit_slam::map_file::write_atomically(&path, (text + "\n").as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    if let Some(error) = report["metrics"]["error"].as_str() {
        anyhow::bail!("{error} (the rest of the run is in {})", path.display());
    }
    Ok(())
}

/// The per-stage timing summary as JSON: `{stage: {median_ms, p95_ms, total_ms, count}}`.
pub fn timings_json(timings: &slamkit_core::StageTimings) -> serde_json::Value {
    serde_json::to_value(timings.summary()).unwrap_or(serde_json::Value::Null)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chain_joins_causes() {
        let err = anyhow::anyhow!("root cause").context("reading log.clf");
        assert_eq!(error_chain(&err), "reading log.clf: root cause");
    }

    #[test]
    fn peak_rss_is_reported_on_linux() {
        if cfg!(target_os = "linux") {
            assert!(peak_rss_bytes().is_some_and(|b| b > 0));
        }
    }
}
