//! slamkit-io: readers and writers for datasets, trajectories and maps.
//!
//! Every reader returns a typed error naming the file and line or frame on bad input; none
//! panics.

pub mod dataset;
pub mod error;
pub mod euroc;
pub mod image_io;
pub mod kitti;
pub mod redwood;
pub mod seven_scenes;
pub mod trajectory_file;
pub mod tum_rgbd;

pub use dataset::{
    Dataset, DatasetFormat, RgbdFrame, RgbdImages, RgbdSequence, StereoFrame, StereoImages,
    StereoSequence,
};
pub use error::IoError;
pub use trajectory_file::{
    parse_trajectory, read_trajectory, write_kitti, write_tum, TrajectoryFormat,
};
