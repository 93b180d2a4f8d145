//! What a bag and a lidar log read from one look like to a person: `rosbag info`'s text for
//! [`BagInfo`], and for [`BagScanLog`] the line naming what was read and the warnings about what
//! was not (damaged chunks, a cut-short file, undecodable messages, a tilted laser). Kept beside
//! the types so the command line, the Python binding and a ROS 2 node say the same things.

use super::info::{BagFormat, BagInfo};
use super::reader::IndexState;
use super::scans::{BagScanLog, Mounting};
use std::fmt;

/// A laser tilted more than this from level \[deg\] is worth a warning: its scans are projected
/// onto the ground plane as they are, not corrected.
const TILT_WARNING_DEG: f64 = 5.0;

impl fmt::Display for BagInfo {
    /// `rosbag info`'s layout: one `label: value` line per fact, one line per topic.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "bag:        {}", self.file)?;
        let format = match self.format {
            BagFormat::Ros1 => "ROS 1 bag (format 2.0)",
            BagFormat::Mcap => "ROS 2 bag, MCAP storage",
            BagFormat::Sqlite3 => "ROS 2 bag, SQLite 3 storage (.db3)",
        };
        writeln!(f, "format:     {format}")?;
        let index = match &self.index {
            IndexState::Indexed => "indexed".to_string(),
            IndexState::NotIndexed => {
                "not indexed (the recording was not closed); counted by reading the chunks".into()
            }
            IndexState::Unreadable(why) => {
                format!("index unreadable ({why}); counted by reading the chunks")
            }
        };
        writeln!(f, "index:      {index}")?;
        if let (Some(start), Some(end)) = (self.start_s, self.end_s) {
            let span = end - start;
            writeln!(f, "time:       {start:.6} to {end:.6} s ({span:.3} s)")?;
        }
        writeln!(f, "messages:   {} in {} chunks", self.messages, self.chunks)?;
        let width = self.topics.iter().map(|t| t.topic.len()).max().unwrap_or(0);
        for t in &self.topics {
            let mut notes = Vec::new();
            if t.connections > 1 {
                notes.push(format!("{} connections", t.connections));
            }
            if t.latching {
                notes.push("latched".to_string());
            }
            let extra = match notes.is_empty() {
                true => String::new(),
                false => format!(" ({})", notes.join(", ")),
            };
            let (topic, count, kind) = (&t.topic, t.messages, &t.message_type);
            writeln!(
                f,
                "topic:      {topic:width$}  {count:>7} msgs  {kind}{extra}"
            )?;
        }
        if let Some(walk) = &self.walk {
            for chunk in &walk.damaged_chunks {
                let (at, error) = (chunk.offset, &chunk.error);
                writeln!(f, "damaged:    chunk at byte {at} skipped: {error}")?;
            }
            if let Some(cut) = &walk.truncated {
                let (at, error) = (cut.offset, &cut.error);
                writeln!(
                    f,
                    "truncated:  the file ends inside the record at byte {at}: {error}"
                )?;
            }
        }
        Ok(())
    }
}

impl BagScanLog {
    /// One line: the scans and odometry read, from which topics, and where the laser sits.
    ///
    /// ```
    /// use slamkit_io::bag::scans::Mounting;
    /// use slamkit_io::bag::BagScanLog;
    /// let log = BagScanLog {
    ///     log: Default::default(),
    ///     scan_topic: "/scan".into(),
    ///     odom_topic: None,
    ///     mounting: Mounting::Identity { reason: "no /tf_static".into() },
    ///     read: Default::default(),
    ///     index: slamkit_io::bag::reader::IndexState::Indexed,
    /// };
    /// assert_eq!(
    ///     log.describe(),
    ///     "0 scans on /scan, odometry none, laser at the base (no /tf_static)"
    /// );
    /// ```
    pub fn describe(&self) -> String {
        let mounting = match &self.mounting {
            Mounting::TfStatic {
                base_frame,
                laser_frame,
                x_y_yaw: [x, y, yaw],
                mirrored,
                ..
            } => format!(
                "laser {laser_frame} at ({x:.3} m, {y:.3} m, {yaw:.3} rad) on {base_frame}{} \
                 (/tf_static)",
                if *mirrored { ", upside down" } else { "" }
            ),
            Mounting::Identity { reason } => format!("laser at the base ({reason})"),
        };
        format!(
            "{} scans on {}, odometry {}, {mounting}",
            self.log.scans.len(),
            self.scan_topic,
            self.odom_topic.as_deref().unwrap_or("none"),
        )
    }

    /// What a user should know was not read as recorded, one sentence each: a tilted laser,
    /// undecodable messages, an unreadable index, damaged chunks, a file cut short.
    pub fn warnings(&self) -> Vec<String> {
        let mut warnings = Vec::new();
        if let Mounting::TfStatic { tilt_deg, .. } = self.mounting {
            if tilt_deg > TILT_WARNING_DEG {
                warnings.push(format!(
                    "the laser is tilted {tilt_deg:.1}° from level; its scans are projected as \
                     they are"
                ));
            }
        }
        if let Some(first) = self.log.skipped.first() {
            warnings.push(format!(
                "{} messages could not be decoded and were skipped (first: message {}: {})",
                self.log.skipped.len(),
                first.line,
                first.reason
            ));
        }
        if let IndexState::Unreadable(why) = &self.index {
            warnings.push(format!(
                "the index is unreadable ({why}); the chunks were read one by one (a bag cut \
                 short loses what followed the cut)"
            ));
        }
        for chunk in &self.read.damaged_chunks {
            let (at, error) = (chunk.offset, &chunk.error);
            warnings.push(format!("chunk at byte {at} skipped: {error}"));
        }
        if let Some(cut) = &self.read.truncated {
            warnings.push(format!(
                "the bag is cut short at byte {} ({}); the messages before it are read",
                cut.offset, cut.error
            ));
        }
        warnings
    }
}
