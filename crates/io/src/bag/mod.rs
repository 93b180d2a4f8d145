//! ROS 1 bags (format 2.0) and ROS 2 bags (MCAP, SQLite `.db3`) read with no ROS installed.
//!
//! [`open`] takes any of them and gives a [`MessageSource`]: topics, messages in storage
//! order, a summary. ROS 2 bags are a folder (`metadata.yaml` and storage files) or one
//! storage file ([`ros2`], [`mcap_file`], [`sqlite_file`]). Messages are decoded by one model
//! ([`messages`]) from either wire format ([`wire`]: ROS 1 serialisation in [`ros1`], CDR in
//! [`cdr`]), each topic checked first against what the bag stores about its type (ROS 1
//! md5sums, ROS 2 definitions: [`definition`]).
//!
//! The ROS 1 side:
//! A bag is a sequence of records (see the format description of `rosbag`, "Bag Format 2.0"):
//! a bag header pointing at the index, chunks of connection and message records stored plain,
//! bzip2- or LZ4-compressed, and at the end the index (every connection, and per chunk its
//! time span and message counts). The modules, from the bytes up:
//!
//! * [`record`]: records and their `name=value` headers, ROS times;
//! * [`chunk`]: chunk decompression (none, bz2 through the pure-Rust `libbz2-rs-sys`, lz4
//!   through `lz4_flex`), bounded by the size the chunk declares;
//! * [`connection`]: topics with their message type, md5sum and stored definition;
//! * [`reader`]: [`Bag`]: the header and index, and the messages in storage or time order
//!   (an unindexed bag is walked instead; damaged chunks are skipped and counted);
//! * [`ros1`] and [`messages`]: ROS 1 serialisation, and the messages slamkit reads
//!   (`sensor_msgs/LaserScan`, `nav_msgs/Odometry`, `tf2_msgs/TFMessage`), each decoded only
//!   from a connection whose type name and md5sum are the ones it was written for;
//! * [`info`]: topics, types, counts and time span (`slamkit bag info`);
//! * [`scans`]: a 2D lidar log from a bag: scans with odometry attached and the laser's
//!   mounting from `/tf_static`, the same [`crate::carmen::CarmenLog`] a CARMEN log gives, so
//!   that sessions do not know bags exist;
//! * [`rgbd`]: an RGB-D camera's frames from a bag (colour and depth images paired by time,
//!   the camera from `CameraInfo`), the frames a dataset folder gives.

pub mod camera_image;
pub mod cdr;
pub mod chunk;
pub mod connection;
pub mod definition;
mod describe;
pub mod info;
pub mod mcap_file;
pub mod messages;
pub mod reader;
pub mod record;
pub mod rgbd;
pub mod ros1;
pub mod ros2;
pub mod scans;
pub mod source;
pub mod sqlite_file;
pub mod wire;

pub use info::{bag_info, BagFormat, BagInfo};
pub use reader::{Bag, Order};
pub use record::RecordError;
pub use rgbd::{BagRgbd, RgbdTopics};
pub use scans::{read_scan_log, BagScanLog, ScanTopics};
pub use source::{open, MessageSource};

/// A bag that cannot be read, or read as asked.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BagError {
    /// The file could not be opened or read.
    #[error("{file}: {error}")]
    Open {
        /// The bag file.
        file: String,
        /// The operating system's error (in the message, not a `source()`).
        error: std::io::Error,
    },
    /// The file is not a bag (ROS 1 of format 2.0, or ROS 2).
    #[error("{file}: not a ROS 1 bag (format 2.0) or ROS 2 bag: {what}")]
    NotABag {
        /// The file.
        file: String,
        /// What it looks like instead.
        what: String,
    },
    /// A ROS 2 storage file that cannot be read (SQLite's error, a file compressed whole).
    #[error("{file}: {what}")]
    Storage {
        /// The storage file.
        file: String,
        /// What is wrong.
        what: String,
    },
    /// A record is damaged so that reading cannot go on.
    #[error("{file}: damaged at byte {offset}: {error}")]
    Damaged {
        /// The bag file.
        file: String,
        /// Offset of the record.
        offset: u64,
        /// What is wrong with it (in the message, not a `source()`).
        error: RecordError,
    },
    /// The topics asked for (or needed) are missing, ambiguous or of another type.
    #[error("{file}: {message}")]
    Topics {
        /// The bag file.
        file: String,
        /// What is wrong, with the topics there are.
        message: String,
    },
    /// The scan topic gave no readable scan.
    #[error("{file}: no readable laser scan on {topic} ({messages} messages, {skipped} could not be decoded)")]
    NoScans {
        /// The bag file.
        file: String,
        /// The scan topic.
        topic: String,
        /// Messages on it.
        messages: usize,
        /// Messages that did not decode.
        skipped: usize,
    },
}
