//! Timestamps that run backwards in a sensor log, counted as the log is read.
//!
//! Lidar logs are kept in file order, never sorted: the Intel benchmark log's scan stamps step
//! back 631 times (by at most 0.9 s, 236 s in all over its 2691 s) while its file order is
//! the physical order. A log whose halves were swapped, or that was written in reverse, is
//! another matter: read in file order it would teleport the robot. [`TimeOrder`] counts the
//! backward steps (and the first line with one) so that reports can show them, and
//! [`TimeOrder::is_mostly_out_of_order`] tells when a log is too disordered to be read as is:
//! more than [`MAX_BACKWARD_FRACTION`] of its steps go back, or its backward steps add up to
//! more than that fraction of its time span (one step back over half a log is a swap, not
//! jitter). The Intel log is at 4.6 % of steps and 8.8 % of its span.

use serde::Serialize;

/// Largest accepted share of backward steps, both of the steps and of the time span \[-\].
pub const MAX_BACKWARD_FRACTION: f64 = 0.25;

/// Order of the timestamps of a log's records (scans), in file order.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct TimeOrder {
    /// Consecutive pairs of records compared (records − 1).
    pub steps: usize,
    /// Pairs whose later record has the earlier stamp.
    pub backward_steps: usize,
    /// Line (1-based) of the first record whose stamp is before its predecessor's.
    pub first_backward_line: Option<usize>,
    /// Sum of the backward steps' sizes \[s\].
    pub backward_s: f64,
    /// Latest minus earliest stamp \[s\].
    pub span_s: f64,
    /// Stamp of the last record, and the earliest and latest stamps so far.
    #[serde(skip)]
    seen: Option<Seen>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Seen {
    last: f64,
    min: f64,
    max: f64,
}

impl TimeOrder {
    /// Records the stamp `t` of the record on `line` (records in file order).
    ///
    /// ```
    /// use slamkit_io::time_order::TimeOrder;
    /// let mut order = TimeOrder::default();
    /// for (line, t) in (1..).zip([0.0, 1.0, 2.0, 3.0, 2.5, 4.0, 5.0]) {
    ///     order.add(t, line);
    /// }
    /// assert_eq!((order.steps, order.backward_steps), (6, 1));
    /// assert_eq!(order.first_backward_line, Some(5));
    /// assert_eq!((order.backward_s, order.span_s), (0.5, 5.0));
    /// assert!(!order.is_mostly_out_of_order()); // 1 step in 6, 0.5 s of 5 s
    /// ```
    pub fn add(&mut self, t: f64, line: usize) {
        let Some(seen) = &mut self.seen else {
            self.seen = Some(Seen {
                last: t,
                min: t,
                max: t,
            });
            return;
        };
        self.steps += 1;
        if t < seen.last {
            self.backward_steps += 1;
            self.first_backward_line.get_or_insert(line);
            // Halved, and capped, so that stamps near ±f64::MAX cannot give infinity.
            self.backward_s = (self.backward_s + 2.0 * (seen.last / 2.0 - t / 2.0)).min(f64::MAX);
        }
        seen.last = t;
        seen.min = seen.min.min(t);
        seen.max = seen.max.max(t);
        self.span_s = (2.0 * (seen.max / 2.0 - seen.min / 2.0)).min(f64::MAX);
    }

    /// True when more than [`MAX_BACKWARD_FRACTION`] of the steps go back in time, or the
    /// backward steps add up to more than that fraction of the time span (a reversed log, or
    /// one whose parts were swapped).
    pub fn is_mostly_out_of_order(&self) -> bool {
        let many = self.backward_steps as f64 > MAX_BACKWARD_FRACTION * self.steps as f64;
        let far = self.span_s > 0.0 && self.backward_s > MAX_BACKWARD_FRACTION * self.span_s;
        many || far
    }

    /// One line for a warning or an error: how many steps go back, by how much, and where the
    /// first is; `None` when the stamps never go back.
    pub fn describe(&self) -> Option<String> {
        let line = self.first_backward_line?;
        Some(format!(
            "timestamps step back {} times in {} steps ({:.1} s in all over a {:.1} s span), \
             first at line {line}",
            self.backward_steps, self.steps, self.backward_s, self.span_s
        ))
    }

    /// `Err` with the reason when [`TimeOrder::is_mostly_out_of_order`].
    pub(crate) fn check(&self) -> Result<(), String> {
        match self.describe() {
            Some(what) if self.is_mostly_out_of_order() => Err(format!(
                "log is mostly out of time order: {what}; at most {:.0} % of the steps and of \
                 the span may go back",
                100.0 * MAX_BACKWARD_FRACTION
            )),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn order_of(stamps: &[f64]) -> TimeOrder {
        let mut order = TimeOrder::default();
        for (i, &t) in stamps.iter().enumerate() {
            order.add(t, i + 1);
        }
        order
    }

    #[test]
    fn small_steps_back_are_counted_not_refused() {
        // 1 in 10 steps back by 0.05 s: jitter, like the Intel log's
        let stamps: Vec<f64> = (0..100)
            .map(|i| i as f64 * 0.1 - if i % 10 == 5 { 0.15 } else { 0.0 })
            .collect();
        let order = order_of(&stamps);
        assert_eq!((order.steps, order.backward_steps), (99, 10));
        assert_eq!(order.first_backward_line, Some(6));
        assert!(!order.is_mostly_out_of_order());
        assert!(order.check().is_ok());
        assert!(order.describe().unwrap().contains("first at line 6"));
    }

    #[test]
    fn reversed_and_swapped_logs_are_refused() {
        let forward: Vec<f64> = (0..100).map(|i| i as f64).collect();
        assert!(order_of(&forward).describe().is_none());
        let reversed: Vec<f64> = forward.iter().rev().copied().collect();
        let order = order_of(&reversed);
        assert_eq!(order.backward_steps, 99);
        assert!(order.is_mostly_out_of_order());
        // halves swapped: one step back, over the whole span
        let swapped: Vec<f64> = forward[50..]
            .iter()
            .chain(&forward[..50])
            .copied()
            .collect();
        let order = order_of(&swapped);
        assert_eq!(order.backward_steps, 1);
        assert_eq!(order.first_backward_line, Some(51));
        let err = order.check().unwrap_err();
        assert!(err.contains("99.0 s in all over a 99.0 s span"), "{err}");
        // equal stamps (logs without time) are in order
        assert!(order_of(&[0.0; 10]).check().is_ok());
    }

    #[test]
    fn extreme_stamps_stay_finite() {
        let order = order_of(&[f64::MAX, -f64::MAX, f64::MAX]);
        assert!(order.backward_s.is_finite() && order.span_s.is_finite());
        assert!(order.is_mostly_out_of_order());
    }
}
