//! Live scans tied to wheel odometry by the rule the bag and CARMEN readers use
//! ([`slamkit_io::odometry_bracket`]): a scan gets the odometry of the readings just before
//! and just after it, interpolated at its stamp. In a file "before" and "after" are the file's
//! order; live they are the order of publication, which DDS gives as each sample's source
//! timestamp (the writer's clock when it wrote the sample). Arrival order would not do: two
//! topics come through two readers, and while the session is busy both queues fill, so which
//! was first is lost; the source timestamps keep it. A log played into the node in its file
//! order therefore gets exactly the odometry the file run gets, however the samples arrive.
//!
//! A scan waits for the first odometry published after it (the same wait as `slam_toolbox`'s
//! for the `odom → base` transform at the scan's time); a scan that has waited `max_wait` is
//! taken with the odometry before it alone, as the last scans of a log are, so a robot whose
//! odometry stops does not stop mapping. Samples of one topic are assumed to arrive in their
//! publication order (one writer per topic, as on a robot).

use slamkit_core::LaserScan;
use slamkit_io::odometry_bracket::{odometry_at, OdomSample};
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// A scan waiting for the odometry published after it.
struct Pending {
    published_ns: i64,
    scan: LaserScan,
    arrived: Instant,
}

/// Ties scans to odometry in publication order (see the module documentation).
///
/// ```
/// use slamkit_core::{LaserScan, Pose2};
/// use slamkit_io::odometry_bracket::OdomSample;
/// use slamkit_ros2::pairing::OdometryPairing;
/// use std::time::{Duration, Instant};
///
/// let scan = LaserScan {
///     timestamp: 1.5,
///     angle_min_rad: 0.0,
///     angle_increment_rad: 0.1,
///     ranges_m: vec![1.0; 3],
///     max_range_m: 10.0,
///     odometry: None,
///     base_from_laser: Pose2::identity(),
/// };
/// let odom = |t: f64, x: f64| OdomSample { timestamp: t, pose: Pose2::new([x, 0.0].into(), 0.0) };
/// let mut pairing = OdometryPairing::new(Duration::from_millis(500));
/// let now = Instant::now();
/// // the scan was published (DDS source time, ns) between the two readings, but the later
/// // reading is received first
/// assert!(pairing.add_odom(100, odom(1.0, 0.0)).is_empty());
/// assert!(pairing.add_odom(300, odom(2.0, 1.0)).is_empty());
/// let ready = pairing.add_scan(200, scan, now);
/// assert_eq!(ready.len(), 1);
/// assert!((ready[0].odometry.unwrap().translation.x - 0.5).abs() < 1e-12);
/// ```
pub struct OdometryPairing {
    /// Odometry readings by publication time, oldest first: from the last one published
    /// before the oldest waiting scan on.
    odometry: VecDeque<(i64, OdomSample)>,
    waiting: VecDeque<Pending>,
    max_wait: Duration,
}

impl OdometryPairing {
    /// Pairing that holds a scan at most `max_wait` for the odometry after it.
    pub fn new(max_wait: Duration) -> Self {
        Self {
            odometry: VecDeque::new(),
            waiting: VecDeque::new(),
            max_wait,
        }
    }

    /// Takes a scan published at `published_ns`, received at `now`; returns the scans now
    /// paired, in order.
    pub fn add_scan(&mut self, published_ns: i64, scan: LaserScan, now: Instant) -> Vec<LaserScan> {
        self.waiting.push_back(Pending {
            published_ns,
            scan,
            arrived: now,
        });
        self.release(now)
    }

    /// Takes an odometry reading published at `published_ns`; returns the scans now paired.
    pub fn add_odom(&mut self, published_ns: i64, sample: OdomSample) -> Vec<LaserScan> {
        self.odometry.push_back((published_ns, sample));
        self.release_paired()
    }

    /// The scans that have waited `max_wait` by `now`, paired with the odometry before them,
    /// and any paired scans behind them.
    pub fn release(&mut self, now: Instant) -> Vec<LaserScan> {
        let mut out = self.release_paired();
        while let Some(front) = self.waiting.front() {
            if now.duration_since(front.arrived) < self.max_wait {
                break;
            }
            if let Some(p) = self.waiting.pop_front() {
                out.push(self.pair(p, false));
            }
            out.extend(self.release_paired());
        }
        out
    }

    /// Every waiting scan, paired with what there is (the end of a run).
    pub fn finish(&mut self) -> Vec<LaserScan> {
        let mut out = self.release_paired();
        while let Some(p) = self.waiting.pop_front() {
            out.push(self.pair(p, false));
        }
        out
    }

    /// Scans waiting.
    pub fn waiting(&self) -> usize {
        self.waiting.len()
    }

    /// The front scans that have odometry published after them.
    fn release_paired(&mut self) -> Vec<LaserScan> {
        let mut out = Vec::new();
        while let Some(front) = self.waiting.front() {
            let t = front.published_ns;
            if !self.odometry.iter().any(|(p, _)| *p > t) {
                break;
            }
            if let Some(p) = self.waiting.pop_front() {
                out.push(self.pair(p, true));
            }
        }
        out
    }

    /// Pairs a scan with the readings around it (`with_after`: the first one published after
    /// it too), and forgets the readings no later scan can use.
    fn pair(&mut self, pending: Pending, with_after: bool) -> LaserScan {
        let t = pending.published_ns;
        let before_index = self.odometry.iter().rposition(|(p, _)| *p <= t);
        let before = before_index
            .and_then(|i| self.odometry.get(i))
            .map(|(_, s)| *s);
        let after = with_after
            .then(|| self.odometry.iter().find(|(p, _)| *p > t).map(|(_, s)| *s))
            .flatten();
        let mut scan = pending.scan;
        if scan.odometry.is_none() {
            scan.odometry = odometry_at(scan.timestamp, before, after);
        }
        // Later scans are published later: their "before" is this one's or a newer reading.
        if let Some(i) = before_index {
            self.odometry.drain(..i);
        }
        scan
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_core::Pose2;

    fn scan(t: f64) -> LaserScan {
        LaserScan {
            timestamp: t,
            angle_min_rad: 0.0,
            angle_increment_rad: 0.1,
            ranges_m: vec![1.0; 3],
            max_range_m: 10.0,
            odometry: None,
            base_from_laser: Pose2::identity(),
        }
    }

    fn odom(t: f64, x: f64) -> OdomSample {
        OdomSample {
            timestamp: t,
            pose: Pose2::new([x, 0.0].into(), 0.0),
        }
    }

    fn x(s: &LaserScan) -> f64 {
        s.odometry.unwrap().translation.x
    }

    /// The log's order O(1) S(1.5) O(2) S(1.9) S(2.5) O(3): the scan stamped 1.9 comes after
    /// the reading stamped 2 (stamps stepping back, as 631 Intel scans do), so it takes the
    /// bracket (2, 3) and the nearer reading, as in the file: not the time bracket (1, 2).
    #[test]
    fn publication_order_decides_whatever_the_arrival_order() {
        let events: Vec<(i64, bool, f64, f64)> = vec![
            (10, false, 1.0, 0.0),
            (20, true, 1.5, 0.0),
            (30, false, 2.0, 1.0),
            (40, true, 1.9, 0.0),
            (50, true, 2.5, 0.0),
            (60, false, 3.0, 3.0),
        ];
        let expected = [0.5, 1.0, 2.0];
        let now = Instant::now();
        // every scan first, then every reading: arrival order as far from publication as it gets
        for order in [
            vec![0, 1, 2, 3, 4, 5],
            vec![1, 3, 4, 0, 2, 5],
            vec![0, 2, 5, 1, 3, 4],
        ] {
            let mut pairing = OdometryPairing::new(Duration::from_secs(10));
            let mut out = Vec::new();
            for i in order {
                let (p, is_scan, t, px) = events[i];
                out.extend(if is_scan {
                    pairing.add_scan(p, scan(t), now)
                } else {
                    pairing.add_odom(p, odom(t, px))
                });
            }
            let got: Vec<f64> = out.iter().map(x).collect();
            assert_eq!(got.len(), 3);
            for (g, e) in got.iter().zip(expected) {
                assert!((g - e).abs() < 1e-12, "{got:?}");
            }
        }
    }

    #[test]
    fn a_scan_without_later_odometry_waits_then_takes_the_last_reading() {
        let now = Instant::now();
        let mut pairing = OdometryPairing::new(Duration::from_millis(100));
        assert!(pairing.add_odom(1, odom(1.0, 4.0)).is_empty());
        assert!(pairing.add_scan(2, scan(1.2), now).is_empty());
        assert_eq!(pairing.waiting(), 1);
        assert!(pairing.release(now + Duration::from_millis(50)).is_empty());
        let out = pairing.release(now + Duration::from_millis(100));
        assert_eq!(out.len(), 1);
        assert_eq!(x(&out[0]), 4.0);
        // no odometry at all: the scan goes without
        let mut bare = OdometryPairing::new(Duration::ZERO);
        let out = bare.add_scan(1, scan(0.0), now);
        assert_eq!(out.len(), 1);
        assert!(out[0].odometry.is_none());
        assert!(bare.finish().is_empty());
    }

    #[test]
    fn readings_no_scan_can_use_are_forgotten() {
        let now = Instant::now();
        let mut pairing = OdometryPairing::new(Duration::from_secs(1));
        for i in 0..100 {
            pairing.add_odom(2 * i, odom(i as f64, i as f64));
            let out = pairing.add_scan(2 * i + 1, scan(i as f64 + 0.5), now);
            assert!(out.is_empty());
        }
        pairing.add_odom(1000, odom(100.0, 100.0));
        assert_eq!(pairing.odometry.len(), 2);
        assert!(pairing.finish().is_empty());
    }
}
