//! [`StoreFile`]: a robot's keyframes and edges messages on disk, so that a robot process
//! killed and started again serves every message it had sent and goes on from its next
//! sequence number: a crash loses at most the updates not yet sent.
//!
//! The file is the messages' bytes one after the other, each after its length (`u32`,
//! little-endian). Each is appended and synced before it is published. A record cut short by a
//! crash while it was written is dropped when the file is opened again.

use crate::FleetError;
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// An append-only file of messages.
#[derive(Debug)]
pub struct StoreFile {
    path: PathBuf,
    file: File,
}

impl StoreFile {
    /// Opens (or creates) the store at `path`; returns it and the messages it holds, in order.
    /// A record cut short at the end is dropped from the file.
    ///
    /// ```
    /// use slamkit_fleet::store::StoreFile;
    /// let dir = tempfile::tempdir()?;
    /// let path = dir.path().join("updates.skmu");
    /// let (mut store, held) = StoreFile::open(&path)?;
    /// assert!(held.is_empty());
    /// store.append(b"first")?;
    /// store.append(b"second")?;
    /// drop(store);
    /// let (_, held) = StoreFile::open(&path)?;
    /// assert_eq!(held, [b"first".to_vec(), b"second".to_vec()]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`FleetError::Store`] when the file cannot be opened, read or cut.
    pub fn open(path: &Path) -> Result<(Self, Vec<Vec<u8>>), FleetError> {
        let fail = |source| FleetError::Store {
            path: path.to_path_buf(),
            source,
        };
        let mut file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .write(true)
            .open(path)
            .map_err(fail)?;
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).map_err(fail)?;
        let mut messages = Vec::new();
        let mut at = 0;
        while let Some(len) = bytes.get(at..at + 4) {
            let len = u32::from_le_bytes([len[0], len[1], len[2], len[3]]) as usize;
            let Some(message) = bytes.get(at + 4..at + 4 + len) else {
                break;
            };
            messages.push(message.to_vec());
            at += 4 + len;
        }
        if at < bytes.len() {
            file.set_len(at as u64).map_err(fail)?;
        }
        file.seek(SeekFrom::End(0)).map_err(fail)?;
        Ok((
            Self {
                path: path.to_path_buf(),
                file,
            },
            messages,
        ))
    }

    /// Appends one message and syncs it to the disk.
    ///
    /// # Errors
    /// [`FleetError::Store`] when it cannot be written (a message longer than 4 GiB is refused
    /// as an [`std::io::ErrorKind::InvalidInput`]).
    pub fn append(&mut self, message: &[u8]) -> Result<(), FleetError> {
        let fail = |source| FleetError::Store {
            path: self.path.clone(),
            source,
        };
        let len = u32::try_from(message.len()).map_err(|_| {
            fail(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "a message longer than 4 GiB",
            ))
        })?;
        let mut record = Vec::with_capacity(4 + message.len());
        record.extend_from_slice(&len.to_le_bytes());
        record.extend_from_slice(message);
        self.file.write_all(&record).map_err(fail)?;
        self.file.sync_data().map_err(fail)
    }

    /// Where it is.
    pub fn path(&self) -> &Path {
        &self.path
    }
}
