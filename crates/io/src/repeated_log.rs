//! A lidar log played several times in a row, as a robot that drives the same corridors for
//! an hour records it: each pass's timestamps shifted past the previous pass's, and its
//! odometry continued from where the previous pass's ended (no jump in the readings; the
//! scans of the next pass start where the log's first scan was, which is where a robot that
//! closed its tour stands). Used to check that a mapper's memory stays flat on ground it has
//! mapped (the three-pass Intel log of issue 24), without writing the long log anywhere: each
//! pass's scans are made on demand from the one log in memory.

use crate::relations::Relation;
use slamkit_core::{LaserScan, Pose2};

/// `scans` played pass after pass.
#[derive(Debug, Clone, Copy)]
pub struct RepeatedLog<'a> {
    scans: &'a [LaserScan],
    /// Time added per pass \[s\]: the log's span (latest minus earliest stamp, as stamps may
    /// step back) plus one second.
    period_s: f64,
    /// Odometry motion over one pass: from the first reading to the last.
    odometry_step: Pose2,
}

impl<'a> RepeatedLog<'a> {
    /// The passes of `scans` (one pass is the log as given).
    pub fn new(scans: &'a [LaserScan]) -> Self {
        let stamps = scans.iter().map(|s| s.timestamp).filter(|t| t.is_finite());
        let (lo, hi) = stamps.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| {
            (lo.min(t), hi.max(t))
        });
        let period_s = if hi >= lo { hi - lo + 1.0 } else { 1.0 };
        let first = scans.iter().find_map(|s| s.odometry);
        let last = scans.iter().rev().find_map(|s| s.odometry);
        let odometry_step = match (first, last) {
            (Some(first), Some(last)) => last * first.inverse(),
            _ => Pose2::identity(),
        };
        Self {
            scans,
            period_s,
            odometry_step,
        }
    }

    /// Time added to pass `pass` (0 for the first) \[s\].
    pub fn time_offset_s(&self, pass: usize) -> f64 {
        pass as f64 * self.period_s
    }

    /// The scans of pass `pass` (0 for the first, the log itself): stamps shifted by
    /// [`RepeatedLog::time_offset_s`], odometry readings moved so that the pass's first reading
    /// is the previous pass's last.
    pub fn pass(&self, pass: usize) -> impl Iterator<Item = LaserScan> + 'a {
        let offset = self.time_offset_s(pass);
        let moved = (0..pass).fold(Pose2::identity(), |acc, _| self.odometry_step * acc);
        self.scans.iter().map(move |scan| LaserScan {
            timestamp: scan.timestamp + offset,
            odometry: scan.odometry.map(|o| moved * o),
            ..scan.clone()
        })
    }

    /// `passes` passes in a row.
    pub fn passes(&self, passes: usize) -> impl Iterator<Item = LaserScan> + 'a {
        let log = *self;
        (0..passes).flat_map(move |pass| log.pass(pass))
    }

    /// `relations` (ground truth of the log) with their stamps moved to pass `pass`.
    pub fn relations(&self, relations: &[Relation], pass: usize) -> Vec<Relation> {
        let offset = self.time_offset_s(pass);
        relations
            .iter()
            .map(|r| Relation {
                t1: r.t1 + offset,
                t2: r.t2 + offset,
                ..*r
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    fn scan(t: f64, x: f64) -> LaserScan {
        LaserScan {
            timestamp: t,
            angle_min_rad: 0.0,
            angle_increment_rad: 0.1,
            ranges_m: vec![1.0; 3],
            max_range_m: 10.0,
            odometry: Some(Pose2::new(Vector2::new(x, 0.0), 0.5 * x)),
            base_from_laser: Pose2::identity(),
        }
    }

    #[test]
    fn passes_follow_each_other_in_time_and_odometry() {
        // stamps step back once (as Intel's do): the period covers the span
        let scans = [scan(10.0, 0.0), scan(12.0, 1.0), scan(11.5, 2.0)];
        let log = RepeatedLog::new(&scans);
        let all: Vec<LaserScan> = log.passes(3).collect();
        assert_eq!(all.len(), 9);
        let stamps: Vec<f64> = all.iter().map(|s| s.timestamp).collect();
        assert_eq!(stamps[3..6], [13.0, 15.0, 14.5]);
        assert_eq!(stamps[6..9], [16.0, 18.0, 17.5]);
        // each pass's first reading is the previous pass's last, and the motion within a pass
        // is the log's
        for pass in 1..3 {
            let (last, first) = (&all[3 * pass - 1], &all[3 * pass]);
            let jump = last.odometry.unwrap().inverse() * first.odometry.unwrap();
            assert!(jump.translation.vector.norm() < 1e-12 && jump.rotation.angle() < 1e-12);
            for i in 1..3 {
                let a = scans[i - 1].odometry.unwrap().inverse() * scans[i].odometry.unwrap();
                let b = all[3 * pass + i - 1].odometry.unwrap().inverse()
                    * all[3 * pass + i].odometry.unwrap();
                let d = a.inverse() * b;
                assert!(d.translation.vector.norm() < 1e-12 && d.rotation.angle() < 1e-12);
            }
        }
        let rel = Relation {
            t1: 10.0,
            t2: 12.0,
            t1_from_t2: slamkit_core::Pose3::identity(),
        };
        let moved = log.relations(&[rel], 2);
        assert_eq!((moved[0].t1, moved[0].t2), (16.0, 18.0));
    }
}
