//! A drone's range finders and IMU on ROS 2 as the readings [`slamkit_slam::DroneSlam`] takes
//! ([`Observation::Range`], [`Observation::Imu`]), with the conventions of the drone's CSV
//! files ([`slamkit_io::drone_csv`]):
//!
//! * Two `sensor_msgs/Range` topics, one per finder (up, down). Each message gives a
//!   [`RangePair`] at its stamp: its own reading and the other finder's latest, when that one
//!   is at most [`PAIR_MAX_AGE_S`] older (a finder that went quiet does not hold a stale height
//!   forever). A range is used when it is finite and within the message's `min_range` ..
//!   `max_range`; `+inf` (nothing in range), `-inf` (nearer than `min_range`, REP 117) and NaN
//!   are "no reading".
//! * `sensor_msgs/Imu` in the base's axes (x forward, y left, z up; a flight controller's
//!   IMU): roll and pitch from `orientation` (level when the message has none:
//!   `orientation_covariance[0] = -1`), and the heading integrated from the yaw-rate gyro,
//!   `angular_velocity.z`, each message's rate held over the time since the previous message
//!   (the first message starts the heading at 0). The tilt's effect on the yaw rate
//!   (ψ̇ = (ω_y sin φ + ω_z cos φ) / cos θ) is left out, as in the drone's CSV files: under the
//!   session's tilt limit it is below 1 %.

use slamkit_core::observation::{ImuSample, RangePair};
use slamkit_core::Observation;
use slamkit_io::bag::messages::{ImuMsg, RangeMsg};

/// Longest the other finder's latest reading is paired with a new one \[s\].
pub const PAIR_MAX_AGE_S: f64 = 0.5;

/// Which range finder a `sensor_msgs/Range` topic carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RangeSide {
    /// The up-looking finder (distance to the ceiling).
    Up,
    /// The down-looking finder (distance to the floor).
    Down,
}

/// The distance a range message reports, `None` for no reading (see the module documentation).
///
/// ```
/// use slamkit_ros2::drone_readings::range_m;
/// use slamkit_io::bag::messages::{Header, RangeMsg};
/// let header = Header { seq: None, stamp: Default::default(), frame_id: "down".into() };
/// let msg = |range| RangeMsg { header: header.clone(), radiation_type: 1,
///     field_of_view: 0.05, min_range: 0.02, max_range: 4.0, range };
/// assert_eq!(range_m(&msg(1.25)), Some(1.25));
/// assert_eq!(range_m(&msg(f32::INFINITY)), None);
/// assert_eq!(range_m(&msg(4.5)), None);
/// assert_eq!(range_m(&msg(f32::NAN)), None);
/// ```
pub fn range_m(msg: &RangeMsg) -> Option<f64> {
    let r = f64::from(msg.range);
    let (min, max) = (f64::from(msg.min_range), f64::from(msg.max_range));
    (r.is_finite() && r >= min && r <= max).then_some(r)
}

/// Turns range and IMU messages into the drone session's readings (see the module
/// documentation); keeps the finders' latest readings and the integrated heading.
#[derive(Debug, Default)]
pub struct DroneReadings {
    /// Latest (stamp, distance) of the up and down finders.
    up: Option<(f64, Option<f64>)>,
    down: Option<(f64, Option<f64>)>,
    /// Stamp and integrated heading of the last IMU message.
    gyro: Option<(f64, f64)>,
}

impl DroneReadings {
    /// The range pair a message of finder `side` gives.
    ///
    /// # Errors
    /// A stamp that is not finite.
    pub fn range(&mut self, side: RangeSide, msg: &RangeMsg) -> Result<Observation, String> {
        let t = msg.header.stamp.as_secs_f64();
        if !t.is_finite() {
            return Err(format!("range stamp {t}"));
        }
        let reading = Some((t, range_m(msg)));
        let (mine, other) = match side {
            RangeSide::Up => (&mut self.up, self.down),
            RangeSide::Down => (&mut self.down, self.up),
        };
        *mine = reading;
        let other = other
            .filter(|(stamp, _)| (t - stamp).abs() <= PAIR_MAX_AGE_S)
            .and_then(|(_, r)| r);
        let own = range_m(msg);
        let (up_m, down_m) = match side {
            RangeSide::Up => (own, other),
            RangeSide::Down => (other, own),
        };
        Ok(Observation::Range(RangePair {
            timestamp: t,
            up_m,
            down_m,
        }))
    }

    /// The attitude and integrated heading an IMU message gives.
    ///
    /// ```
    /// use slamkit_core::Observation;
    /// use slamkit_io::bag::messages::{Header, ImuMsg};
    /// use slamkit_io::bag::record::RosTime;
    /// use slamkit_ros2::drone_readings::DroneReadings;
    /// let imu = |sec, yaw_rate| ImuMsg {
    ///     header: Header { seq: None, stamp: RosTime { sec, nsec: 0 }, frame_id: "imu".into() },
    ///     orientation: [0.0, 0.0, 0.0, 1.0], orientation_covariance: [0.0; 9],
    ///     angular_velocity: [0.0, 0.0, yaw_rate], angular_velocity_covariance: [0.0; 9],
    ///     linear_acceleration: [0.0, 0.0, 9.81], linear_acceleration_covariance: [0.0; 9] };
    /// let mut readings = DroneReadings::default();
    /// readings.imu(&imu(10, 0.3)).unwrap();
    /// // 0.5 rad/s held over the 2 s since the previous message
    /// let Observation::Imu(sample) = readings.imu(&imu(12, 0.5)).unwrap() else { panic!() };
    /// assert!((sample.gyro_yaw_rad.unwrap() - 1.0).abs() < 1e-12);
    /// ```
    ///
    /// # Errors
    /// A stamp, orientation or yaw rate that is not finite, or a zero quaternion.
    pub fn imu(&mut self, msg: &ImuMsg) -> Result<Observation, String> {
        let t = msg.header.stamp.as_secs_f64();
        let rate = msg.angular_velocity[2];
        if !(t.is_finite() && rate.is_finite()) {
            return Err(format!("imu stamp {t}, yaw rate {rate}"));
        }
        let (roll_rad, pitch_rad) = if msg.orientation_covariance[0] == -1.0 {
            (0.0, 0.0)
        } else {
            let [x, y, z, w] = msg.orientation;
            let q = nalgebra::Quaternion::new(w, x, y, z);
            if !(q.coords.iter().all(|v| v.is_finite()) && q.norm() > 0.0) {
                return Err(format!("imu orientation {:?}", msg.orientation));
            }
            let (roll, pitch, _) = nalgebra::UnitQuaternion::from_quaternion(q).euler_angles();
            (roll, pitch)
        };
        let yaw = match self.gyro {
            Some((t0, yaw0)) => yaw0 + rate * (t - t0).max(0.0),
            None => 0.0,
        };
        self.gyro = Some((t, yaw));
        Ok(Observation::Imu(ImuSample {
            timestamp: t,
            roll_rad,
            pitch_rad,
            gyro_yaw_rad: Some(yaw),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_io::bag::messages::Header;
    use slamkit_io::bag::record::RosTime;

    fn header(t: f64) -> Header {
        Header {
            seq: None,
            stamp: RosTime {
                sec: t.floor() as u32,
                nsec: ((t - t.floor()) * 1e9).round() as u32,
            },
            frame_id: String::new(),
        }
    }

    fn range(t: f64, r: f32) -> RangeMsg {
        RangeMsg {
            header: header(t),
            radiation_type: 1,
            field_of_view: 0.05,
            min_range: 0.02,
            max_range: 4.0,
            range: r,
        }
    }

    fn pair(o: Observation) -> (Option<f64>, Option<f64>) {
        match o {
            Observation::Range(p) => (p.up_m, p.down_m),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn each_finder_is_paired_with_the_other_ones_recent_reading() {
        let mut r = DroneReadings::default();
        let up = RangeSide::Up;
        let down = RangeSide::Down;
        assert_eq!(
            pair(r.range(down, &range(1.0, 0.5)).unwrap()),
            (None, Some(0.5))
        );
        assert_eq!(
            pair(r.range(up, &range(1.0, 1.5)).unwrap()),
            (Some(1.5), Some(0.5))
        );
        // nothing above in range: up has no reading, down still pairs
        assert_eq!(
            pair(r.range(up, &range(1.1, f32::INFINITY)).unwrap()),
            (None, Some(0.5))
        );
        // the down finder went quiet for longer than PAIR_MAX_AGE_S
        assert_eq!(
            pair(r.range(up, &range(2.0, 1.25)).unwrap()),
            (Some(1.25), None)
        );
    }

    #[test]
    fn imu_attitude_and_heading() {
        let imu = |t: f64, q: [f64; 4], rate: f64| ImuMsg {
            header: header(t),
            orientation: q,
            orientation_covariance: [0.0; 9],
            angular_velocity: [0.0, 0.0, rate],
            angular_velocity_covariance: [0.0; 9],
            linear_acceleration: [0.0, 0.0, 9.81],
            linear_acceleration_covariance: [0.0; 9],
        };
        let tilted = nalgebra::UnitQuaternion::from_euler_angles(0.1, -0.05, 2.0);
        let q = tilted.quaternion();
        let mut r = DroneReadings::default();
        let Observation::Imu(s) = r.imu(&imu(5.0, [q.i, q.j, q.k, q.w], 1.0)).unwrap() else {
            panic!()
        };
        assert!((s.roll_rad - 0.1).abs() < 1e-12 && (s.pitch_rad + 0.05).abs() < 1e-12);
        assert_eq!(s.gyro_yaw_rad, Some(0.0));
        let mut none = imu(5.5, [0.0; 4], -0.4);
        none.orientation_covariance[0] = -1.0;
        let Observation::Imu(s) = r.imu(&none).unwrap() else {
            panic!()
        };
        assert_eq!((s.roll_rad, s.pitch_rad), (0.0, 0.0));
        assert!((s.gyro_yaw_rad.unwrap() + 0.2).abs() < 1e-12);
        assert!(r.imu(&imu(6.0, [0.0; 4], 0.0)).is_err());
        assert!(r.imu(&imu(6.0, [0.0, 0.0, 0.0, 1.0], f64::NAN)).is_err());
    }
}
