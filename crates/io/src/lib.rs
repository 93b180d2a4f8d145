//! slamkit-io: readers and writers for datasets, trajectories and maps.
//!
//! Every reader returns a typed error ([`IoError`]) naming the file and line or frame on bad
//! input; none panics.
//!
//! * [`trajectory_file`]: TUM, KITTI and EuRoC-CSV trajectories, format told from content.
//! * [`image_io`]: 8-bit gray / RGB and 16-bit depth images into `slamkit_core::image::Image`.
//! * Camera datasets, each giving frames (timestamps + paths, images decoded on demand),
//!   calibrated cameras and `world_from_camera` ground truth: [`tum_rgbd`], [`kitti`],
//!   [`seven_scenes`], [`redwood`], [`euroc`]; [`Dataset`] opens any of them by name.
//! * [`dataset`]: what every camera dataset reader returns, and [`Dataset`] to open any of
//!   them by format name.
//! * Writers for simulated data: [`tum_rgbd_writer`], [`kitti_writer`] (images through
//!   [`image_writer`]), [`carmen_writer`].
//! * [`drone_csv`]: a drone's range finders, attitude and gyro, and optical flow as CSV files
//!   (read and written), the signals layered drone SLAM takes besides the scans.
//! * 2D lidar logs: [`carmen`] (CARMEN `.clf`, plain or gzip: scans with wheel odometry) and
//!   [`mrpt_text`] (text dumps of MRPT rawlogs and ground-truth files).
//! * [`lidar_log`]: a lidar log from a CARMEN file or a bag, whichever the path holds, with the
//!   warnings a user should see; a log without scans refused.
//! * [`bag`]: ROS 1 bags (format 2.0: none, bz2 and lz4 chunks, indexed or not): topics,
//!   messages in storage or time order, `sensor_msgs/LaserScan`, `nav_msgs/Odometry` and
//!   `tf2_msgs/TFMessage` decoded, and a 2D lidar log with odometry and mounting from a bag.
//! * [`g2o`]: 3D pose graphs in g2o's text format (`VERTEX_SE3:QUAT`, `EDGE_SE3:QUAT`, `FIX`).
//! * [`time_order`]: timestamps stepping back in a lidar log, counted; a log mostly out of
//!   order refused.
//! * [`repeated_log`]: a lidar log played several times in a row (stamps shifted, odometry
//!   continued), for long-run checks without a long file.
//! * [`relations`]: ground-truth relations of the 2D SLAM benchmark (`*.relations`,
//!   Kümmerle et al. 2009).
//! * [`ply`]: point clouds as PLY for any viewer.
//! * [`output_folder`]: a run's outputs written atomically (temporary file or staging folder,
//!   then rename), an earlier run's files not mixed with the new ones.
//! * [`error`]: [`IoError`], every variant naming the file, and the line or frame.

pub mod bag;
pub mod carmen;
pub mod carmen_writer;
pub mod dataset;
pub mod degraded_log;
pub mod drone_csv;
pub mod error;
pub mod euroc;
pub mod g2o;
pub mod image_io;
pub mod image_writer;
pub mod kitti;
pub mod kitti_writer;
pub mod layout;
pub mod lidar_log;
pub mod mrpt_text;
pub mod odometry_bracket;
pub mod output_folder;
pub mod ply;
pub mod redwood;
pub mod relations;
pub mod repeated_log;
pub mod seven_scenes;
pub mod time_order;
pub mod trajectory_file;
pub mod tum_rgbd;
pub mod tum_rgbd_writer;

pub use dataset::{
    Dataset, DatasetFormat, RgbdFrame, RgbdImages, RgbdSequence, StereoFrame, StereoImages,
    StereoSequence,
};
pub use error::IoError;
pub use trajectory_file::{
    parse_trajectory, read_trajectory, write_kitti, write_tum, TrajectoryFormat,
};
