//! This process's memory as the operating system counts it (Linux `/proc`), for run reports
//! (peak resident memory) and for refusing runs a machine cannot hold
//! ([`crate::lidar::preflight::ensure_fits_memory`]). Elsewhere both are unknown (`None`).

/// Peak resident memory of this process in bytes (`VmHWM`), when the OS tells it.
///
/// ```
/// if cfg!(target_os = "linux") {
///     assert!(slamkit_slam::memory::peak_rss_bytes().is_some_and(|b| b > 0));
/// }
/// ```
pub fn peak_rss_bytes() -> Option<u64> {
    proc_kib("/proc/self/status", "VmHWM:").map(|kib| kib * 1024)
}

/// Resident memory of this process now in bytes (`VmRSS`), when the OS tells it: what a
/// long run checks stays flat (the peak only ever grows).
pub fn rss_bytes() -> Option<u64> {
    proc_kib("/proc/self/status", "VmRSS:").map(|kib| kib * 1024)
}

/// The machine's memory in bytes (`MemTotal`), when the OS tells it.
pub fn total_bytes() -> Option<u64> {
    proc_kib("/proc/meminfo", "MemTotal:").map(|kib| kib * 1024)
}

/// A `KEY: N kB` value of a /proc file, in KiB.
fn proc_kib(file: &str, key: &str) -> Option<u64> {
    let text = std::fs::read_to_string(file).ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
