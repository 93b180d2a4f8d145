//! Why a scan had too few usable beams to be matched: the broken-scan counts of a run.
//!
//! A scan is skipped (it keeps its predicted pose) when fewer than `min_scan_points` of its
//! beams give a usable point. The reason recorded is the most common defect among its beams, so
//! an all-NaN scan counts as `non_finite`, a scan of overflow readings as `no_return`, and so on.

use serde::Serialize;
use slamkit_core::LaserScan;

/// What was wrong with a skipped scan.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BrokenScan {
    /// The scan has no beam at all.
    Empty,
    /// Most beams are NaN or infinite.
    NonFinite,
    /// Most beams are negative or zero.
    Negative,
    /// Most beams are "no return" readings (at or beyond the scan's or the mapper's maximum
    /// range).
    NoReturn,
    /// Most beams are closer than the mapper's minimum range.
    TooShort,
    /// Every beam is usable, but there are fewer than the mapper needs.
    TooFewBeams,
}

/// Skipped scans by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct BrokenScanCounts {
    /// See [`BrokenScan::Empty`].
    pub empty: usize,
    /// See [`BrokenScan::NonFinite`].
    pub non_finite: usize,
    /// See [`BrokenScan::Negative`].
    pub negative: usize,
    /// See [`BrokenScan::NoReturn`].
    pub no_return: usize,
    /// See [`BrokenScan::TooShort`].
    pub too_short: usize,
    /// See [`BrokenScan::TooFewBeams`].
    pub too_few_beams: usize,
}

impl BrokenScanCounts {
    /// Counts one skipped scan.
    pub fn add(&mut self, reason: BrokenScan) {
        let count = match reason {
            BrokenScan::Empty => &mut self.empty,
            BrokenScan::NonFinite => &mut self.non_finite,
            BrokenScan::Negative => &mut self.negative,
            BrokenScan::NoReturn => &mut self.no_return,
            BrokenScan::TooShort => &mut self.too_short,
            BrokenScan::TooFewBeams => &mut self.too_few_beams,
        };
        *count += 1;
    }

    /// All skipped scans.
    pub fn total(&self) -> usize {
        self.empty
            + self.non_finite
            + self.negative
            + self.no_return
            + self.too_short
            + self.too_few_beams
    }
}

/// The most common defect among the beams of `scan`, for beams kept in
/// `[min_range_m, max_range_m)`; ties go to the earlier reason in [`BrokenScan`]'s order.
pub fn classify(scan: &LaserScan, min_range_m: f64, max_range_m: f64) -> BrokenScan {
    if scan.ranges_m.is_empty() {
        return BrokenScan::Empty;
    }
    let no_return = scan.max_range_m.min(max_range_m);
    let mut counts = [0usize; 4];
    for r in &scan.ranges_m {
        let slot = if !r.is_finite() {
            0
        } else if *r <= 0.0 {
            1
        } else if *r >= no_return {
            2
        } else if *r < min_range_m {
            3
        } else {
            continue;
        };
        if let Some(c) = counts.get_mut(slot) {
            *c += 1;
        }
    }
    let reasons = [
        BrokenScan::NonFinite,
        BrokenScan::Negative,
        BrokenScan::NoReturn,
        BrokenScan::TooShort,
    ];
    reasons
        .into_iter()
        .zip(counts)
        .filter(|(_, n)| *n > 0)
        .fold(
            None,
            |best: Option<(BrokenScan, usize)>, (reason, n)| match best {
                Some((_, m)) if m >= n => best,
                _ => Some((reason, n)),
            },
        )
        .map_or(BrokenScan::TooFewBeams, |(reason, _)| reason)
}
