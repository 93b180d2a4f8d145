//! Wheel odometry tied to laser scans that carry none of their own, from the odometry
//! readings around each scan in file order: interpolated by timestamp when the scan's time lies
//! between theirs, else the nearer in time. Shared by the CARMEN reader (`ODOM` lines) and the
//! ROS 1 bag reader (`nav_msgs/Odometry` messages), so a log and the bag it was converted from
//! give the same scans. The ROS 2 node ties live scans to odometry by the same rule, in
//! publication order ([`odometry_at`]).

use slamkit_core::pose::wrap_angle;
use slamkit_core::{LaserScan, Pose2};

/// One odometry reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdomSample {
    /// Time of the reading \[s\].
    pub timestamp: f64,
    /// `odom_from_base` at that time.
    pub pose: Pose2,
}

/// Ties scans without odometry of their own to the ODOM lines around them in file order.
#[derive(Default)]
pub(crate) struct OdometryBracket {
    /// The last ODOM line read.
    before: Option<OdomSample>,
    /// Scans read since then that still need odometry.
    pending: Vec<usize>,
}

impl OdometryBracket {
    pub(crate) fn add_scan(&mut self, scans: &mut Vec<LaserScan>, scan: LaserScan) {
        if scan.odometry.is_none() {
            self.pending.push(scans.len());
        }
        scans.push(scan);
    }

    pub(crate) fn add_odom(&mut self, scans: &mut [LaserScan], after: OdomSample) {
        self.resolve(scans, Some(after));
        self.before = Some(after);
    }

    pub(crate) fn finish(&mut self, scans: &mut [LaserScan]) {
        self.resolve(scans, None);
    }

    fn resolve(&mut self, scans: &mut [LaserScan], after: Option<OdomSample>) {
        for i in self.pending.drain(..) {
            if let Some(scan) = scans.get_mut(i) {
                scan.odometry = odometry_at(scan.timestamp, self.before, after);
            }
        }
    }
}

/// Odometry at time `t` from the samples just before and after it in file order (or, live, in
/// publication order): interpolated when `t` lies between their times, else the nearer in time
/// (or the only one).
///
/// ```
/// use slamkit_core::Pose2;
/// use slamkit_io::odometry_bracket::{odometry_at, OdomSample};
/// let a = OdomSample { timestamp: 1.0, pose: Pose2::new([0.0, 0.0].into(), 0.0) };
/// let b = OdomSample { timestamp: 2.0, pose: Pose2::new([1.0, 0.0].into(), 0.0) };
/// let mid = odometry_at(1.25, Some(a), Some(b)).unwrap();
/// assert!((mid.translation.x - 0.25).abs() < 1e-12);
/// assert_eq!(odometry_at(5.0, Some(a), None), Some(a.pose));
/// ```
pub fn odometry_at(t: f64, before: Option<OdomSample>, after: Option<OdomSample>) -> Option<Pose2> {
    match (before, after) {
        (Some(a), Some(b)) if a.timestamp <= t && t <= b.timestamp && a.timestamp < b.timestamp => {
            // Halved so that stamps near ±f64::MAX cannot overflow to inf / inf = NaN.
            let s = (t / 2.0 - a.timestamp / 2.0) / (b.timestamp / 2.0 - a.timestamp / 2.0);
            Some(interpolate_pose2(&a.pose, &b.pose, s.clamp(0.0, 1.0)))
        }
        (Some(a), Some(b)) => {
            let nearer = if (t - a.timestamp).abs() <= (b.timestamp - t).abs() {
                a
            } else {
                b
            };
            Some(nearer.pose)
        }
        (Some(only), None) | (None, Some(only)) => Some(only.pose),
        (None, None) => None,
    }
}

/// Linear interpolation of position and of heading along the shorter arc, `s` in [0, 1];
/// written as `a·(1−s) + b·s` so that it stays finite for any finite `a`, `b`.
fn interpolate_pose2(a: &Pose2, b: &Pose2, s: f64) -> Pose2 {
    let p = a.translation.vector * (1.0 - s) + b.translation.vector * s;
    let dtheta = wrap_angle(b.rotation.angle() - a.rotation.angle());
    Pose2::new(p, a.rotation.angle() + s * dtheta)
}
