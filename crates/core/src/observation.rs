//! The timestamped sensor readings every source produces (dataset readers, bags, ROS 2 topics,
//! the simulator) and every SLAM session consumes.
//!
//! One enum for all of them lets a source stay ignorant of the sessions and a session ignorant
//! of where its data came from: a recorded log, a live robot and a simulated flight are the same
//! stream of [`Observation`]s. Readings carry the sensor's own timestamp; a session needs them
//! in time order, which `slamkit-slam`'s collator restores when sources interleave.

use crate::image::{GrayImage, Image, RgbImage};
use crate::{LaserScan, Pose2};
use nalgebra::Vector2;

/// One timestamped sensor reading.
#[derive(Debug, Clone)]
pub enum Observation {
    /// A planar lidar scan (it may carry the wheel odometry of its time).
    Scan(LaserScan),
    /// A wheel or visual odometry reading on its own.
    Odometry(OdometryReading),
    /// The up- and down-looking range finders of a drone.
    Range(RangePair),
    /// Attitude and the gyro's integrated heading.
    Imu(ImuSample),
    /// A downward optical-flow sensor's body-frame velocity.
    Flow(FlowSample),
    /// A colour image with its registered depth image.
    Rgbd(RgbdFrame),
    /// A rectified stereo pair.
    Stereo(StereoFrame),
}

impl Observation {
    /// Time of the reading \[s\].
    pub fn timestamp(&self) -> f64 {
        match self {
            Observation::Scan(s) => s.timestamp,
            Observation::Odometry(o) => o.timestamp,
            Observation::Range(r) => r.timestamp,
            Observation::Imu(i) => i.timestamp,
            Observation::Flow(f) => f.timestamp,
            Observation::Rgbd(f) => f.timestamp,
            Observation::Stereo(f) => f.timestamp,
        }
    }

    /// A short name of the kind of reading, for counters and messages.
    pub fn kind(&self) -> &'static str {
        match self {
            Observation::Scan(_) => "scan",
            Observation::Odometry(_) => "odometry",
            Observation::Range(_) => "range",
            Observation::Imu(_) => "imu",
            Observation::Flow(_) => "flow",
            Observation::Rgbd(_) => "rgbd",
            Observation::Stereo(_) => "stereo",
        }
    }

    /// Whether this is a frame a session estimates a pose for (a scan or an image frame),
    /// rather than a reading it stores for the next frame: at equal timestamps frames go
    /// after readings ([`time_ordered`], and the collator of live sources), so a frame is
    /// matched with the readings of its own time.
    pub fn is_frame(&self) -> bool {
        matches!(
            self,
            Observation::Scan(_) | Observation::Rgbd(_) | Observation::Stereo(_)
        )
    }
}

/// `observations` (each source's already in time order, concatenated in any order) sorted by
/// time, stably: at equal timestamps a scan or image frame comes after the readings (range,
/// IMU, flow, odometry) of the same time, so a session that uses the latest reading at a scan
/// uses the one stamped with the scan's time, as it would have had the sensors been sampled
/// together; otherwise the given order is kept.
pub fn time_ordered(mut observations: Vec<Observation>) -> Vec<Observation> {
    observations.sort_by(|a, b| {
        a.timestamp()
            .total_cmp(&b.timestamp())
            .then(a.is_frame().cmp(&b.is_frame()))
    });
    observations
}

/// An odometry pose of the robot base in the odometry frame (any origin; only increments
/// between readings are used).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryReading {
    /// Time \[s\].
    pub timestamp: f64,
    /// `odom_from_base`.
    pub pose: Pose2,
}

/// Readings of a drone's up- and down-looking range finders.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangePair {
    /// Time \[s\].
    pub timestamp: f64,
    /// Distance from the up-looking sensor to the ceiling or an obstacle above \[m\]
    /// (`None`: no reading, or nothing in range).
    pub up_m: Option<f64>,
    /// Distance from the down-looking sensor to the floor or an obstacle below \[m\].
    pub down_m: Option<f64>,
}

/// Attitude as a flight controller reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// Time \[s\].
    pub timestamp: f64,
    /// Roll about the base x axis \[rad\].
    pub roll_rad: f64,
    /// Pitch about the base y axis \[rad\].
    pub pitch_rad: f64,
    /// Heading integrated from the yaw-rate gyro \[rad\] (any origin, not wrapped: only its
    /// change between readings is used); `None` without a gyro.
    pub gyro_yaw_rad: Option<f64>,
}

/// A downward optical-flow sensor's reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlowSample {
    /// End of the integration period \[s\].
    pub timestamp: f64,
    /// Length of the integration period \[s\].
    pub integration_s: f64,
    /// Mean body-frame horizontal velocity `(forward, left)` over the period \[m/s\]
    /// (`None`: no surface in range).
    pub velocity_mps: Option<Vector2<f64>>,
}

/// A colour image and its depth image, registered to the colour camera.
#[derive(Debug, Clone)]
pub struct RgbdFrame {
    /// Time of the colour image \[s\].
    pub timestamp: f64,
    /// Colour image.
    pub color: RgbImage,
    /// Depth \[m\]; 0.0 where the sensor gave no depth.
    pub depth_m: Image<f32>,
}

/// A rectified stereo pair.
#[derive(Debug, Clone)]
pub struct StereoFrame {
    /// Time of the left image \[s\].
    pub timestamp: f64,
    /// Left image (the tracked one).
    pub left: GrayImage,
    /// Right image.
    pub right: GrayImage,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_reports_its_own_timestamp() {
        let obs = [
            Observation::Odometry(OdometryReading {
                timestamp: 1.0,
                pose: Pose2::identity(),
            }),
            Observation::Range(RangePair {
                timestamp: 2.0,
                up_m: None,
                down_m: Some(0.5),
            }),
            Observation::Imu(ImuSample {
                timestamp: 3.0,
                roll_rad: 0.0,
                pitch_rad: 0.0,
                gyro_yaw_rad: None,
            }),
            Observation::Flow(FlowSample {
                timestamp: 4.0,
                integration_s: 0.1,
                velocity_mps: None,
            }),
        ];
        let times: Vec<f64> = obs.iter().map(Observation::timestamp).collect();
        assert_eq!(times, [1.0, 2.0, 3.0, 4.0]);
        assert_eq!(obs[2].kind(), "imu");
    }

    #[test]
    fn time_ordered_puts_readings_before_the_scan_of_their_time() {
        let scan = |t| {
            Observation::Scan(LaserScan {
                timestamp: t,
                angle_min_rad: 0.0,
                angle_increment_rad: 0.1,
                ranges_m: vec![1.0],
                max_range_m: 5.0,
                odometry: None,
                base_from_laser: Pose2::identity(),
            })
        };
        let range = |t| {
            Observation::Range(RangePair {
                timestamp: t,
                up_m: None,
                down_m: Some(t),
            })
        };
        let ordered = time_ordered(vec![scan(0.0), scan(1.0), range(1.0), range(0.5)]);
        let kinds: Vec<(f64, &str)> = ordered.iter().map(|o| (o.timestamp(), o.kind())).collect();
        assert_eq!(
            kinds,
            [(0.0, "scan"), (0.5, "range"), (1.0, "range"), (1.0, "scan")]
        );
    }
}
