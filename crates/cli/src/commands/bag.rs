//! `slamkit bag info`: what a ROS 1 or ROS 2 bag holds; and the topics `slamkit lidar BAG`
//! reads (all the reading is `slamkit_io::bag`'s).

use slamkit_io::bag::ScanTopics;
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
    /// The topics to read, as the bag reader takes them.
    pub fn scan_topics(&self) -> ScanTopics {
        ScanTopics {
            scan: self.scan_topic.clone(),
            odom: self.odom_topic.clone(),
        }
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
        print!("{info}");
    }
    Ok(())
}
