//! The ROS messages slamkit reads from bags, decoded from ROS 1 serialisation. Each type
//! carries its ROS name and md5sum (the hash ROS computes over the message definition, the
//! same in every ROS 1 distribution since these types were last changed), and a connection
//! is decoded only when the type name and md5sum stored in the bag are these
//! ([`check_type`]): a message of another version or another type would otherwise decode
//! into nonsense.

use super::connection::Connection;
use super::record::RosTime;
use super::ros1::{Cursor, DecodeError};

/// A ROS message type slamkit decodes.
pub trait RosMessage: Sized {
    /// The ROS type name (`sensor_msgs/LaserScan`).
    const TYPE: &'static str;
    /// md5sum of the type's definition.
    const MD5SUM: &'static str;
    /// Reads the message's fields (not checking for left-over bytes).
    fn read(c: &mut Cursor) -> Result<Self, DecodeError>;

    /// Decodes one whole message: every byte must be used.
    fn decode(bytes: &[u8]) -> Result<Self, DecodeError> {
        let mut c = Cursor::new(bytes);
        let msg = Self::read(&mut c)?;
        c.finish()?;
        Ok(msg)
    }
}

/// Why a connection's messages cannot be read as type `M`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum TypeMismatch {
    /// The connection carries another type.
    #[error("topic {topic} carries {got}, not {want}")]
    Type {
        /// The topic.
        topic: String,
        /// Type expected.
        want: &'static str,
        /// Type recorded.
        got: String,
    },
    /// Same name, another definition (another version of the message).
    #[error("topic {topic}: {ty} has md5sum {got}, slamkit reads {want} (another version of the message)")]
    Md5 {
        /// The topic.
        topic: String,
        /// The type.
        ty: &'static str,
        /// md5sum expected.
        want: &'static str,
        /// md5sum recorded.
        got: String,
    },
}

/// Checks that `conn` records messages of type `M`, by name and md5sum.
///
/// ```
/// use slamkit_io::bag::connection::Connection;
/// use slamkit_io::bag::messages::{check_type, LaserScanMsg, OdometryMsg, RosMessage};
///
/// let conn = Connection {
///     id: 0,
///     topic: "/scan".into(),
///     message_type: "sensor_msgs/LaserScan".into(),
///     md5sum: LaserScanMsg::MD5SUM.into(),
///     message_definition: String::new(),
///     callerid: None,
///     latching: false,
/// };
/// assert!(check_type::<LaserScanMsg>(&conn).is_ok());
/// assert!(check_type::<OdometryMsg>(&conn).is_err());
/// ```
pub fn check_type<M: RosMessage>(conn: &Connection) -> Result<(), TypeMismatch> {
    if conn.message_type != M::TYPE {
        return Err(TypeMismatch::Type {
            topic: conn.topic.clone(),
            want: M::TYPE,
            got: conn.message_type.clone(),
        });
    }
    if conn.md5sum != M::MD5SUM {
        return Err(TypeMismatch::Md5 {
            topic: conn.topic.clone(),
            ty: M::TYPE,
            want: M::MD5SUM,
            got: conn.md5sum.clone(),
        });
    }
    Ok(())
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// Sequence number.
    pub seq: u32,
    /// Time of the data (the sensor's time).
    pub stamp: RosTime,
    /// Frame the data is in.
    pub frame_id: String,
}

impl Header {
    fn read(c: &mut Cursor) -> Result<Self, DecodeError> {
        Ok(Self {
            seq: c.u32()?,
            stamp: c.time()?,
            frame_id: c.string()?,
        })
    }
}

/// `sensor_msgs/LaserScan`: one sweep of a planar lidar.
#[derive(Debug, Clone, PartialEq)]
pub struct LaserScanMsg {
    /// Time of the first beam, and the laser's frame.
    pub header: Header,
    /// Bearing of the first beam \[rad\].
    pub angle_min: f32,
    /// Bearing of the last beam \[rad\].
    pub angle_max: f32,
    /// Angle between beams \[rad\].
    pub angle_increment: f32,
    /// Time between beams \[s\].
    pub time_increment: f32,
    /// Time between scans \[s\].
    pub scan_time: f32,
    /// Readings below this are invalid \[m\].
    pub range_min: f32,
    /// Readings above this are invalid \[m\].
    pub range_max: f32,
    /// Ranges \[m\].
    pub ranges: Vec<f32>,
    /// Intensities (device units), possibly empty.
    pub intensities: Vec<f32>,
}

impl RosMessage for LaserScanMsg {
    const TYPE: &'static str = "sensor_msgs/LaserScan";
    const MD5SUM: &'static str = "90c7ef2dc6895d81024acba2ac42f369";
    fn read(c: &mut Cursor) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(c)?,
            angle_min: c.f32()?,
            angle_max: c.f32()?,
            angle_increment: c.f32()?,
            time_increment: c.f32()?,
            scan_time: c.f32()?,
            range_min: c.f32()?,
            range_max: c.f32()?,
            ranges: c.f32_array()?,
            intensities: c.f32_array()?,
        })
    }
}

/// `geometry_msgs/Pose` (and the translation + rotation of `geometry_msgs/Transform`, which
/// has the same layout).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseMsg {
    /// Position \[m\].
    pub position: [f64; 3],
    /// Orientation quaternion `x, y, z, w`.
    pub orientation: [f64; 4],
}

impl PoseMsg {
    fn read(c: &mut Cursor) -> Result<Self, DecodeError> {
        Ok(Self {
            position: c.f64_fixed()?,
            orientation: c.f64_fixed()?,
        })
    }

    /// The pose as an isometry, its quaternion normalised; `None` for a zero or non-finite
    /// quaternion or position.
    pub fn to_isometry(&self) -> Option<slamkit_core::Pose3> {
        let [x, y, z, w] = self.orientation;
        let q = nalgebra::Quaternion::new(w, x, y, z);
        let norm = q.norm();
        if !(norm.is_finite() && norm > 1e-9 && self.position.iter().all(|v| v.is_finite())) {
            return None;
        }
        Some(slamkit_core::Pose3::from_parts(
            nalgebra::Translation3::from(self.position),
            nalgebra::UnitQuaternion::from_quaternion(q),
        ))
    }
}

/// `nav_msgs/Odometry`: the robot's pose and velocity from its wheels (or another
/// odometry source).
#[derive(Debug, Clone, PartialEq)]
pub struct OdometryMsg {
    /// Time and the odometry frame (`odom`).
    pub header: Header,
    /// The robot's frame (`base_link`).
    pub child_frame_id: String,
    /// `odom_from_base`.
    pub pose: PoseMsg,
    /// Covariance of the pose (row-major 6×6: x y z roll pitch yaw).
    pub pose_covariance: [f64; 36],
    /// Linear velocity in the child frame \[m/s\].
    pub linear: [f64; 3],
    /// Angular velocity in the child frame \[rad/s\].
    pub angular: [f64; 3],
    /// Covariance of the velocity.
    pub twist_covariance: [f64; 36],
}

impl RosMessage for OdometryMsg {
    const TYPE: &'static str = "nav_msgs/Odometry";
    const MD5SUM: &'static str = "cd5e73d190d741a2f92e81eda573aca7";
    fn read(c: &mut Cursor) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(c)?,
            child_frame_id: c.string()?,
            pose: PoseMsg::read(c)?,
            pose_covariance: c.f64_fixed()?,
            linear: c.f64_fixed()?,
            angular: c.f64_fixed()?,
            twist_covariance: c.f64_fixed()?,
        })
    }
}

/// `geometry_msgs/TransformStamped`: `parent_from_child` at a time.
#[derive(Debug, Clone, PartialEq)]
pub struct TransformStampedMsg {
    /// Time, and the parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// `parent_from_child`.
    pub transform: PoseMsg,
}

/// `tf2_msgs/TFMessage`: the transforms published on `/tf` and `/tf_static`.
#[derive(Debug, Clone, PartialEq)]
pub struct TfMessageMsg {
    /// The transforms.
    pub transforms: Vec<TransformStampedMsg>,
}

impl RosMessage for TfMessageMsg {
    const TYPE: &'static str = "tf2_msgs/TFMessage";
    const MD5SUM: &'static str = "94810edda583a504dfda3829e70d7eec";
    fn read(c: &mut Cursor) -> Result<Self, DecodeError> {
        // Each transform takes at least 4 + 8 + 4 + 4 + 56 bytes.
        let n = c.count(76)?;
        let transforms = (0..n)
            .map(|_| {
                Ok(TransformStampedMsg {
                    header: Header::read(c)?,
                    child_frame_id: c.string()?,
                    transform: PoseMsg::read(c)?,
                })
            })
            .collect::<Result<_, DecodeError>>()?;
        Ok(Self { transforms })
    }
}

/// Writers of the same serialisation, for tests that build messages.
#[cfg(test)]
pub(crate) mod encode {
    use super::*;

    pub(crate) fn header(out: &mut Vec<u8>, h: &Header) {
        out.extend_from_slice(&h.seq.to_le_bytes());
        out.extend_from_slice(&h.stamp.sec.to_le_bytes());
        out.extend_from_slice(&h.stamp.nsec.to_le_bytes());
        string(out, &h.frame_id);
    }

    pub(crate) fn string(out: &mut Vec<u8>, s: &str) {
        out.extend_from_slice(&(s.len() as u32).to_le_bytes());
        out.extend_from_slice(s.as_bytes());
    }

    pub(crate) fn f64s(out: &mut Vec<u8>, v: &[f64]) {
        for x in v {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::encode::*;
    use super::*;

    fn stamp(sec: u32) -> Header {
        Header {
            seq: 1,
            stamp: RosTime { sec, nsec: 5 },
            frame_id: "laser".into(),
        }
    }

    #[test]
    fn laser_scan_decodes_and_trailing_bytes_are_refused() {
        let mut b = Vec::new();
        header(&mut b, &stamp(9));
        for v in [-1.5f32, 1.5, 1.5, 0.0, 0.1, 0.05, 30.0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        for arr in [&[1.0f32, 2.0, 3.0][..], &[]] {
            b.extend_from_slice(&(arr.len() as u32).to_le_bytes());
            arr.iter()
                .for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
        }
        let m = LaserScanMsg::decode(&b).unwrap();
        assert_eq!(m.header.stamp.sec, 9);
        assert_eq!(m.header.frame_id, "laser");
        assert_eq!((m.range_min, m.range_max), (0.05, 30.0));
        assert_eq!(m.ranges, vec![1.0, 2.0, 3.0]);
        b.push(0);
        assert!(LaserScanMsg::decode(&b).is_err());
        assert!(LaserScanMsg::decode(&b[..20]).is_err());
    }

    #[test]
    fn odometry_and_tf_decode() {
        let mut b = Vec::new();
        header(&mut b, &stamp(3));
        string(&mut b, "base_link");
        f64s(&mut b, &[1.0, 2.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        f64s(&mut b, &[0.0; 36]);
        f64s(&mut b, &[0.5, 0.0, 0.0, 0.0, 0.0, 0.1]);
        f64s(&mut b, &[0.0; 36]);
        let m = OdometryMsg::decode(&b).unwrap();
        assert_eq!(m.child_frame_id, "base_link");
        assert_eq!(m.pose.position, [1.0, 2.0, 0.0]);
        assert_eq!((m.linear[0], m.angular[2]), (0.5, 0.1));
        let mut t = 1u32.to_le_bytes().to_vec();
        header(&mut t, &stamp(0));
        string(&mut t, "laser");
        f64s(&mut t, &[0.1, 0.0, 0.2, 0.0, 0.0, 0.0, 2.0]);
        let tf = TfMessageMsg::decode(&t).unwrap();
        let iso = tf.transforms[0].transform.to_isometry().unwrap();
        assert!((iso.rotation.norm() - 1.0).abs() < 1e-12 && iso.translation.z == 0.2);
        let zero = PoseMsg {
            position: [0.0; 3],
            orientation: [0.0; 4],
        };
        assert!(zero.to_isometry().is_none());
    }
}
