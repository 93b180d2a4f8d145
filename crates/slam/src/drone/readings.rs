//! The readings that arrive between scans, kept until the next scan uses them: the latest
//! range pair and attitude at the scan's time, and the optical flow over the interval since
//! the previous scan.

use nalgebra::Vector2;
use slamkit_core::observation::{FlowSample, ImuSample, RangePair};
use slamkit_core::LaserScan;
use slamkit_lidar::layers::LayerInput;

/// What the drone's other sensors said since the last scan.
#[derive(Debug, Default)]
pub(crate) struct Readings {
    /// The latest range pair.
    range: Option<RangePair>,
    /// The latest attitude.
    imu: Option<ImuSample>,
    /// Flow readings since the previous scan, in time order.
    flows: Vec<FlowSample>,
    /// Time of the previous scan \[s\].
    previous_scan_s: Option<f64>,
}

impl Readings {
    pub(crate) fn range(&mut self, r: RangePair) {
        self.range = Some(r);
    }

    pub(crate) fn imu(&mut self, i: ImuSample) {
        self.imu = Some(i);
    }

    pub(crate) fn flow(&mut self, f: FlowSample) {
        self.flows.push(f);
    }

    /// The layered mapper's input for `scan`: the latest range pair and attitude (roll and
    /// pitch 0 and no gyro before the first IMU sample), and the mean flow since the previous
    /// scan (none at the first scan); starts the next scan's flow interval. Also returns the
    /// range pair used.
    pub(crate) fn input<'a>(&mut self, scan: &'a LaserScan) -> (LayerInput<'a>, Option<RangePair>) {
        let flow = self.previous_scan_s.and_then(|_| mean_flow(&self.flows));
        self.flows.clear();
        self.previous_scan_s = Some(scan.timestamp);
        let range = self.range;
        let input = LayerInput {
            scan,
            up_m: range.and_then(|r| r.up_m),
            down_m: range.and_then(|r| r.down_m),
            roll_rad: self.imu.map_or(0.0, |i| i.roll_rad),
            pitch_rad: self.imu.map_or(0.0, |i| i.pitch_rad),
            gyro_yaw_rad: self.imu.and_then(|i| i.gyro_yaw_rad),
            flow_velocity_mps: flow,
        };
        (input, range)
    }
}

/// The mean optical-flow velocity over `readings`, weighted by their integration periods;
/// `None` when one of them has no velocity (or there is none): a period without a reading
/// would bias the mean towards the periods that had one.
pub fn mean_flow(readings: &[FlowSample]) -> Option<Vector2<f64>> {
    let (sum, span) = readings
        .iter()
        .try_fold((Vector2::zeros(), 0.0), |(sum, span), r| {
            r.velocity_mps
                .map(|v| (sum + v * r.integration_s, span + r.integration_s))
        })?;
    (span > 0.0).then(|| sum / span)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flow(t: f64, v: Option<f64>) -> FlowSample {
        FlowSample {
            timestamp: t,
            integration_s: t,
            velocity_mps: v.map(|x| Vector2::new(x, 0.0)),
        }
    }

    #[test]
    fn mean_flow_is_weighted_by_period_and_needs_every_reading() {
        let mean = mean_flow(&[flow(1.0, Some(1.0)), flow(3.0, Some(3.0))]);
        assert_eq!(mean, Some(Vector2::new(2.5, 0.0)));
        assert_eq!(mean_flow(&[flow(1.0, Some(1.0)), flow(1.0, None)]), None);
        assert_eq!(mean_flow(&[]), None);
    }

    #[test]
    fn a_scan_takes_the_latest_readings_and_the_flow_since_the_previous_scan() {
        let scan = |t| LaserScan {
            timestamp: t,
            angle_min_rad: 0.0,
            angle_increment_rad: 0.1,
            ranges_m: vec![1.0],
            max_range_m: 5.0,
            odometry: None,
            base_from_laser: slamkit_core::Pose2::identity(),
        };
        let mut r = Readings::default();
        r.flow(flow(0.5, Some(9.0)));
        let first = scan(1.0);
        let (input, range) = r.input(&first);
        assert_eq!(
            (input.flow_velocity_mps, input.roll_rad, range),
            (None, 0.0, None)
        );
        for (t, down) in [(1.5, 0.4), (2.0, 0.6)] {
            r.range(RangePair {
                timestamp: t,
                up_m: None,
                down_m: Some(down),
            });
        }
        r.imu(ImuSample {
            timestamp: 2.0,
            roll_rad: 0.1,
            pitch_rad: 0.2,
            gyro_yaw_rad: Some(3.0),
        });
        r.flow(flow(2.0, Some(1.0)));
        let second = scan(2.0);
        let (input, _) = r.input(&second);
        assert_eq!(input.down_m, Some(0.6));
        assert_eq!((input.roll_rad, input.gyro_yaw_rad), (0.1, Some(3.0)));
        assert_eq!(input.flow_velocity_mps, Some(Vector2::new(1.0, 0.0)));
    }
}
