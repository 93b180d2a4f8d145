//! The ROS 2 messages the node exchanges, as serde structs in the field order of their ROS 2
//! definitions (CDR, which RustDDS reads and writes through serde, is that order with no field
//! names). Incoming messages are turned into the bag reader's message types
//! ([`slamkit_io::bag::messages`]) so live topics and bags go through the same checks and
//! conversions ([`slamkit_io::bag::scans`]).

use serde::de::{Error as _, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use slamkit_core::camera::Intrinsics;
use slamkit_core::image::RgbImage;
use slamkit_core::Pose3;
use slamkit_io::bag::messages as bag;
use slamkit_io::bag::record::RosTime;

/// `builtin_interfaces/Time`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    /// Whole seconds (signed in ROS 2).
    pub sec: i32,
    /// Nanoseconds, below 10⁹.
    pub nanosec: u32,
}

impl Time {
    /// The nearest time to `seconds` (saturated to the type's range). An `f64` holds a
    /// present-day stamp to about 0.1 µs, so the node publishes the stamps it received, not
    /// these.
    ///
    /// ```
    /// use slamkit_ros2::msgs::Time;
    /// let t = Time::from_secs_f64(70.29);
    /// assert_eq!((t.sec, t.nanosec), (70, 290_000_000));
    /// let t = Time::from_secs_f64(976052857.337284);
    /// assert_eq!(t.sec, 976052857);
    /// assert!((t.as_secs_f64() - 976052857.337284).abs() < 1e-9);
    /// ```
    pub fn from_secs_f64(seconds: f64) -> Self {
        let seconds = seconds.clamp(f64::from(i32::MIN), f64::from(i32::MAX));
        let whole = seconds.floor();
        let nanos = ((seconds - whole) * 1e9).round() as u32;
        // a fraction that rounds up to a whole second carries
        let (sec, nanosec) = if nanos >= 1_000_000_000 {
            (whole + 1.0, nanos - 1_000_000_000)
        } else {
            (whole, nanos)
        };
        Self {
            sec: sec.min(f64::from(i32::MAX)) as i32,
            nanosec,
        }
    }

    /// Seconds as `f64`.
    pub fn as_secs_f64(&self) -> f64 {
        f64::from(self.sec) + f64::from(self.nanosec) * 1e-9
    }

    /// As the bag reader's time, which is unsigned: a stamp before 1970 is refused.
    fn to_ros_time(self) -> Result<RosTime, String> {
        let sec = u32::try_from(self.sec).map_err(|_| format!("negative stamp {}", self.sec))?;
        Ok(RosTime {
            sec,
            nsec: self.nanosec,
        })
    }
}

/// `std_msgs/Header` (ROS 2: no sequence number).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Time of the data.
    pub stamp: Time,
    /// Frame of the data.
    pub frame_id: String,
}

impl Header {
    fn to_bag(&self) -> Result<bag::Header, String> {
        Ok(bag::Header {
            seq: None,
            stamp: self.stamp.to_ros_time()?,
            frame_id: self.frame_id.clone(),
        })
    }
}

/// `geometry_msgs/Vector3` (and `Point`, which has the same layout).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/Pose` (and `Transform`, the same layout: translation, rotation).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position \[m\].
    pub position: Vector3,
    /// Orientation.
    pub orientation: Quaternion,
}

impl Pose {
    /// A slamkit pose as a ROS pose.
    pub fn from_isometry(pose: &Pose3) -> Self {
        let t = pose.translation.vector;
        let q = pose.rotation.quaternion();
        Self {
            position: Vector3 {
                x: t.x,
                y: t.y,
                z: t.z,
            },
            orientation: Quaternion {
                x: q.i,
                y: q.j,
                z: q.k,
                w: q.w,
            },
        }
    }

    fn to_bag(self) -> bag::PoseMsg {
        let (p, q) = (self.position, self.orientation);
        bag::PoseMsg {
            position: [p.x, p.y, p.z],
            orientation: [q.x, q.y, q.z, q.w],
        }
    }
}

/// A 6×6 row-major covariance (`float64[36]`: a CDR fixed array, no length on the wire;
/// serde derives arrays only up to 32 elements).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covariance(pub [f64; 36]);

impl Default for Covariance {
    fn default() -> Self {
        Self([0.0; 36])
    }
}

impl Serialize for Covariance {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(36)?;
        for v in &self.0 {
            t.serialize_element(v)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Elements;
        impl<'de> Visitor<'de> for Elements {
            type Value = Covariance;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("36 float64")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Covariance, A::Error> {
                let mut out = [0.0; 36];
                for (i, slot) in out.iter_mut().enumerate() {
                    *slot = seq
                        .next_element()?
                        .ok_or_else(|| A::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance(out))
            }
        }
        d.deserialize_tuple(36, Elements)
    }
}

/// `geometry_msgs/PoseWithCovariance`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Its covariance (x, y, z, rotations about x, y, z).
    pub covariance: Covariance,
}

/// `geometry_msgs/Twist`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity \[m/s\].
    pub linear: Vector3,
    /// Angular velocity \[rad/s\].
    pub angular: Vector3,
}

/// `geometry_msgs/TwistWithCovariance`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// Its covariance.
    pub covariance: Covariance,
}

/// `sensor_msgs/LaserScan`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LaserScan {
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
    /// Intensities, possibly empty.
    pub intensities: Vec<f32>,
}

impl LaserScan {
    /// As the bag reader's message (for [`slamkit_io::bag::scans::to_laser_scan`]).
    ///
    /// # Errors
    /// A stamp before 1970.
    pub fn to_bag(&self) -> Result<bag::LaserScanMsg, String> {
        Ok(bag::LaserScanMsg {
            header: self.header.to_bag()?,
            angle_min: self.angle_min,
            angle_max: self.angle_max,
            angle_increment: self.angle_increment,
            time_increment: self.time_increment,
            scan_time: self.scan_time,
            range_min: self.range_min,
            range_max: self.range_max,
            ranges: self.ranges.clone(),
            intensities: self.intensities.clone(),
        })
    }
}

/// `nav_msgs/Odometry`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// Time, and the odometry frame.
    pub header: Header,
    /// The robot's frame.
    pub child_frame_id: String,
    /// `odom_from_base`.
    pub pose: PoseWithCovariance,
    /// Velocity in the robot's frame.
    pub twist: TwistWithCovariance,
}

impl Odometry {
    /// As the bag reader's message (for [`slamkit_io::bag::scans::odom_sample`]).
    ///
    /// # Errors
    /// A stamp before 1970.
    pub fn to_bag(&self) -> Result<bag::OdometryMsg, String> {
        let (l, a) = (self.twist.twist.linear, self.twist.twist.angular);
        Ok(bag::OdometryMsg {
            header: self.header.to_bag()?,
            child_frame_id: self.child_frame_id.clone(),
            pose: self.pose.pose.to_bag(),
            pose_covariance: self.pose.covariance.0,
            linear: [l.x, l.y, l.z],
            angular: [a.x, a.y, a.z],
            twist_covariance: self.twist.covariance.0,
        })
    }
}

/// `geometry_msgs/TransformStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Time, and the parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// `parent_from_child` (translation, rotation).
    pub transform: Pose,
}

/// `tf2_msgs/TFMessage`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

impl TfMessage {
    /// As the bag reader's message (for [`slamkit_io::bag::scans::add_static_transforms`]).
    ///
    /// # Errors
    /// A stamp before 1970.
    pub fn to_bag(&self) -> Result<bag::TfMessageMsg, String> {
        let transforms = self
            .transforms
            .iter()
            .map(|t| {
                Ok(bag::TransformStampedMsg {
                    header: t.header.to_bag()?,
                    child_frame_id: t.child_frame_id.clone(),
                    transform: t.transform.to_bag(),
                })
            })
            .collect::<Result<_, String>>()?;
        Ok(bag::TfMessageMsg { transforms })
    }
}

/// `sensor_msgs/Range` (Jazzy's layout: no `variance`, which later distributions append).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Range {
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
    /// The range \[m\] (+inf: nothing within `max_range`, -inf: nearer than `min_range`,
    /// REP 117).
    pub range: f32,
}

impl Range {
    /// As the bag reader's message.
    ///
    /// # Errors
    /// A stamp before 1970.
    pub fn to_bag(&self) -> Result<bag::RangeMsg, String> {
        Ok(bag::RangeMsg {
            header: self.header.to_bag()?,
            radiation_type: self.radiation_type,
            field_of_view: self.field_of_view,
            min_range: self.min_range,
            max_range: self.max_range,
            range: self.range,
        })
    }
}

/// `sensor_msgs/Imu`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// Time of the reading, and the IMU's frame.
    pub header: Header,
    /// Orientation of the IMU in a level frame.
    pub orientation: Quaternion,
    /// Its covariance (row-major 3×3; element 0 = -1: no orientation).
    pub orientation_covariance: [f64; 9],
    /// Angular velocity in the IMU's frame \[rad/s\].
    pub angular_velocity: Vector3,
    /// Its covariance.
    pub angular_velocity_covariance: [f64; 9],
    /// Linear acceleration \[m/s²\].
    pub linear_acceleration: Vector3,
    /// Its covariance.
    pub linear_acceleration_covariance: [f64; 9],
}

impl Imu {
    /// As the bag reader's message.
    ///
    /// # Errors
    /// A stamp before 1970.
    pub fn to_bag(&self) -> Result<bag::ImuMsg, String> {
        let (q, w, a) = (
            self.orientation,
            self.angular_velocity,
            self.linear_acceleration,
        );
        Ok(bag::ImuMsg {
            header: self.header.to_bag()?,
            orientation: [q.x, q.y, q.z, q.w],
            orientation_covariance: self.orientation_covariance,
            angular_velocity: [w.x, w.y, w.z],
            angular_velocity_covariance: self.angular_velocity_covariance,
            linear_acceleration: [a.x, a.y, a.z],
            linear_acceleration_covariance: self.linear_acceleration_covariance,
        })
    }
}

impl LaserScan {
    /// A slamkit scan as a ROS scan in `header`'s frame: ranges as they are (NaN and readings
    /// below `range_min_m` are beams without a return, as ROS defines them), `range_max` the
    /// scan's maximum range, `scan_time_s` the time between scans.
    pub fn from_scan(
        header: Header,
        scan: &slamkit_core::LaserScan,
        range_min_m: f64,
        scan_time_s: f64,
    ) -> Self {
        let beams = scan.ranges_m.len().max(1) - 1;
        Self {
            header,
            angle_min: scan.angle_min_rad as f32,
            angle_max: (scan.angle_min_rad + beams as f64 * scan.angle_increment_rad) as f32,
            angle_increment: scan.angle_increment_rad as f32,
            time_increment: 0.0,
            scan_time: scan_time_s as f32,
            range_min: range_min_m as f32,
            range_max: scan.max_range_m as f32,
            ranges: scan.ranges_m.iter().map(|&r| r as f32).collect(),
            intensities: Vec::new(),
        }
    }
}

/// `geometry_msgs/PoseWithCovarianceStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovarianceStamped {
    /// Time, and the frame of the pose.
    pub header: Header,
    /// The pose.
    pub pose: PoseWithCovariance,
}

/// `nav_msgs/MapMetaData`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct MapMetaData {
    /// When the map was loaded (made).
    pub map_load_time: Time,
    /// Side of a cell \[m\].
    pub resolution: f32,
    /// Cells along x.
    pub width: u32,
    /// Cells along y.
    pub height: u32,
    /// Pose of the corner of cell (0, 0) in the map frame.
    pub origin: Pose,
}

/// `nav_msgs/OccupancyGrid`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct OccupancyGrid {
    /// Time, and the map frame.
    pub header: Header,
    /// Size, resolution and origin.
    pub info: MapMetaData,
    /// Row-major cells, row 0 at the origin: occupancy probability 0..100, -1 unknown.
    pub data: Vec<i8>,
}

/// `sensor_msgs/Image`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Image {
    /// Time of the exposure, and the camera's optical frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (`rgb8`, `16UC1`, ...).
    pub encoding: String,
    /// Whether multi-byte pixels are big endian.
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// The pixels.
    pub data: Vec<u8>,
}

impl Image {
    /// As the bag reader's message (for [`slamkit_io::bag::rgbd`]'s conversions).
    ///
    /// # Errors
    /// A stamp before 1970.
    pub fn into_bag(self) -> Result<bag::ImageMsg, String> {
        Ok(bag::ImageMsg {
            header: self.header.to_bag()?,
            height: self.height,
            width: self.width,
            encoding: self.encoding,
            is_bigendian: self.is_bigendian,
            step: self.step,
            data: self.data,
        })
    }
}

impl Image {
    /// An `rgb8` colour image.
    ///
    /// ```
    /// use slamkit_core::image::RgbImage;
    /// use slamkit_ros2::msgs::{Header, Image};
    /// let pixels = RgbImage::from_vec(2, 1, vec![[1, 2, 3], [4, 5, 6]]).unwrap();
    /// let m = Image::rgb8(Header::default(), &pixels);
    /// assert_eq!((m.width, m.height, m.step), (2, 1, 6));
    /// assert_eq!(m.data, [1, 2, 3, 4, 5, 6]);
    /// ```
    pub fn rgb8(header: Header, image: &RgbImage) -> Self {
        let data: Vec<u8> = image.data().iter().flatten().copied().collect();
        Self::packed(header, (image.width(), image.height()), "rgb8", data)
    }

    /// A `32FC1` depth image in metres (0 where there is no depth, as the session reads it),
    /// little endian.
    ///
    /// ```
    /// use slamkit_core::image::Image as Pixels;
    /// use slamkit_ros2::msgs::{Header, Image};
    /// let depth = Pixels::from_vec(1, 1, vec![1.5f32]).unwrap();
    /// let m = Image::depth_32fc1(Header::default(), &depth);
    /// assert_eq!((m.encoding.as_str(), m.step), ("32FC1", 4));
    /// assert_eq!(m.data, 1.5f32.to_le_bytes());
    /// ```
    pub fn depth_32fc1(header: Header, depth_m: &slamkit_core::image::Image<f32>) -> Self {
        let data: Vec<u8> = depth_m
            .data()
            .iter()
            .flat_map(|d| d.to_le_bytes())
            .collect();
        Self::packed(header, (depth_m.width(), depth_m.height()), "32FC1", data)
    }

    /// Rows of `data` with no padding.
    fn packed(
        header: Header,
        (width, height): (usize, usize),
        encoding: &str,
        data: Vec<u8>,
    ) -> Self {
        let step = data.len().checked_div(height).unwrap_or(0);
        Self {
            header,
            height: height as u32,
            width: width as u32,
            encoding: encoding.into(),
            is_bigendian: 0,
            step: step as u32,
            data,
        }
    }
}

/// `sensor_msgs/CompressedImage`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage {
    /// Time of the exposure, and the camera's optical frame.
    pub header: Header,
    /// `jpeg` or `png` (image_transport writes `rgb8; jpeg compressed bgr8`).
    pub format: String,
    /// The compressed file's bytes.
    pub data: Vec<u8>,
}

impl CompressedImage {
    /// As the bag reader's message.
    ///
    /// # Errors
    /// A stamp before 1970.
    pub fn into_bag(self) -> Result<bag::CompressedImageMsg, String> {
        Ok(bag::CompressedImageMsg {
            header: self.header.to_bag()?,
            format: self.format,
            data: self.data,
        })
    }
}

/// `sensor_msgs/RegionOfInterest`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct RegionOfInterest {
    /// Left column.
    pub x_offset: u32,
    /// Top row.
    pub y_offset: u32,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Whether the region is to be rectified.
    pub do_rectify: bool,
}

/// `sensor_msgs/CameraInfo`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CameraInfo {
    /// Time, and the camera's optical frame.
    pub header: Header,
    /// Image rows.
    pub height: u32,
    /// Image columns.
    pub width: u32,
    /// `plumb_bob`, `rational_polynomial`, ...
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
    /// Region of interest.
    pub roi: RegionOfInterest,
}

impl CameraInfo {
    /// As the bag reader's message (for [`slamkit_io::bag::rgbd::camera_of`]).
    ///
    /// # Errors
    /// A stamp before 1970.
    pub fn to_bag(&self) -> Result<bag::CameraInfoMsg, String> {
        let roi = self.roi;
        Ok(bag::CameraInfoMsg {
            header: self.header.to_bag()?,
            height: self.height,
            width: self.width,
            distortion_model: self.distortion_model.clone(),
            d: self.d.clone(),
            k: self.k,
            r: self.r,
            p: self.p,
            binning_x: self.binning_x,
            binning_y: self.binning_y,
            roi: [roi.x_offset, roi.y_offset, roi.height, roi.width],
            roi_do_rectify: roi.do_rectify,
        })
    }
}

impl CameraInfo {
    /// The calibration of an undistorted pinhole camera (`plumb_bob`, zero distortion), as a
    /// driver publishes it for rectified images.
    ///
    /// ```
    /// use slamkit_core::camera::Intrinsics;
    /// use slamkit_ros2::msgs::{CameraInfo, Header};
    /// let k = Intrinsics { fx: 500.0, fy: 501.0, cx: 320.0, cy: 240.0, width: 640, height: 480 };
    /// let info = CameraInfo::pinhole(Header::default(), &k);
    /// let camera = slamkit_io::bag::rgbd::camera_of(&info.to_bag().unwrap(), None).unwrap();
    /// assert_eq!(camera.intrinsics, k);
    /// ```
    pub fn pinhole(header: Header, k: &Intrinsics) -> Self {
        Self {
            header,
            height: k.height as u32,
            width: k.width as u32,
            distortion_model: "plumb_bob".into(),
            d: vec![0.0; 5],
            k: [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0],
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [
                k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
            ],
            ..Self::default()
        }
    }
}

/// `geometry_msgs/PoseStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Time, and the frame of the pose.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

/// `nav_msgs/Path`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Path {
    /// Time, and the frame of the poses.
    pub header: Header,
    /// The poses, oldest first.
    pub poses: Vec<PoseStamped>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_roundtrip_and_negative_stamps() {
        for s in [0.0, 1.5, 976052857.337284, 70.29] {
            let t = Time::from_secs_f64(s);
            assert!((t.as_secs_f64() - s).abs() < 1e-9, "{s}");
            assert!(t.nanosec < 1_000_000_000);
        }
        let t = Time::from_secs_f64(-0.25);
        assert_eq!((t.sec, t.nanosec), (-1, 750_000_000));
        assert!(t.to_ros_time().is_err());
    }

    /// CDR as RustDDS writes it (little endian, after the 4-byte encapsulation header ROS 2
    /// messages carry in bags).
    fn cdr<T: Serialize>(value: &T) -> Vec<u8> {
        use ros2_client::dds::rustdds::serialization::{
            to_writer_with_rep_id, RepresentationIdentifier,
        };
        let mut bytes = vec![0, 1, 0, 0];
        to_writer_with_rep_id(&mut bytes, value, RepresentationIdentifier::CDR_LE).unwrap();
        bytes
    }

    /// The serde layouts are the ROS 2 definitions: what RustDDS writes from them, the bag
    /// reader's CDR decoder (checked against rosbags-written bags) reads back field for field.
    #[test]
    fn serde_layouts_decode_with_the_bag_readers_cdr_decoder() {
        use slamkit_io::bag::messages::RosMessage;
        let scan = LaserScan {
            header: Header {
                stamp: Time {
                    sec: 976052857,
                    nanosec: 337530017,
                },
                frame_id: "laser".into(),
            },
            angle_min: -1.57,
            angle_max: 1.57,
            angle_increment: 0.0175,
            time_increment: 0.0,
            scan_time: 0.2,
            range_min: 0.1,
            range_max: 81.9,
            ranges: vec![1.0, 2.5, 81.9],
            intensities: vec![],
        };
        let decoded = bag::LaserScanMsg::decode_cdr(&cdr(&scan)).unwrap();
        assert_eq!(decoded, scan.to_bag().unwrap());
        let mut odom = Odometry::default();
        odom.header.frame_id = "odom".into();
        odom.child_frame_id = "base_link".into();
        odom.pose.pose.position.y = -3.25;
        odom.pose.covariance.0[7] = 0.01;
        odom.twist.twist.angular.z = 0.5;
        odom.twist.covariance.0[35] = 0.2;
        let decoded = bag::OdometryMsg::decode_cdr(&cdr(&odom)).unwrap();
        assert_eq!(decoded, odom.to_bag().unwrap());
        let tf = TfMessage {
            transforms: vec![
                TransformStamped {
                    header: Header::default(),
                    child_frame_id: "laser".into(),
                    transform: Pose::default(),
                };
                2
            ],
        };
        let decoded = bag::TfMessageMsg::decode_cdr(&cdr(&tf)).unwrap();
        assert_eq!(decoded, tf.to_bag().unwrap());
        let range = Range {
            header: Header::default(),
            radiation_type: 1,
            field_of_view: 0.05,
            min_range: 0.02,
            max_range: 4.0,
            range: f32::INFINITY,
        };
        let decoded = bag::RangeMsg::decode_cdr(&cdr(&range)).unwrap();
        assert_eq!(decoded, range.to_bag().unwrap());
        let mut imu = Imu::default();
        imu.orientation.z = 0.6;
        imu.orientation.w = 0.8;
        imu.orientation_covariance[0] = 0.01;
        imu.angular_velocity.z = -0.3;
        imu.linear_acceleration.z = 9.81;
        imu.linear_acceleration_covariance[8] = 0.2;
        let decoded = bag::ImuMsg::decode_cdr(&cdr(&imu)).unwrap();
        assert_eq!(decoded, imu.to_bag().unwrap());
    }

    /// The camera messages likewise (and `CompressedImage`).
    #[test]
    fn camera_layouts_decode_with_the_bag_readers_cdr_decoder() {
        use slamkit_io::bag::messages::RosMessage;
        let header = Header {
            stamp: Time { sec: 7, nanosec: 9 },
            frame_id: "camera_color_optical_frame".into(),
        };
        let image = Image {
            header: header.clone(),
            height: 1,
            width: 2,
            encoding: "16UC1".into(),
            is_bigendian: 0,
            step: 4,
            data: vec![1, 2, 3, 4],
        };
        let decoded = bag::ImageMsg::decode_cdr(&cdr(&image)).unwrap();
        assert_eq!(decoded, image.into_bag().unwrap());
        let info = CameraInfo {
            header: header.clone(),
            height: 480,
            width: 640,
            distortion_model: "plumb_bob".into(),
            d: vec![0.1, -0.2, 0.0, 0.0, 0.05],
            k: [585.0, 0.0, 320.0, 0.0, 585.0, 240.0, 0.0, 0.0, 1.0],
            roi: RegionOfInterest {
                x_offset: 1,
                width: 3,
                do_rectify: true,
                ..RegionOfInterest::default()
            },
            ..CameraInfo::default()
        };
        let decoded = bag::CameraInfoMsg::decode_cdr(&cdr(&info)).unwrap();
        assert_eq!(decoded, info.to_bag().unwrap());
        let jpeg = CompressedImage {
            header,
            format: "rgb8; jpeg compressed bgr8".into(),
            data: vec![0xff, 0xd8, 0xff],
        };
        let decoded = bag::CompressedImageMsg::decode_cdr(&cdr(&jpeg)).unwrap();
        assert_eq!(decoded, jpeg.into_bag().unwrap());
    }

    #[test]
    fn odometry_converts_to_the_bag_message() {
        let mut odom = Odometry::default();
        odom.header.stamp = Time { sec: 3, nanosec: 5 };
        odom.pose.pose.position.x = 2.0;
        odom.pose.covariance.0[35] = 0.5;
        let b = odom.to_bag().unwrap();
        assert_eq!(b.header.stamp, RosTime { sec: 3, nsec: 5 });
        assert_eq!(b.pose.position, [2.0, 0.0, 0.0]);
        assert_eq!(b.pose.orientation, [0.0, 0.0, 0.0, 1.0]);
        assert_eq!(b.pose_covariance[35], 0.5);
    }
}
