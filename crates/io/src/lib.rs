//! slamkit-io: readers and writers for datasets, trajectories and maps.
//!
//! Every reader returns a typed error naming the file and line or frame on bad input; none
//! panics.

pub mod error;
pub mod image_io;
pub mod trajectory_file;

pub use error::IoError;
pub use trajectory_file::{
    parse_trajectory, read_trajectory, write_kitti, write_tum, TrajectoryFormat,
};
