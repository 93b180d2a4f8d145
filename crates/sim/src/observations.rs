//! The simulator as a source of [`Observation`]s: its readings in the types every session
//! takes, so a simulated flight feeds a session exactly as a recording or a live robot does.

use crate::{AttitudeReading, FlowReading, LidarRun, RangeReading};
use slamkit_core::observation::{time_ordered, FlowSample, ImuSample, RangePair};
use slamkit_core::Observation;

impl From<&RangeReading> for RangePair {
    fn from(r: &RangeReading) -> Self {
        Self {
            timestamp: r.timestamp,
            up_m: r.up_m,
            down_m: r.down_m,
        }
    }
}

impl From<&AttitudeReading> for ImuSample {
    fn from(a: &AttitudeReading) -> Self {
        Self {
            timestamp: a.timestamp,
            roll_rad: a.roll_rad,
            pitch_rad: a.pitch_rad,
            gyro_yaw_rad: Some(a.gyro_yaw_rad),
        }
    }
}

impl From<&FlowReading> for FlowSample {
    fn from(f: &FlowReading) -> Self {
        Self {
            timestamp: f.timestamp,
            integration_s: f.integration_s,
            velocity_mps: f.velocity_mps,
        }
    }
}

impl LidarRun {
    /// Every scan, range reading, attitude and flow reading of the run as observations, in
    /// time order (readings before the scan of their time: the attitudes are taken at the scan
    /// times).
    pub fn observations(&self) -> Vec<Observation> {
        let ranges = self.ranges.iter().map(|r| Observation::Range(r.into()));
        let imu = self.attitudes.iter().map(|a| Observation::Imu(a.into()));
        let flows = self.flows.iter().map(|f| Observation::Flow(f.into()));
        let scans = self.scans.iter().cloned().map(Observation::Scan);
        time_ordered(ranges.chain(imu).chain(flows).chain(scans).collect())
    }
}
