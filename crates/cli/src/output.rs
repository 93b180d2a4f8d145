//! What every command shares for its outputs: progress bars, report.json and the end of a run,
//! peak memory, and one-line error messages.

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use slamkit_io::output_folder::OutputFolder;
pub use slamkit_slam::report::merge_json;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

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

/// A flag set by Ctrl-C or SIGTERM, for a command that runs until stopped.
pub fn stop_flag() -> anyhow::Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    Ok(stop)
}

/// Ends a run: writes `report`, with the run's peak memory as `peak_rss_bytes`, as pretty JSON
/// to `report.json` and moves every output into
/// the output folder (each atomically; see [`OutputFolder`]), removing the files an earlier
/// run left there that this one did not write (said on stderr). A report whose
/// `metrics.error` is set (scoring failed) is written, then returned as the run's error.
pub fn finish(folder: OutputFolder, report: &serde_json::Value) -> anyhow::Result<()> {
    finish_run(folder, report, None)
}

/// [`finish`], with `report.html` beside `report.json`: the page of
/// [`slamkit_slam::report::page`], headed `title`, drawn from the folder's outputs.
pub fn finish_with_page(
    folder: OutputFolder,
    report: &serde_json::Value,
    title: &str,
) -> anyhow::Result<()> {
    finish_run(folder, report, Some(title))
}

fn finish_run(
    folder: OutputFolder,
    report: &serde_json::Value,
    page_title: Option<&str>,
) -> anyhow::Result<()> {
    let mut report = report.clone();
    report["peak_rss_bytes"] = serde_json::json!(slamkit_slam::memory::peak_rss_bytes());
    let text = serde_json::to_string_pretty(&report).context("serialising report")?;
    std::fs::write(folder.path().join("report.json"), text + "\n")
        .with_context(|| format!("writing report.json in {}", folder.dir().display()))?;
    if let Some(title) = page_title {
        slamkit_slam::report::page::write_run_page(folder.path(), title, &report)
            .with_context(|| format!("writing report.html in {}", folder.dir().display()))?;
    }
    let dir = folder.dir().to_path_buf();
    let removed = folder.commit()?;
    if !removed.is_empty() {
        eprintln!(
            "note: removed from {} what an earlier run wrote and this one did not: {}",
            dir.display(),
            removed.join(", ")
        );
    }
    if let Some(error) = report["metrics"]["error"].as_str() {
        let path = dir.join("report.json");
        anyhow::bail!("{error} (the rest of the run is in {})", path.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chain_joins_causes() {
        let err = anyhow::anyhow!("root cause").context("reading log.clf");
        assert_eq!(error_chain(&err), "reading log.clf: root cause");
    }
}
