//! Per-stage wall-clock timings, summarised as median and 95th percentile.
//!
//! Pipelines record how long each stage took on each frame; reports show the median (typical
//! cost) and p95 (the hiccups a real-time loop must absorb), which are robust to the noise of
//! shared machines where a mean is not.

use std::collections::BTreeMap;
use std::time::Instant;

/// Durations per named stage, in milliseconds.
#[derive(Debug, Clone, Default)]
pub struct StageTimings {
    samples_ms: BTreeMap<String, Vec<f64>>,
}

/// Summary of one stage's durations.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TimingSummary {
    /// Median duration \[ms\].
    pub median_ms: f64,
    /// 95th percentile duration \[ms\] (nearest rank).
    pub p95_ms: f64,
    /// Total time spent in the stage \[ms\].
    pub total_ms: f64,
    /// Number of samples.
    pub count: usize,
}

impl StageTimings {
    /// Records one duration for `stage`.
    pub fn record(&mut self, stage: &str, ms: f64) {
        self.samples_ms
            .entry(stage.to_owned())
            .or_default()
            .push(ms);
    }

    /// Records the time from `start` until now for `stage`.
    pub fn record_since(&mut self, stage: &str, start: Instant) {
        self.record(stage, start.elapsed().as_secs_f64() * 1e3);
    }

    /// Runs `f`, records its duration under `stage` and returns its result.
    pub fn time<T>(&mut self, stage: &str, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        self.record_since(stage, start);
        out
    }

    /// Adds every sample of `other` to this one.
    pub fn merge(&mut self, other: &StageTimings) {
        for (stage, samples) in &other.samples_ms {
            self.samples_ms
                .entry(stage.clone())
                .or_default()
                .extend(samples);
        }
    }

    /// Median, p95, total and count per stage, in stage-name order.
    pub fn summary(&self) -> BTreeMap<String, TimingSummary> {
        self.samples_ms
            .iter()
            .filter(|(_, s)| !s.is_empty())
            .map(|(stage, samples)| (stage.clone(), summarise(samples)))
            .collect()
    }
}

fn summarise(samples: &[f64]) -> TimingSummary {
    let mut sorted = samples.to_vec();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    let median_ms = if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    };
    let rank = ((0.95 * n as f64).ceil() as usize).clamp(1, n);
    TimingSummary {
        median_ms,
        p95_ms: sorted[rank - 1],
        total_ms: sorted.iter().sum(),
        count: n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_p95() {
        let mut t = StageTimings::default();
        for i in 1..=100 {
            t.record("match", i as f64);
        }
        t.record("insert", 2.0);
        t.record("insert", 4.0);
        let s = t.summary();
        assert_eq!(s["match"].median_ms, 50.5);
        assert_eq!(s["match"].p95_ms, 95.0);
        assert_eq!(s["match"].count, 100);
        assert_eq!(s["insert"].median_ms, 3.0);
        assert_eq!(s["insert"].total_ms, 6.0);
    }
}
