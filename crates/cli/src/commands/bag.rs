//! `slamkit bag info`: what a ROS 1 or ROS 2 bag holds; and the bag side of `slamkit lidar BAG`: its
//! topics chosen, its scans read as a lidar log (all the reading is `slamkit_io::bag`'s).

use anyhow::Context;
use slamkit_io::bag::scans::Mounting;
use slamkit_io::bag::{read_scan_log, BagFormat, BagInfo, ScanTopics};
use slamkit_io::carmen::CarmenLog;
use std::path::{Path, PathBuf};

/// Arguments of `slamkit bag`.
#[derive(Debug, clap::Args)]
pub struct BagArgs {
    #[command(subcommand)]
    command: BagCommand,
}

#[derive(Debug, clap::Subcommand)]
enum BagCommand {
    /// Print a bag's topics, message types, counts and time span.
    Info {
        /// The bag: ROS 1 (`.bag`), or ROS 2 (a folder with `metadata.yaml`, or one `.mcap`
        /// or `.db3` file).
        bag: PathBuf,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
}

/// The topics of a bag to read (chosen by message type when there is only one of it).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct TopicArgs {
    /// Topic of the scans (`sensor_msgs/LaserScan`) in a bag.
    #[arg(long)]
    pub scan_topic: Option<String>,
    /// Topic of the wheel odometry (`nav_msgs/Odometry`) in a bag.
    #[arg(long)]
    pub odom_topic: Option<String>,
}

impl TopicArgs {
    /// True when a topic was named.
    pub fn any(&self) -> bool {
        self.scan_topic.is_some() || self.odom_topic.is_some()
    }
}

/// Runs `slamkit bag`.
pub fn run(args: &BagArgs) -> anyhow::Result<()> {
    match &args.command {
        BagCommand::Info { bag, json } => info(bag, *json),
    }
}

fn info(path: &Path, as_json: bool) -> anyhow::Result<()> {
    let mut bag = slamkit_io::bag::open(path)?;
    let info = bag.summary()?;
    if as_json {
        let mut value = serde_json::to_value(&info)?;
        value["duration_s"] = serde_json::json!(info.duration_s());
        println!("{value}");
    } else {
        print_info(&info);
    }
    Ok(())
}

fn print_info(info: &BagInfo) {
    println!("bag:        {}", info.file);
    let format = match info.format {
        BagFormat::Ros1 => "ROS 1 bag (format 2.0)",
        BagFormat::Mcap => "ROS 2 bag, MCAP storage",
        BagFormat::Sqlite3 => "ROS 2 bag, SQLite 3 storage (.db3)",
    };
    println!("format:     {format}");
    let index = match &info.index {
        slamkit_io::bag::reader::IndexState::Indexed => "indexed".to_string(),
        slamkit_io::bag::reader::IndexState::NotIndexed => {
            "not indexed (the recording was not closed); counted by reading the chunks".into()
        }
        slamkit_io::bag::reader::IndexState::Unreadable(why) => {
            format!("index unreadable ({why}); counted by reading the chunks")
        }
    };
    println!("index:      {index}");
    if let (Some(start), Some(end)) = (info.start_s, info.end_s) {
        println!(
            "time:       {start:.6} to {end:.6} s ({:.3} s)",
            end - start
        );
    }
    println!("messages:   {} in {} chunks", info.messages, info.chunks);
    let width = info.topics.iter().map(|t| t.topic.len()).max().unwrap_or(0);
    for t in &info.topics {
        let mut notes = Vec::new();
        if t.connections > 1 {
            notes.push(format!("{} connections", t.connections));
        }
        if t.latching {
            notes.push("latched".to_string());
        }
        let extra = if notes.is_empty() {
            String::new()
        } else {
            format!(" ({})", notes.join(", "))
        };
        println!(
            "topic:      {:width$}  {:>7} msgs  {}{extra}",
            t.topic, t.messages, t.message_type
        );
    }
    if let Some(walk) = &info.walk {
        for chunk in &walk.damaged_chunks {
            println!(
                "damaged:    chunk at byte {} skipped: {}",
                chunk.offset, chunk.error
            );
        }
        if let Some(cut) = &walk.truncated {
            println!(
                "truncated:  the file ends inside the record at byte {}: {}",
                cut.offset, cut.error
            );
        }
    }
}

/// The lidar log of the bag at `path`, its topics, mounting and damage reported on the
/// terminal.
pub(crate) fn read_log(path: &Path, topics: &TopicArgs) -> anyhow::Result<CarmenLog> {
    let topics = ScanTopics {
        scan: topics.scan_topic.clone(),
        odom: topics.odom_topic.clone(),
    };
    let bag = read_scan_log(path, &topics).context("reading bag")?;
    let mounting = match &bag.mounting {
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
    println!(
        "bag {}: {} scans on {}, odometry {}, {mounting}",
        path.display(),
        bag.log.scans.len(),
        bag.scan_topic,
        bag.odom_topic.as_deref().unwrap_or("none"),
    );
    if let Mounting::TfStatic { tilt_deg, .. } = bag.mounting {
        if tilt_deg > 5.0 {
            eprintln!("warning: the laser is tilted {tilt_deg:.1}° from level; its scans are projected as they are");
        }
    }
    if !bag.log.skipped.is_empty() {
        eprintln!(
            "warning: {} messages could not be decoded and were skipped (first: message {}: {})",
            bag.log.skipped.len(),
            bag.log.skipped[0].line,
            bag.log.skipped[0].reason
        );
    }
    if let slamkit_io::bag::reader::IndexState::Unreadable(why) = &bag.index {
        eprintln!(
            "warning: {}: the index is unreadable ({why}); the chunks were read one by one \
             (a bag cut short loses what followed the cut)",
            path.display()
        );
    }
    for chunk in &bag.read.damaged_chunks {
        eprintln!(
            "warning: {}: chunk at byte {} skipped: {}",
            path.display(),
            chunk.offset,
            chunk.error
        );
    }
    if let Some(cut) = &bag.read.truncated {
        eprintln!(
            "warning: {}: the bag is cut short at byte {} ({}); the messages before it are read",
            path.display(),
            cut.offset,
            cut.error
        );
    }
    Ok(bag.log)
}
