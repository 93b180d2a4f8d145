//! Any bag, ROS 1 or ROS 2, as one source of messages: its topics (connections), its messages
//! in storage order, and its summary. [`open`] tells the kinds apart by their first bytes
//! (a folder is a ROS 2 bag), so that `slamkit bag info` and the readers built on bags
//! ([`super::scans`]) need not know which kind they read.

use super::connection::Connection;
use super::info::{bag_info, BagInfo};
use super::reader::ReadStats;
use super::reader::{count_by_connection, Bag, Connections, IndexState, MessageRecord, Order};
use super::ros2::Ros2Bag;
use super::BagError;
use std::io::{Read, Seek};
use std::path::Path;

/// A bag read message by message.
pub trait MessageSource {
    /// The bag's name in errors (its path).
    fn bag_name(&self) -> &str;
    /// Its connections (complete after [`MessageSource::find_connections`]).
    fn topics(&self) -> &Connections;
    /// The state of its index.
    fn index(&self) -> &IndexState;
    /// Makes [`MessageSource::topics`] complete (walks a bag without a usable index once).
    fn find_connections(&mut self) -> Result<(), BagError>;
    /// Every message in storage order (the order written), with its connection.
    fn read_stored(
        &mut self,
        visit: &mut dyn FnMut(&Connection, &MessageRecord),
    ) -> Result<ReadStats, BagError>;
    /// Topics, types, counts and time span.
    fn summary(&mut self) -> Result<BagInfo, BagError>;
}

impl<R: Read + Seek> MessageSource for Bag<R> {
    fn bag_name(&self) -> &str {
        self.name()
    }

    fn topics(&self) -> &Connections {
        self.connections()
    }

    fn index(&self) -> &IndexState {
        self.index_state()
    }

    fn find_connections(&mut self) -> Result<(), BagError> {
        if self.connections().is_empty() {
            count_by_connection(self)?;
        }
        Ok(())
    }

    fn read_stored(
        &mut self,
        visit: &mut dyn FnMut(&Connection, &MessageRecord),
    ) -> Result<ReadStats, BagError> {
        self.read_messages(Order::Storage, visit)
    }

    fn summary(&mut self) -> Result<BagInfo, BagError> {
        bag_info(self)
    }
}

/// Opens the bag at `path`: a ROS 1 `.bag`, a ROS 2 bag folder (`metadata.yaml` and its
/// storage files), or one ROS 2 storage file (`.mcap`, `.db3`).
///
/// ```
/// let dir = std::env::temp_dir().join(format!("slamkit_open_{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// let err = slamkit_io::bag::open(&dir).err().unwrap();
/// assert!(err.to_string().contains("no .mcap or .db3"), "{err}");
/// std::fs::remove_dir(&dir)?;
/// # Ok::<(), std::io::Error>(())
/// ```
pub fn open(path: &Path) -> Result<Box<dyn MessageSource>, BagError> {
    if path.is_dir() {
        return Ok(Box::new(Ros2Bag::open(path)?));
    }
    let name = path.display().to_string();
    let mut head = [0u8; 16];
    let got = std::fs::File::open(path)
        .and_then(|f| f.take(16).read(&mut head))
        .map_err(|error| BagError::Open {
            file: name.clone(),
            error,
        })?;
    if head[..got].starts_with(b"\x89MCAP") || head[..got].starts_with(b"SQLite format 3\0") {
        Ok(Box::new(Ros2Bag::open(path)?))
    } else {
        Ok(Box::new(Bag::open(path)?))
    }
}
