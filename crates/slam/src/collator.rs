//! Puts observations from several sources back into time order.
//!
//! A robot's sensors arrive through different drivers, threads or bag connections, so a range
//! reading stamped before a scan may arrive after it. The collator holds every observation for
//! `window_s` of sensor time and releases them oldest first once a newer one proves the window
//! has passed; at equal timestamps readings leave before frames (scans, images), as
//! [`time_ordered`](slamkit_core::observation::time_ordered) orders a recording, then in
//! arrival order. An observation older than what was already released cannot be put in order; it
//! is dropped and counted, never passed on out of order.

use slamkit_core::Observation;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Orders observations within a time window.
///
/// ```
/// use slamkit_core::observation::{Observation, RangePair};
/// use slamkit_slam::Collator;
///
/// let range = |t| Observation::Range(RangePair { timestamp: t, up_m: None, down_m: Some(1.0) });
/// let mut collator = Collator::new(0.5);
/// let mut out = Vec::new();
/// for t in [1.0, 0.8, 1.2, 2.0] {
///     out.extend(collator.push(range(t)));
/// }
/// out.extend(collator.finish());
/// let times: Vec<f64> = out.iter().map(Observation::timestamp).collect();
/// assert_eq!(times, [0.8, 1.0, 1.2, 2.0]);
/// ```
#[derive(Debug)]
pub struct Collator {
    window_s: f64,
    pending: BinaryHeap<Pending>,
    /// Arrival counter: equal timestamps leave in arrival order.
    arrivals: u64,
    /// Timestamp of the last observation released.
    released_until: f64,
    /// Newest timestamp seen.
    newest: f64,
    dropped_late: usize,
    dropped_invalid: usize,
}

impl Collator {
    /// A collator holding observations for `window_s` seconds of sensor time (0: pass each one
    /// on at once, dropping any older than the last).
    pub fn new(window_s: f64) -> Self {
        Self {
            window_s: if window_s.is_finite() {
                window_s.max(0.0)
            } else {
                0.0
            },
            pending: BinaryHeap::new(),
            arrivals: 0,
            released_until: f64::NEG_INFINITY,
            newest: f64::NEG_INFINITY,
            dropped_late: 0,
            dropped_invalid: 0,
        }
    }

    /// Takes one observation; returns those now known to be in order, oldest first.
    pub fn push(&mut self, observation: Observation) -> Vec<Observation> {
        let t = observation.timestamp();
        if !t.is_finite() {
            self.dropped_invalid += 1;
            return Vec::new();
        }
        if t < self.released_until {
            self.dropped_late += 1;
            return Vec::new();
        }
        self.arrivals += 1;
        self.pending.push(Pending {
            timestamp: t,
            frame: observation.is_frame(),
            arrival: self.arrivals,
            observation,
        });
        self.newest = self.newest.max(t);
        let horizon = self.newest - self.window_s;
        self.release_while(|oldest| oldest <= horizon)
    }

    /// Releases everything still held, oldest first (the end of a recording).
    pub fn finish(&mut self) -> Vec<Observation> {
        self.release_while(|_| true)
    }

    /// Observations dropped because they arrived after newer ones had been released.
    pub fn dropped_late(&self) -> usize {
        self.dropped_late
    }

    /// Observations dropped for a timestamp that is not a finite number.
    pub fn dropped_invalid(&self) -> usize {
        self.dropped_invalid
    }

    fn release_while(&mut self, mut ready: impl FnMut(f64) -> bool) -> Vec<Observation> {
        let mut out = Vec::new();
        while let Some(oldest) = self.pending.peek() {
            if !ready(oldest.timestamp) {
                break;
            }
            if let Some(p) = self.pending.pop() {
                self.released_until = p.timestamp;
                out.push(p.observation);
            }
        }
        out
    }
}

/// A held observation, ordered oldest (then readings before frames, then first arrived) first
/// in the max-heap.
#[derive(Debug)]
struct Pending {
    timestamp: f64,
    frame: bool,
    arrival: u64,
    observation: Observation,
}

impl PartialEq for Pending {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Pending {}

impl PartialOrd for Pending {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Pending {
    fn cmp(&self, other: &Self) -> Ordering {
        // Reversed: the heap's top is the oldest.
        other
            .timestamp
            .total_cmp(&self.timestamp)
            .then(other.frame.cmp(&self.frame))
            .then(other.arrival.cmp(&self.arrival))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_core::observation::RangePair;

    fn range(t: f64) -> Observation {
        Observation::Range(RangePair {
            timestamp: t,
            up_m: None,
            down_m: Some(t),
        })
    }

    fn times(obs: &[Observation]) -> Vec<f64> {
        obs.iter().map(Observation::timestamp).collect()
    }

    #[test]
    fn shuffled_within_the_window_comes_out_sorted() {
        let mut c = Collator::new(0.3);
        let mut out = Vec::new();
        for t in [0.0, 0.2, 0.1, 0.4, 0.3, 0.6, 0.5, 1.0] {
            out.extend(c.push(range(t)));
        }
        // 1.0 arrived: everything at or before 0.7 is in order
        assert_eq!(times(&out), [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]);
        out.extend(c.finish());
        assert_eq!(times(&out), [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 1.0]);
        assert_eq!(c.dropped_late(), 0);
    }

    #[test]
    fn too_late_and_nan_are_dropped_and_counted() {
        let mut c = Collator::new(0.1);
        let mut out = c.push(range(1.0));
        out.extend(c.push(range(2.0)));
        assert_eq!(times(&out), [1.0]);
        assert!(c.push(range(0.5)).is_empty());
        assert!(c.push(range(f64::NAN)).is_empty());
        out.extend(c.finish());
        assert_eq!(times(&out), [1.0, 2.0]);
        assert_eq!((c.dropped_late(), c.dropped_invalid()), (1, 1));
    }

    #[test]
    fn equal_times_keep_arrival_order() {
        let mut c = Collator::new(0.0);
        let a = Observation::Range(RangePair {
            timestamp: 1.0,
            up_m: Some(1.0),
            down_m: None,
        });
        let b = Observation::Range(RangePair {
            timestamp: 1.0,
            up_m: Some(2.0),
            down_m: None,
        });
        let mut out = c.push(a);
        out.extend(c.push(b));
        out.extend(c.finish());
        let ups: Vec<Option<f64>> = out
            .iter()
            .map(|o| match o {
                Observation::Range(r) => r.up_m,
                _ => None,
            })
            .collect();
        assert_eq!(ups, [Some(1.0), Some(2.0)]);
    }

    /// A live range reading stamped with a scan's time but arriving after it still goes
    /// first, as in a recording: the scan is matched with the reading of its own time.
    #[test]
    fn a_reading_of_a_frames_time_goes_before_it_whatever_the_arrival() {
        let scan = Observation::Scan(slamkit_core::LaserScan {
            timestamp: 1.0,
            angle_min_rad: 0.0,
            angle_increment_rad: 0.1,
            ranges_m: vec![1.0; 3],
            max_range_m: 10.0,
            odometry: None,
            base_from_laser: slamkit_core::Pose2::identity(),
        });
        let mut c = Collator::new(0.5);
        let mut out = c.push(scan);
        out.extend(c.push(range(1.0)));
        out.extend(c.finish());
        let kinds: Vec<&str> = out.iter().map(Observation::kind).collect();
        assert_eq!(kinds, ["range", "scan"]);
    }
}
