//! A 2D lidar log from a bag: `sensor_msgs/LaserScan` messages become [`LaserScan`]s with the
//! wheel odometry of their time attached, exactly as the CARMEN reader attaches it (the
//! `nav_msgs/Odometry` readings just before and after each scan in storage order,
//! interpolated by timestamp), and with the laser's mounting on the robot from `/tf_static`.
//! The result is the [`CarmenLog`] a CARMEN log gives, so the sessions see the same scans
//! whichever file they came from.
//!
//! Choices, and why:
//! * Topics are chosen by type when there is exactly one of it (`--scan-topic` /
//!   `--odom-topic` otherwise); a chosen topic of another type, or of another version of the
//!   type (md5sum), is an error, not a decode into nonsense.
//! * Messages are taken in storage order, the order they were written (see
//!   [`super::reader`]): a bag converted from a log keeps the log's physical order, and
//!   rosbag's time order would shuffle the Intel log's 631 scans whose stamps step back.
//!   Stamps stepping back are counted in [`CarmenLog::time_order`] as for a CARMEN log, and a
//!   bag mostly out of order is refused; the "line" of a bag log is the message's 1-based
//!   number in storage order (all topics counted).
//! * A scan's time is its `header.stamp` (the sensor's), not the record time.
//! * Ranges below the message's `range_min` are beams without a usable return (NaN), as ROS
//!   defines them; `max_range_m` follows the CARMEN rule ([`no_return_threshold`] of
//!   `range_max`).
//! * The mounting is `base_from_laser` between the odometry's `child_frame_id` (else
//!   `base_link`, `base_footprint`) and the scans' `frame_id` in the `/tf_static` tree,
//!   projected onto the ground plane (x, y, yaw); a laser mounted upside down (its z axis
//!   pointing down) has its beam angles mirrored. Without `/tf_static`, or without a path
//!   between the two frames, the laser sits at the base (identity), as in CARMEN logs.
//! * A message that does not decode is skipped and counted ([`CarmenLog::skipped`]).

use super::connection::Connection;
use super::messages::{check_type, is_type, LaserScanMsg, OdometryMsg, RosMessage, TfMessageMsg};
use super::reader::{IndexState, ReadStats};
use super::source::MessageSource;
use super::BagError;
use crate::carmen::{no_return_threshold, CarmenLog, SkipReason, SkippedLine};
use crate::odometry_bracket::{OdomSample, OdometryBracket};
use slamkit_core::{LaserScan, Pose2, Pose3};
use std::collections::HashMap;
use std::path::Path;

/// The topics to read; `None` chooses by type.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ScanTopics {
    /// Topic of the `sensor_msgs/LaserScan` messages.
    pub scan: Option<String>,
    /// Topic of the `nav_msgs/Odometry` messages.
    pub odom: Option<String>,
}

/// Where the laser's mounting came from.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Mounting {
    /// From `/tf_static`.
    TfStatic {
        /// The robot's base frame.
        base_frame: String,
        /// The laser's frame.
        laser_frame: String,
        /// `base_from_laser` on the ground plane: x, y \[m\], yaw \[rad\].
        x_y_yaw: [f64; 3],
        /// True when the laser is upside down (its beam angles are mirrored).
        mirrored: bool,
        /// Angle between the laser's z axis and the base's (or its opposite when
        /// mirrored) \[deg\]: a tilted laser is projected, not corrected.
        tilt_deg: f64,
    },
    /// The laser taken at the base (identity), and why.
    Identity {
        /// Why no mounting was found.
        reason: String,
    },
}

/// A lidar log read from a bag.
#[derive(Debug, Clone, PartialEq)]
pub struct BagScanLog {
    /// The scans with odometry and mounting, as a CARMEN log gives them.
    pub log: CarmenLog,
    /// The scan topic read.
    pub scan_topic: String,
    /// The odometry topic read, if any.
    pub odom_topic: Option<String>,
    /// The laser's mounting.
    pub mounting: Mounting,
    /// What the bag read went through (damaged chunks, a cut-short file).
    pub read: ReadStats,
    /// The state of the bag's index (unreadable for a file cut short between records).
    pub index: IndexState,
}

/// Reads the lidar log of the bag at `path` (ROS 1 or ROS 2, see [`super::open`]).
pub fn read_scan_log(path: &Path, topics: &ScanTopics) -> Result<BagScanLog, BagError> {
    let mut bag = super::open(path)?;
    scan_log(bag.as_mut(), topics)
}

/// Reads the lidar log of an open bag (see the module documentation).
pub fn scan_log<S: MessageSource + ?Sized>(
    bag: &mut S,
    topics: &ScanTopics,
) -> Result<BagScanLog, BagError> {
    // Without an index, a first walk finds the connections.
    bag.find_connections()?;
    let file = bag.bag_name().to_string();
    let scan_topic = choose_topic::<LaserScanMsg, _>(bag, topics.scan.as_deref(), "--scan-topic")?
        .ok_or_else(|| BagError::Topics {
            file: file.clone(),
            message: format!(
                "no {} topic (topics: {}{})",
                LaserScanMsg::TYPE,
                topic_list(bag),
                match bag.index() {
                    IndexState::Unreadable(why) => format!("; the index is unreadable: {why}"),
                    _ => String::new(),
                }
            ),
        })?;
    let odom_topic = choose_topic::<OdometryMsg, _>(bag, topics.odom.as_deref(), "--odom-topic")?;
    let mut state = Collect::default();
    let read = bag.read_stored(&mut |conn, msg| {
        state.message_no += 1;
        let result = if conn.topic == scan_topic {
            state.scan(conn, msg.data)
        } else if Some(&conn.topic) == odom_topic.as_ref() {
            state.odom(conn, msg.data)
        } else if conn.topic == "/tf_static" && check_type::<TfMessageMsg>(conn).is_ok() {
            state.tf_static(conn, msg.data)
        } else {
            state.log.other_message_lines += 1;
            Ok(())
        };
        if let Err(reason) = result {
            state.log.skipped.push(SkippedLine {
                line: state.message_no,
                reason: SkipReason::Undecodable {
                    topic: conn.topic.clone(),
                    what: reason,
                },
            });
        }
    })?;
    let Collect {
        mut log,
        mut bracket,
        statics,
        base_frame,
        laser_frame,
        ..
    } = state;
    bracket.finish(&mut log.scans);
    if log.scans.is_empty() {
        return Err(BagError::NoScans {
            file,
            topic: scan_topic,
            messages: read.messages,
            skipped: log.skipped.len(),
        });
    }
    log.time_order.check().map_err(|reason| BagError::Topics {
        file: file.clone(),
        message: reason,
    })?;
    let mounting = mounting(&statics, base_frame.as_deref(), laser_frame.as_deref());
    apply_mounting(&mut log.scans, &mounting);
    Ok(BagScanLog {
        log,
        scan_topic,
        odom_topic,
        mounting,
        read,
        index: bag.index().clone(),
    })
}

/// The topic of type `M`: the one asked for (checked), else the only one of that type.
pub(crate) fn choose_topic<M: RosMessage, S: MessageSource + ?Sized>(
    bag: &S,
    asked: Option<&str>,
    flag: &str,
) -> Result<Option<String>, BagError> {
    let file = bag.bag_name().to_string();
    let err = |message: String| BagError::Topics {
        file: file.clone(),
        message,
    };
    if let Some(topic) = asked {
        let conns: Vec<_> = bag.topics().values().filter(|c| c.topic == topic).collect();
        if conns.is_empty() {
            return Err(err(format!(
                "no topic {topic} (topics: {})",
                topic_list(bag)
            )));
        }
        for conn in conns {
            check_type::<M>(conn).map_err(|e| err(e.to_string()))?;
        }
        return Ok(Some(topic.to_string()));
    }
    let mut found: Vec<&str> = bag
        .topics()
        .values()
        .filter(|c| is_type::<M>(c))
        .map(|c| c.topic.as_str())
        .collect();
    found.sort_unstable();
    found.dedup();
    match found.as_slice() {
        [] => Ok(None),
        [one] => {
            for conn in bag.topics().values().filter(|c| c.topic == *one) {
                check_type::<M>(conn).map_err(|e| err(e.to_string()))?;
            }
            Ok(Some((*one).to_string()))
        }
        many => Err(err(format!(
            "several {} topics ({}): choose one with {flag}",
            M::TYPE,
            many.join(", ")
        ))),
    }
}

/// The bag's topics and their types, for errors.
pub(crate) fn topic_list<S: MessageSource + ?Sized>(bag: &S) -> String {
    let mut topics: Vec<String> = bag
        .topics()
        .values()
        .map(|c| format!("{} [{}]", c.topic, c.message_type))
        .collect();
    topics.sort();
    topics.dedup();
    if topics.is_empty() {
        "none".into()
    } else {
        topics.join(", ")
    }
}

/// What the read collects.
#[derive(Default)]
struct Collect {
    log: CarmenLog,
    bracket: OdometryBracket,
    message_no: usize,
    statics: StaticTree,
    base_frame: Option<String>,
    laser_frame: Option<String>,
}

impl Collect {
    fn scan(&mut self, conn: &Connection, bytes: &[u8]) -> Result<(), String> {
        let msg = LaserScanMsg::decode_from(conn, bytes).map_err(|e| e.to_string())?;
        let scan = to_laser_scan(&msg)?;
        self.laser_frame.get_or_insert(msg.header.frame_id);
        self.log.time_order.add(scan.timestamp, self.message_no);
        self.bracket.add_scan(&mut self.log.scans, scan);
        Ok(())
    }

    fn odom(&mut self, conn: &Connection, bytes: &[u8]) -> Result<(), String> {
        let msg = OdometryMsg::decode_from(conn, bytes).map_err(|e| e.to_string())?;
        let sample = odom_sample(&msg)?;
        self.base_frame.get_or_insert(msg.child_frame_id);
        self.log.odometry_lines += 1;
        self.bracket.add_odom(&mut self.log.scans, sample);
        Ok(())
    }

    fn tf_static(&mut self, conn: &Connection, bytes: &[u8]) -> Result<(), String> {
        let msg = TfMessageMsg::decode_from(conn, bytes).map_err(|e| e.to_string())?;
        add_static_transforms(&mut self.statics, msg)
    }
}

/// The static transform tree: child frame → (parent frame, `parent_from_child`).
pub type StaticTree = HashMap<String, (String, Pose3)>;

/// Adds the transforms of a `/tf_static` message to `statics`.
///
/// # Errors
/// A transform that is not finite or whose quaternion is zero (the ones before it are kept).
pub fn add_static_transforms(statics: &mut StaticTree, msg: TfMessageMsg) -> Result<(), String> {
    for t in msg.transforms {
        let pose = t
            .transform
            .to_isometry()
            .ok_or("static transform is not finite or its quaternion is zero")?;
        statics.insert(t.child_frame_id, (t.header.frame_id, pose));
    }
    Ok(())
}

/// An odometry message as the planar reading slamkit uses: its time (`header.stamp`) and
/// `odom_from_base` projected onto the ground plane (x, y, yaw).
///
/// # Errors
/// A pose that is not finite or whose quaternion is zero.
pub fn odom_sample(msg: &OdometryMsg) -> Result<OdomSample, String> {
    let pose = msg
        .pose
        .to_isometry()
        .ok_or("odometry pose is not finite or its quaternion is zero")?;
    let yaw = pose.rotation.euler_angles().2;
    Ok(OdomSample {
        timestamp: msg.header.stamp.as_secs_f64(),
        pose: Pose2::new(pose.translation.vector.xy(), yaw),
    })
}

/// A scan message as a [`LaserScan`] (odometry and mounting come later): ranges below
/// `range_min` become NaN (no usable return), the maximum range follows the CARMEN rule.
///
/// # Errors
/// A scan without beams, or with a beam layout that is not finite or has a zero increment.
pub fn to_laser_scan(msg: &LaserScanMsg) -> Result<LaserScan, String> {
    let (min, inc) = (f64::from(msg.angle_min), f64::from(msg.angle_increment));
    if msg.ranges.is_empty() {
        return Err("scan has no beams".into());
    }
    if !(min.is_finite() && inc.is_finite() && inc != 0.0) {
        return Err(format!(
            "bad beam layout: angle_min {min}, angle_increment {inc}"
        ));
    }
    let range_min = f64::from(msg.range_min);
    let ranges_m = msg
        .ranges
        .iter()
        .map(|&r| {
            let r = f64::from(r);
            if r < range_min {
                f64::NAN
            } else {
                r
            }
        })
        .collect();
    Ok(LaserScan {
        timestamp: msg.header.stamp.as_secs_f64(),
        angle_min_rad: min,
        angle_increment_rad: inc,
        ranges_m,
        max_range_m: no_return_threshold(Some(f64::from(msg.range_max))),
        odometry: None,
        base_from_laser: Pose2::identity(),
    })
}

/// The frames met walking up the static tree from `frame` (itself first), each with
/// `ancestor_from_frame`.
fn ancestors(statics: &StaticTree, frame: &str) -> Vec<(String, Pose3)> {
    let mut out = vec![(frame.to_string(), Pose3::identity())];
    // A tree deeper than this is a loop in the data.
    for _ in 0..64 {
        let Some((name, from_frame)) = out.last().cloned() else {
            break;
        };
        let Some((parent, parent_from_child)) = statics.get(&name) else {
            break;
        };
        if out.iter().any(|(n, _)| n == parent) {
            break;
        }
        out.push((parent.clone(), parent_from_child * from_frame));
    }
    out
}

/// `target_from_source` through the static tree, when the two frames are connected.
pub fn lookup(statics: &StaticTree, target: &str, source: &str) -> Option<Pose3> {
    let from_source = ancestors(statics, source);
    ancestors(statics, target)
        .into_iter()
        .find_map(|(name, anc_from_target)| {
            let (_, anc_from_source) = from_source.iter().find(|(n, _)| *n == name)?;
            Some(anc_from_target.inverse() * anc_from_source)
        })
}

/// The laser's mounting from the static transforms (see the module documentation): the
/// path from `base_frame` (else `base_link`, `base_footprint`) to `laser_frame`.
pub fn mounting(
    statics: &StaticTree,
    base_frame: Option<&str>,
    laser_frame: Option<&str>,
) -> Mounting {
    let identity = |reason: String| Mounting::Identity { reason };
    if statics.is_empty() {
        return identity("no /tf_static transforms".into());
    }
    let Some(laser) = laser_frame.filter(|f| !f.is_empty()) else {
        return identity("the scans name no frame_id".into());
    };
    let bases: Vec<&str> = match base_frame.filter(|f| !f.is_empty()) {
        Some(b) => vec![b],
        None => vec!["base_link", "base_footprint"],
    };
    for base in &bases {
        if let Some(base_from_laser) = lookup(statics, base, laser) {
            let r = base_from_laser.rotation;
            let z = r * nalgebra::Vector3::z();
            let x = r * nalgebra::Vector3::x();
            let mirrored = z.z < 0.0;
            let tilt_deg = z.z.abs().clamp(0.0, 1.0).acos().to_degrees();
            let t = base_from_laser.translation.vector;
            return Mounting::TfStatic {
                base_frame: (*base).to_string(),
                laser_frame: laser.to_string(),
                x_y_yaw: [t.x, t.y, x.y.atan2(x.x)],
                mirrored,
                tilt_deg,
            };
        }
    }
    identity(format!(
        "/tf_static has no path from {} to {laser}",
        bases.join(" or ")
    ))
}

/// Sets each scan's `base_from_laser` from `mounting`, mirroring the beam angles of a laser
/// mounted upside down.
pub fn apply_mounting(scans: &mut [LaserScan], mounting: &Mounting) {
    let Mounting::TfStatic {
        x_y_yaw: [x, y, yaw],
        mirrored,
        ..
    } = *mounting
    else {
        return;
    };
    let base_from_laser = Pose2::new(nalgebra::Vector2::new(x, y), yaw);
    for scan in scans {
        scan.base_from_laser = base_from_laser;
        if mirrored {
            scan.angle_min_rad = -scan.angle_min_rad;
            scan.angle_increment_rad = -scan.angle_increment_rad;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn edge(parent: &str, pose: Pose3) -> (String, Pose3) {
        (parent.to_string(), pose)
    }

    #[test]
    fn mounting_through_the_static_tree_and_upside_down() {
        let mut statics = HashMap::new();
        let lift = Pose3::from_parts(Translation3::new(0.0, 0.0, 0.1), UnitQuaternion::identity());
        statics.insert("base_link".to_string(), edge("base_footprint", lift));
        let laser = Pose3::from_parts(
            Translation3::new(0.2, -0.05, 0.3),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5),
        );
        statics.insert("laser".to_string(), edge("base_link", laser));
        let Mounting::TfStatic {
            x_y_yaw,
            mirrored,
            tilt_deg,
            ..
        } = mounting(&statics, Some("base_footprint"), Some("laser"))
        else {
            panic!("no mounting");
        };
        assert!((x_y_yaw[0] - 0.2).abs() < 1e-12 && (x_y_yaw[1] + 0.05).abs() < 1e-12);
        assert!((x_y_yaw[2] - 0.5).abs() < 1e-12 && !mirrored && tilt_deg < 1e-6);
        // the other way round: base below laser in the tree
        let inverse = lookup(&statics, "laser", "base_footprint").unwrap();
        assert!((inverse * laser * lift).translation.vector.norm() < 1e-12);
        // upside down: beam angles mirrored
        let flipped = Pose3::from_parts(
            Translation3::new(0.0, 0.0, 0.2),
            UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0),
        );
        statics.insert("laser".to_string(), edge("base_link", flipped));
        let m = mounting(&statics, None, Some("laser"));
        let mut scans = vec![LaserScan {
            timestamp: 0.0,
            angle_min_rad: -1.0,
            angle_increment_rad: 0.1,
            ranges_m: vec![1.0; 3],
            max_range_m: 10.0,
            odometry: None,
            base_from_laser: Pose2::identity(),
        }];
        apply_mounting(&mut scans, &m);
        assert!(
            matches!(m, Mounting::TfStatic { mirrored: true, .. }),
            "{m:?}"
        );
        assert_eq!(
            (scans[0].angle_min_rad, scans[0].angle_increment_rad),
            (1.0, -0.1)
        );
        // no path
        let m = mounting(&statics, Some("odom_base"), Some("laser"));
        assert!(matches!(m, Mounting::Identity { .. }), "{m:?}");
        // a loop in the tree ends the walk
        statics.insert("base_link".to_string(), edge("laser", lift));
        assert!(ancestors(&statics, "laser").len() <= 2);
    }
}
