//! The ROS messages slamkit reads from bags: one model for both wire formats. Each type is
//! written once as a sequence of [`Wire`] reads, so it decodes from ROS 1 serialisation
//! ([`RosMessage::decode`]) and from ROS 2's CDR ([`RosMessage::decode_cdr`]) alike. Each type
//! carries its ROS name and ROS 1 md5sum (the hash ROS 1 computes over the message definition,
//! the same in every ROS 1 distribution since these types were last changed), and a topic is
//! decoded only when what the bag stores about it matches ([`check_type`]): the name and
//! md5sum of a ROS 1 connection, the name and stored definition of a ROS 2 topic
//! ([`super::definition`]). A message of another version or another type would otherwise
//! decode into nonsense.

use super::cdr::CdrCursor;
use super::connection::Connection;
use super::definition::{check_definition, ros2_type_name};
use super::record::RosTime;
use super::ros1::Cursor;
use super::wire::{DecodeError, Serialization, Wire};

/// A ROS message type slamkit decodes.
pub trait RosMessage: Sized {
    /// The ROS type name (`sensor_msgs/LaserScan`).
    const TYPE: &'static str;
    /// md5sum of the type's ROS 1 definition.
    const MD5SUM: &'static str;
    /// Reads the message's fields (not checking for left-over bytes).
    fn read<W: Wire>(w: &mut W) -> Result<Self, DecodeError>;

    /// Decodes one whole ROS 1 serialised message: every byte must be used.
    fn decode(bytes: &[u8]) -> Result<Self, DecodeError> {
        let mut c = Cursor::new(bytes);
        let msg = Self::read(&mut c)?;
        c.finish()?;
        Ok(msg)
    }

    /// Decodes one whole CDR serialised message (ROS 2), encapsulation header first.
    fn decode_cdr(bytes: &[u8]) -> Result<Self, DecodeError> {
        let mut c = CdrCursor::new(bytes)?;
        let msg = Self::read(&mut c)?;
        c.finish()?;
        Ok(msg)
    }

    /// Decodes a message of `conn` in the connection's serialisation.
    fn decode_from(conn: &Connection, bytes: &[u8]) -> Result<Self, DecodeError> {
        match &conn.serialization {
            Serialization::Ros1 => Self::decode(bytes),
            Serialization::Cdr => Self::decode_cdr(bytes),
            Serialization::Other(name) => Err(DecodeError {
                offset: 0,
                what: format!("messages encoded as {name:?} are not read"),
            }),
        }
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
    /// Same name, another ROS 1 definition (another version of the message).
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
    /// Same name, another ROS 2 definition stored in the bag.
    #[error(
        "topic {topic}: the bag's definition of {ty} differs from the one slamkit reads: {what}"
    )]
    Definition {
        /// The topic.
        topic: String,
        /// The type.
        ty: &'static str,
        /// The first difference.
        what: String,
    },
    /// A serialisation slamkit does not decode.
    #[error("topic {topic}: messages encoded as {encoding:?} are not read (ROS 1 or CDR are)")]
    Encoding {
        /// The topic.
        topic: String,
        /// The encoding.
        encoding: String,
    },
}

/// Checks that `conn` records messages of type `M`: by name and md5sum for ROS 1, by name
/// (`sensor_msgs/msg/LaserScan` or `sensor_msgs/LaserScan`) and, when the bag stores one, by
/// definition for ROS 2.
///
/// ```
/// use slamkit_io::bag::connection::Connection;
/// use slamkit_io::bag::messages::{check_type, LaserScanMsg, OdometryMsg, RosMessage};
/// use slamkit_io::bag::wire::Serialization;
///
/// let conn = Connection {
///     id: 0,
///     topic: "/scan".into(),
///     message_type: "sensor_msgs/LaserScan".into(),
///     md5sum: LaserScanMsg::MD5SUM.into(),
///     message_definition: String::new(),
///     serialization: Serialization::Ros1,
///     callerid: None,
///     latching: false,
/// };
/// assert!(check_type::<LaserScanMsg>(&conn).is_ok());
/// assert!(check_type::<OdometryMsg>(&conn).is_err());
/// let ros2 = Connection {
///     message_type: "sensor_msgs/msg/LaserScan".into(),
///     md5sum: String::new(),
///     serialization: Serialization::Cdr,
///     ..conn
/// };
/// assert!(check_type::<LaserScanMsg>(&ros2).is_ok());
/// ```
pub fn check_type<M: RosMessage>(conn: &Connection) -> Result<(), TypeMismatch> {
    let type_err = || TypeMismatch::Type {
        topic: conn.topic.clone(),
        want: M::TYPE,
        got: conn.message_type.clone(),
    };
    match &conn.serialization {
        Serialization::Ros1 => {
            if conn.message_type != M::TYPE {
                return Err(type_err());
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
        Serialization::Cdr => {
            if ros2_type_name(&conn.message_type) != M::TYPE {
                return Err(type_err());
            }
            check_definition(M::TYPE, &conn.message_definition).map_err(|what| {
                TypeMismatch::Definition {
                    topic: conn.topic.clone(),
                    ty: M::TYPE,
                    what,
                }
            })
        }
        Serialization::Other(encoding) => Err(TypeMismatch::Encoding {
            topic: conn.topic.clone(),
            encoding: encoding.clone(),
        }),
    }
}

/// True when `conn`'s type is `M` by name (either spelling), whatever its version.
pub fn is_type<M: RosMessage>(conn: &Connection) -> bool {
    ros2_type_name(&conn.message_type) == M::TYPE
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// Sequence number (ROS 1 only: ROS 2's header has none).
    pub seq: Option<u32>,
    /// Time of the data (the sensor's time).
    pub stamp: RosTime,
    /// Frame the data is in.
    pub frame_id: String,
}

impl Header {
    fn read<W: Wire>(c: &mut W) -> Result<Self, DecodeError> {
        Ok(Self {
            seq: c.header_seq()?,
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
    fn read<W: Wire>(c: &mut W) -> Result<Self, DecodeError> {
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
    fn read<W: Wire>(c: &mut W) -> Result<Self, DecodeError> {
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
    fn read<W: Wire>(c: &mut W) -> Result<Self, DecodeError> {
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
    fn read<W: Wire>(c: &mut W) -> Result<Self, DecodeError> {
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

/// `sensor_msgs/Range`: one reading of a range finder (sonar, infrared, a ToF point sensor).
#[derive(Debug, Clone, PartialEq)]
pub struct RangeMsg {
    /// Time of the reading, and the sensor's frame.
    pub header: Header,
    /// 0 ultrasound, 1 infrared.
    pub radiation_type: u8,
    /// Width of the beam \[rad\].
    pub field_of_view: f32,
    /// Shortest range the sensor reports \[m\].
    pub min_range: f32,
    /// Longest range the sensor reports \[m\].
    pub max_range: f32,
    /// The range \[m\] (±inf: beyond the limits, as REP 117 defines).
    pub range: f32,
}

impl RosMessage for RangeMsg {
    const TYPE: &'static str = "sensor_msgs/Range";
    const MD5SUM: &'static str = "c005c34273dc426c67a020a87bc24148";
    fn read<W: Wire>(c: &mut W) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(c)?,
            radiation_type: c.u8()?,
            field_of_view: c.f32()?,
            min_range: c.f32()?,
            max_range: c.f32()?,
            range: c.f32()?,
        })
    }
}

/// `sensor_msgs/Imu`: orientation, angular velocity and linear acceleration.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuMsg {
    /// Time of the reading, and the IMU's frame.
    pub header: Header,
    /// Orientation quaternion `x, y, z, w`.
    pub orientation: [f64; 4],
    /// Its covariance (row-major 3×3; element 0 = -1: no orientation).
    pub orientation_covariance: [f64; 9],
    /// Angular velocity \[rad/s\].
    pub angular_velocity: [f64; 3],
    /// Its covariance.
    pub angular_velocity_covariance: [f64; 9],
    /// Linear acceleration \[m/s²\].
    pub linear_acceleration: [f64; 3],
    /// Its covariance.
    pub linear_acceleration_covariance: [f64; 9],
}

impl RosMessage for ImuMsg {
    const TYPE: &'static str = "sensor_msgs/Imu";
    const MD5SUM: &'static str = "6a62c6daae103f4ff57a132d6f95cec2";
    fn read<W: Wire>(c: &mut W) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(c)?,
            orientation: c.f64_fixed()?,
            orientation_covariance: c.f64_fixed()?,
            angular_velocity: c.f64_fixed()?,
            angular_velocity_covariance: c.f64_fixed()?,
            linear_acceleration: c.f64_fixed()?,
            linear_acceleration_covariance: c.f64_fixed()?,
        })
    }
}

/// `sensor_msgs/Image`: raw pixels (see [`ImageMsg::pixels`] for the encodings read).
#[derive(Debug, Clone, PartialEq)]
pub struct ImageMsg {
    /// Time of the exposure, and the camera's optical frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (`mono8`, `rgb8`, `bgr8`, `16UC1`, `32FC1`, …).
    pub encoding: String,
    /// 1 when multi-byte pixels are big-endian.
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// The pixels, row after row.
    pub data: Vec<u8>,
}

impl RosMessage for ImageMsg {
    const TYPE: &'static str = "sensor_msgs/Image";
    const MD5SUM: &'static str = "060021388200f6f0f447d0fcd9c64743";
    fn read<W: Wire>(c: &mut W) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(c)?,
            height: c.u32()?,
            width: c.u32()?,
            encoding: c.string()?,
            is_bigendian: c.u8()?,
            step: c.u32()?,
            data: c.u8_array()?,
        })
    }
}

/// The pixels of an [`ImageMsg`], by encoding.
#[derive(Debug, Clone, PartialEq)]
pub enum Pixels {
    /// `mono8`: one byte per pixel.
    Mono8(Vec<u8>),
    /// `rgb8` and `bgr8` (reordered): red, green, blue per pixel.
    Rgb8(Vec<[u8; 3]>),
    /// `16UC1`: depth in millimetres (RealSense, Kinect).
    Depth16(Vec<u16>),
    /// `32FC1`: depth in metres.
    Depth32F(Vec<f32>),
}

impl ImageMsg {
    /// The pixels, row-major without row padding; `Err` for another encoding, or a `step`
    /// or data size that does not fit the width and height.
    ///
    /// ```
    /// use slamkit_io::bag::messages::{Header, ImageMsg, Pixels};
    /// use slamkit_io::bag::record::RosTime;
    ///
    /// let header = Header { seq: None, stamp: RosTime { sec: 1, nsec: 0 }, frame_id: "cam".into() };
    /// // 2×1 bgr8 with 2 bytes of row padding
    /// let img = ImageMsg { header, height: 1, width: 2, encoding: "bgr8".into(), is_bigendian: 0,
    ///                      step: 8, data: vec![3, 2, 1, 6, 5, 4, 0, 0] };
    /// assert_eq!(img.pixels()?, Pixels::Rgb8(vec![[1, 2, 3], [4, 5, 6]]));
    /// # Ok::<(), String>(())
    /// ```
    pub fn pixels(&self) -> Result<Pixels, String> {
        let bytes_per_pixel = match self.encoding.as_str() {
            "mono8" | "8UC1" => 1,
            "rgb8" | "bgr8" => 3,
            "16UC1" | "mono16" => 2,
            "32FC1" => 4,
            other => return Err(format!("image encoding {other:?} is not read")),
        };
        let (w, h, step) = (
            self.width as usize,
            self.height as usize,
            self.step as usize,
        );
        let row = w * bytes_per_pixel;
        if step < row
            || self.data.len() < step.saturating_mul(h.saturating_sub(1)) + row * usize::from(h > 0)
        {
            return Err(format!(
                "{}×{} {} image with step {} holds {} bytes",
                w,
                h,
                self.encoding,
                step,
                self.data.len()
            ));
        }
        let rows = (0..h).map(|r| &self.data[r * step..r * step + row]);
        let big = self.is_bigendian != 0;
        Ok(match self.encoding.as_str() {
            "mono8" | "8UC1" => Pixels::Mono8(rows.flatten().copied().collect()),
            "rgb8" => Pixels::Rgb8(
                rows.flat_map(|r| r.chunks_exact(3).map(|p| [p[0], p[1], p[2]]))
                    .collect(),
            ),
            "bgr8" => Pixels::Rgb8(
                rows.flat_map(|r| r.chunks_exact(3).map(|p| [p[2], p[1], p[0]]))
                    .collect(),
            ),
            "16UC1" | "mono16" => Pixels::Depth16(
                rows.flat_map(|r| {
                    r.chunks_exact(2).map(move |p| {
                        let b = [p[0], p[1]];
                        if big {
                            u16::from_be_bytes(b)
                        } else {
                            u16::from_le_bytes(b)
                        }
                    })
                })
                .collect(),
            ),
            _ => Pixels::Depth32F(
                rows.flat_map(|r| {
                    r.chunks_exact(4).map(move |p| {
                        let b = [p[0], p[1], p[2], p[3]];
                        if big {
                            f32::from_be_bytes(b)
                        } else {
                            f32::from_le_bytes(b)
                        }
                    })
                })
                .collect(),
            ),
        })
    }
}

/// `sensor_msgs/CompressedImage`: a JPEG or PNG file's bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct CompressedImageMsg {
    /// Time of the exposure, and the camera's optical frame.
    pub header: Header,
    /// `jpeg` or `png`, possibly with more (`rgb8; jpeg compressed bgr8`).
    pub format: String,
    /// The compressed image.
    pub data: Vec<u8>,
}

impl RosMessage for CompressedImageMsg {
    const TYPE: &'static str = "sensor_msgs/CompressedImage";
    const MD5SUM: &'static str = "8f7a12909da2c9d3332d540a0977563f";
    fn read<W: Wire>(c: &mut W) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(c)?,
            format: c.string()?,
            data: c.u8_array()?,
        })
    }
}

/// `sensor_msgs/CameraInfo`: a camera's calibration (`D`, `K`, `R`, `P` in ROS 1, `d`, `k`,
/// `r`, `p` in ROS 2; the same layout).
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfoMsg {
    /// Time, and the camera's optical frame.
    pub header: Header,
    /// Image rows.
    pub height: u32,
    /// Image columns.
    pub width: u32,
    /// `plumb_bob`, `rational_polynomial`, `equidistant`, …
    pub distortion_model: String,
    /// Distortion coefficients.
    pub d: Vec<f64>,
    /// Intrinsic matrix (row-major 3×3).
    pub k: [f64; 9],
    /// Rectification rotation (row-major 3×3).
    pub r: [f64; 9],
    /// Projection matrix (row-major 3×4).
    pub p: [f64; 12],
    /// Horizontal binning.
    pub binning_x: u32,
    /// Vertical binning.
    pub binning_y: u32,
    /// Region of interest: x offset, y offset, height, width.
    pub roi: [u32; 4],
    /// Whether the region of interest is to be rectified.
    pub roi_do_rectify: bool,
}

impl RosMessage for CameraInfoMsg {
    const TYPE: &'static str = "sensor_msgs/CameraInfo";
    const MD5SUM: &'static str = "c9a58c1b0b154e0e6da7578cb991d214";
    fn read<W: Wire>(c: &mut W) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(c)?,
            height: c.u32()?,
            width: c.u32()?,
            distortion_model: c.string()?,
            d: c.f64_array()?,
            k: c.f64_fixed()?,
            r: c.f64_fixed()?,
            p: c.f64_fixed()?,
            binning_x: c.u32()?,
            binning_y: c.u32()?,
            roi: [c.u32()?, c.u32()?, c.u32()?, c.u32()?],
            roi_do_rectify: c.u8()? != 0,
        })
    }
}

/// Writers of the same serialisation, for tests that build messages.
#[cfg(test)]
pub(crate) mod encode {
    use super::*;

    pub(crate) fn header(out: &mut Vec<u8>, h: &Header) {
        out.extend_from_slice(&h.seq.unwrap_or_default().to_le_bytes());
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
            seq: Some(1),
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
    fn hex(s: &str) -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    }

    /// Each message in the three serialisations, as PyPI `rosbags` 0.11.9 writes them
    /// (`serialize_cdr` little- and big-endian, `cdr_to_ros1`); header stamp 12.000000345 s,
    /// frame `cam` (see `scripts/make_ros2_bags.sh` for the tool).
    fn forms<M: RosMessage + PartialEq + std::fmt::Debug>(le: &str, be: &str, ros1: &str) -> M {
        let a = M::decode_cdr(&hex(le)).unwrap();
        let b = M::decode_cdr(&hex(be)).unwrap();
        assert_eq!(a, b);
        assert!(M::decode(&hex(ros1)).is_ok());
        for cut in [1, 5, 12] {
            let short = hex(le);
            assert!(M::decode_cdr(&short[..short.len().saturating_sub(cut * 4)]).is_err());
        }
        a
    }

    #[test]
    fn range_known_bytes() {
        let m: RangeMsg = forms(
            "000100000c000000590100000400000063616d00010000000000003f0ad7a33c000080400000a03f",
            "000000000000000c000001590000000463616d00010000003f0000003ca3d70a408000003fa00000",
            "000000000c000000590100000300000063616d010000003f0ad7a33c000080400000a03f",
        );
        assert_eq!(m.header.stamp, RosTime { sec: 12, nsec: 345 });
        assert_eq!((m.header.frame_id.as_str(), m.header.seq), ("cam", None));
        assert_eq!(
            (
                m.radiation_type,
                m.field_of_view,
                m.min_range,
                m.max_range,
                m.range
            ),
            (1, 0.5, 0.02, 4.0, 1.25)
        );
        let ros1 = RangeMsg::decode(&hex(
            "000000000c000000590100000300000063616d010000003f0ad7a33c000080400000a03f",
        ))
        .unwrap();
        assert_eq!(ros1.header.seq, Some(0));
        assert_eq!(
            RangeMsg {
                header: m.header.clone(),
                ..ros1
            },
            m
        );
    }

    #[test]
    fn image_and_compressed_image_known_bytes() {
        let m: ImageMsg = forms(
            "000100000c000000590100000400000063616d000200000003000000060000006d6f6e6f380000000300000006000000010203040506",
            "000000000000000c000001590000000463616d000000000200000003000000066d6f6e6f380000000000000300000006010203040506",
            "000000000c000000590100000300000063616d0200000003000000050000006d6f6e6f38000300000006000000010203040506",
        );
        assert_eq!(
            (m.height, m.width, m.encoding.as_str(), m.step),
            (2, 3, "mono8", 3)
        );
        assert_eq!(m.pixels().unwrap(), Pixels::Mono8(vec![1, 2, 3, 4, 5, 6]));
        let depth = ImageMsg {
            encoding: "16UC1".into(),
            width: 1,
            step: 2,
            data: vec![0xe8, 0x03, 0x01, 0x00],
            ..m.clone()
        };
        assert_eq!(depth.pixels().unwrap(), Pixels::Depth16(vec![1000, 1]));
        let f = ImageMsg {
            encoding: "32FC1".into(),
            height: 1,
            width: 1,
            step: 4,
            is_bigendian: 1,
            data: 1.5f32.to_be_bytes().to_vec(),
            ..m.clone()
        };
        assert_eq!(f.pixels().unwrap(), Pixels::Depth32F(vec![1.5]));
        let rgb = ImageMsg {
            encoding: "rgb8".into(),
            height: 1,
            width: 2,
            step: 6,
            data: vec![1, 2, 3, 4, 5, 6],
            ..m.clone()
        };
        assert_eq!(
            rgb.pixels().unwrap(),
            Pixels::Rgb8(vec![[1, 2, 3], [4, 5, 6]])
        );
        assert!(ImageMsg {
            step: 2,
            ..m.clone()
        }
        .pixels()
        .is_err());
        assert!(ImageMsg {
            encoding: "yuv422".into(),
            ..m
        }
        .pixels()
        .is_err());
        let c: CompressedImageMsg = forms(
            "000100000c000000590100000400000063616d0004000000706e67000400000089504e47",
            "000000000000000c000001590000000463616d0000000004706e67000000000489504e47",
            "000000000c000000590100000300000063616d03000000706e670400000089504e47",
        );
        assert_eq!(
            (c.format.as_str(), c.data.as_slice()),
            ("png", &[137u8, 80, 78, 71][..])
        );
    }

    #[test]
    fn imu_and_camera_info_known_bytes() {
        let m: ImuMsg = forms(
            "000100000c000000590100000400000063616d0000000000000000000000000000000000333333333333e33f9a9999999999e93f0000000000000000000000000000f03f000000000000004000000000000008400000000000001040000000000000144000000000000018400000000000001c4000000000000020409a9999999999b93f9a9999999999c9bf333333333333d33f000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000001f85eb51b89e2340000000000000f03f000000000000f03f000000000000f03f000000000000f03f000000000000f03f000000000000f03f000000000000f03f000000000000f03f000000000000f03f",
            "000000000000000c000001590000000463616d00000000000000000000000000000000003fe33333333333333fe999999999999a00000000000000003ff000000000000040000000000000004008000000000000401000000000000040140000000000004018000000000000401c00000000000040200000000000003fb999999999999abfc999999999999a3fd33333333333330000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000040239eb851eb851f3ff00000000000003ff00000000000003ff00000000000003ff00000000000003ff00000000000003ff00000000000003ff00000000000003ff00000000000003ff0000000000000",
            "000000000c000000590100000300000063616d00000000000000000000000000000000333333333333e33f9a9999999999e93f0000000000000000000000000000f03f000000000000004000000000000008400000000000001040000000000000144000000000000018400000000000001c4000000000000020409a9999999999b93f9a9999999999c9bf333333333333d33f000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000001f85eb51b89e2340000000000000f03f000000000000f03f000000000000f03f000000000000f03f000000000000f03f000000000000f03f000000000000f03f000000000000f03f000000000000f03f",
        );
        assert_eq!(m.orientation, [0.0, 0.0, 0.6, 0.8]);
        assert_eq!(m.orientation_covariance[8], 8.0);
        assert_eq!(
            (m.angular_velocity, m.linear_acceleration[2]),
            ([0.1, -0.2, 0.3], 9.81)
        );
        let c: CameraInfoMsg = forms(
            "000100000c000000590100000400000063616d00e0010000800200000a000000706c756d625f626f6200000005000000000000009a9999999999b93f9a9999999999c9bf000000000000000000000000000000000000000000000000000000000068804000000000000000000000000000f87340000000000000000000000000006880400000000000f06d4000000000000000000000000000000000000000000000f03f000000000000f03f000000000000000000000000000000000000000000000000000000000000f03f000000000000000000000000000000000000000000000000000000000000f03f000000000068804000000000000000000000000000f873400000000000000000000000000000000000000000006880400000000000f06d40000000000000000000000000000000000000000000000000000000000000f03f000000000000000000000000000000000000000000000000000000000000000000",
            "000000000000000c000001590000000463616d00000001e0000002800000000a706c756d625f626f6200000000000005000000003fb999999999999abfc999999999999a000000000000000000000000000000000000000000000000408068000000000000000000000000004073f8000000000000000000000000004080680000000000406df00000000000000000000000000000000000000000003ff00000000000003ff00000000000000000000000000000000000000000000000000000000000003ff00000000000000000000000000000000000000000000000000000000000003ff0000000000000408068000000000000000000000000004073f80000000000000000000000000000000000000000004080680000000000406df000000000000000000000000000000000000000000000000000000000003ff0000000000000000000000000000000000000000000000000000000000000000000000000000000",
            "000000000c000000590100000300000063616de00100008002000009000000706c756d625f626f62050000009a9999999999b93f9a9999999999c9bf000000000000000000000000000000000000000000000000000000000068804000000000000000000000000000f87340000000000000000000000000006880400000000000f06d4000000000000000000000000000000000000000000000f03f000000000000f03f000000000000000000000000000000000000000000000000000000000000f03f000000000000000000000000000000000000000000000000000000000000f03f000000000068804000000000000000000000000000f873400000000000000000000000000000000000000000006880400000000000f06d40000000000000000000000000000000000000000000000000000000000000f03f000000000000000000000000000000000000000000000000000000000000000000",
        );
        assert_eq!(
            (c.width, c.height, c.distortion_model.as_str()),
            (640, 480, "plumb_bob")
        );
        assert_eq!(c.d, vec![0.1, -0.2, 0.0, 0.0, 0.0]);
        assert_eq!((c.k[0], c.k[2], c.k[5], c.p[3]), (525.0, 319.5, 239.5, 0.0));
        assert_eq!((c.roi, c.roi_do_rectify), ([0; 4], false));
    }
}
