//! A 2D lidar log from whichever file a robot left: a CARMEN log (plain or gzip) or a ROS 1 /
//! ROS 2 bag, told apart by the file's first bytes ([`crate::layout::is_bag`]). Every program
//! that runs a lidar session on a recording (the CLI, the fleet's robots, the Python package)
//! reads through here, so they all refuse the same logs and warn about the same damage.

use crate::bag::{read_scan_log, BagError, ScanTopics};
use crate::carmen::{read_carmen, CarmenError, CarmenLog};
use std::path::Path;

/// A lidar log as read, with what the user should be told about it.
#[derive(Debug)]
pub struct LidarLogFile {
    /// The scans with their odometry (and, from a bag, the laser's mounting).
    pub log: CarmenLog,
    /// One line on what was read from a bag (topics, counts, mounting); `None` for a CARMEN log.
    pub description: Option<String>,
    /// Damage worth a warning: timestamps stepping back, a tilted laser, skipped messages.
    pub warnings: Vec<String>,
}

/// Why a lidar log could not be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LidarLogError {
    /// The CARMEN reader's error (its source, naming the file).
    #[error("reading log")]
    Carmen(#[from] CarmenError),
    /// The bag reader's error (its source, naming the file).
    #[error("reading bag")]
    Bag(#[from] BagError),
    /// Topics were named for a file that is not a bag.
    #[error("--scan-topic and --odom-topic apply to bags; {0} is not one")]
    TopicsWithoutBag(String),
    /// The file holds no scan at all.
    #[error("{0} holds no laser scan")]
    NoScans(String),
}

/// Reads the lidar log at `path`: a bag with the scan and odometry topics of `topics` (chosen
/// by type when `None`), or a CARMEN log (then `topics` must name none). A log without a
/// single scan is an error: nothing could be mapped from it.
///
/// ```
/// use slamkit_io::bag::ScanTopics;
/// use slamkit_io::lidar_log::{read_lidar_log, LidarLogError};
///
/// // Topics name messages in a bag; a CARMEN log has none to choose.
/// let path = std::env::temp_dir().join(format!("slamkit-doc-{}.clf", std::process::id()));
/// std::fs::write(&path, "# a CARMEN log\n")?;
/// let topics = ScanTopics { scan: Some("/scan".into()), odom: None };
/// let err = read_lidar_log(&path, &topics).unwrap_err();
/// assert!(matches!(err, LidarLogError::TopicsWithoutBag(_)));
/// std::fs::remove_file(&path)?;
/// # Ok::<(), std::io::Error>(())
/// ```
pub fn read_lidar_log(path: &Path, topics: &ScanTopics) -> Result<LidarLogFile, LidarLogError> {
    let (log, description, mut warnings) = if crate::layout::is_bag(path) {
        let bag = read_scan_log(path, topics)?;
        let (description, warnings) = (bag.describe(), bag.warnings());
        (bag.log, Some(description), warnings)
    } else {
        if topics.scan.is_some() || topics.odom.is_some() {
            return Err(LidarLogError::TopicsWithoutBag(path.display().to_string()));
        }
        (read_carmen(path)?, None, Vec::new())
    };
    if log.scans.is_empty() {
        return Err(LidarLogError::NoScans(path.display().to_string()));
    }
    if let Some(steps_back) = log.time_order.describe() {
        warnings.insert(0, steps_back);
    }
    Ok(LidarLogFile {
        log,
        description,
        warnings,
    })
}
