//! Writing a run's output files so that a reader never sees half of one, and a folder never
//! mixes two runs.
//!
//! * [`write_atomically`]: one file through a temporary sibling and a rename; a crash leaves
//!   the old file or the whole new one.
//! * [`OutputFolder`]: a whole run's outputs. Every writer writes into a fresh staging folder
//!   inside the output folder ([`OutputFolder::path`]); [`OutputFolder::commit`] then renames
//!   each output into place (a rename within one file system is atomic) and removes the files
//!   of an earlier run that this one did not write again, among the names the caller owns.
//!   A run that fails before its commit leaves the earlier outputs as they were, and its
//!   staging folder is removed. A run killed outright leaves its staging folder
//!   (`.slamkit-staging-<pid>`), which the next run into that folder removes.

use crate::IoError;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Prefix of a staging folder's name.
const STAGING_PREFIX: &str = ".slamkit-staging-";

/// Writes `bytes` to `path` atomically: into a temporary file beside it, synced, then renamed
/// over `path`, so a reader (or a crash) sees the old file or the whole new one.
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("report.json");
/// slamkit_io::output_folder::write_atomically(&path, b"{}\n").unwrap();
/// assert_eq!(std::fs::read(&path).unwrap(), b"{}\n");
/// ```
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_via_temp(path, |tmp| {
        let mut file = std::fs::File::create(tmp)?;
        file.write_all(bytes)?;
        file.sync_all()
    })
}

/// Calls `write` with a temporary path beside `path` (a hidden name ending in the same file
/// name, so writers that choose a format by extension choose the same), then renames it over
/// `path`; on failure the temporary file is removed and `path` is untouched.
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("figure.svg");
/// slamkit_io::output_folder::write_via_temp(&path, |tmp| std::fs::write(tmp, "<svg/>")).unwrap();
/// assert_eq!(std::fs::read_to_string(&path).unwrap(), "<svg/>");
/// ```
pub fn write_via_temp<E: From<std::io::Error>>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), E> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let tmp = dir.join(format!(".tmp-{}-{name}", std::process::id()));
    let result = write(&tmp).and_then(|()| Ok(std::fs::rename(&tmp, path)?));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    } else if let Ok(d) = std::fs::File::open(&dir) {
        // The rename is durable once the folder is synced; not every platform allows opening
        // a folder, and the data is already safe, so a failure here is not an error.
        let _ = d.sync_all();
    }
    result
}

/// An output folder being written: outputs go to a staging folder until [`commit`](Self::commit).
///
/// ```
/// use slamkit_io::output_folder::OutputFolder;
/// let dir = tempfile::tempdir().unwrap();
/// std::fs::write(dir.path().join("old.csv"), "from an earlier run").unwrap();
/// let out = OutputFolder::create(dir.path(), &["new.csv", "old.csv"]).unwrap();
/// std::fs::write(out.path().join("new.csv"), "x").unwrap();
/// assert_eq!(out.commit().unwrap(), vec!["old.csv".to_string()]);
/// assert!(dir.path().join("new.csv").exists() && !dir.path().join("old.csv").exists());
/// ```
#[derive(Debug)]
pub struct OutputFolder {
    dir: PathBuf,
    staging: PathBuf,
    owned: &'static [&'static str],
    committed: bool,
}

impl OutputFolder {
    /// Checks that `dir` is a folder (or absent) where files can be written, creates it, and
    /// opens a fresh staging folder in it. `owned` names the files and folders (directly in
    /// `dir`) that the caller's runs write: those of an earlier run that this one does not
    /// write again are removed at the commit; nothing else in `dir` is touched.
    pub fn create(dir: &Path, owned: &'static [&'static str]) -> Result<Self, IoError> {
        if dir.exists() && !dir.is_dir() {
            return Err(IoError::invalid(
                dir.display(),
                "the output folder is a file",
            ));
        }
        std::fs::create_dir_all(dir).map_err(|e| IoError::io(dir, e))?;
        remove_stale_staging(dir);
        let staging = dir.join(format!("{STAGING_PREFIX}{}", std::process::id()));
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(|e| IoError::io(&staging, e))?;
        }
        std::fs::create_dir(&staging).map_err(|e| IoError::Invalid {
            file: dir.display().to_string(),
            message: format!("the output folder is not writable ({e})"),
        })?;
        Ok(Self {
            dir: dir.to_path_buf(),
            staging,
            owned,
            committed: false,
        })
    }

    /// Where to write the outputs until the commit.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// The output folder itself.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Moves every output into the folder (replacing files of the same name; a replaced
    /// sub-folder is removed first), then removes the owned files and folders of an earlier
    /// run that this run did not write. Returns the names removed, sorted.
    pub fn commit(mut self) -> Result<Vec<String>, IoError> {
        let mut written = Vec::new();
        let entries =
            std::fs::read_dir(&self.staging).map_err(|e| IoError::io(&self.staging, e))?;
        for entry in entries {
            let entry = entry.map_err(|e| IoError::io(&self.staging, e))?;
            let target = self.dir.join(entry.file_name());
            if entry.path().is_dir() && target.is_dir() {
                std::fs::remove_dir_all(&target).map_err(|e| IoError::io(&target, e))?;
            }
            std::fs::rename(entry.path(), &target).map_err(|e| IoError::io(&target, e))?;
            written.push(entry.file_name().to_string_lossy().into_owned());
        }
        let mut removed = Vec::new();
        for name in self
            .owned
            .iter()
            .filter(|n| !written.iter().any(|w| w == *n))
        {
            let path = self.dir.join(name);
            let result = if path.is_dir() {
                std::fs::remove_dir_all(&path)
            } else if path.exists() {
                std::fs::remove_file(&path)
            } else {
                continue;
            };
            result.map_err(|e| IoError::io(&path, e))?;
            removed.push(name.to_string());
        }
        removed.sort();
        std::fs::remove_dir(&self.staging).map_err(|e| IoError::io(&self.staging, e))?;
        self.committed = true;
        Ok(removed)
    }
}

impl Drop for OutputFolder {
    /// A run that ends without its commit leaves the folder as it was.
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

/// Removes the staging folders runs killed before their commit left in `dir`.
fn remove_stale_staging(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        if entry
            .file_name()
            .to_string_lossy()
            .starts_with(STAGING_PREFIX)
        {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn commit_replaces_outputs_removes_stale_owned_ones_and_keeps_the_users_files() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("report.json"), "old").unwrap();
        std::fs::write(d.join("trajectory_pf.tum"), "old").unwrap();
        std::fs::create_dir_all(d.join("maps")).unwrap();
        std::fs::write(d.join("maps/layer_007.png"), "old").unwrap();
        std::fs::write(d.join("notes.txt"), "the user's").unwrap();
        std::fs::create_dir(d.join(".slamkit-staging-1")).unwrap(); // a killed run's
        let owned = &["report.json", "trajectory_pf.tum", "maps", "map.png"];
        let out = OutputFolder::create(d, owned).unwrap();
        assert!(!d.join(".slamkit-staging-1").exists());
        std::fs::write(out.path().join("report.json"), "new").unwrap();
        std::fs::create_dir(out.path().join("maps")).unwrap();
        std::fs::write(out.path().join("maps/layer_000.png"), "new").unwrap();
        // Until the commit, the folder holds the earlier run's outputs.
        assert_eq!(
            std::fs::read_to_string(d.join("report.json")).unwrap(),
            "old"
        );
        let removed = out.commit().unwrap();
        assert_eq!(removed, vec!["trajectory_pf.tum".to_string()]);
        assert_eq!(names(d), ["maps", "notes.txt", "report.json"]);
        assert_eq!(names(&d.join("maps")), ["layer_000.png"]);
        assert_eq!(
            std::fs::read_to_string(d.join("report.json")).unwrap(),
            "new"
        );
    }

    #[test]
    fn a_run_without_commit_leaves_the_folder_as_it_was() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("path.csv"), "old").unwrap();
        {
            let out = OutputFolder::create(dir.path(), &["path.csv"]).unwrap();
            std::fs::write(out.path().join("path.csv"), "half").unwrap();
        }
        assert_eq!(names(dir.path()), ["path.csv"]);
        assert_eq!(
            std::fs::read_to_string(dir.path().join("path.csv")).unwrap(),
            "old"
        );
    }

    #[test]
    fn a_file_in_place_of_the_folder_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("out");
        std::fs::write(&file, "").unwrap();
        let err = OutputFolder::create(&file, &[]).unwrap_err().to_string();
        assert!(err.contains("out") && err.contains("is a file"), "{err}");
    }

    #[test]
    fn atomic_write_replaces_and_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.json");
        write_atomically(&path, b"1").unwrap();
        write_atomically(&path, b"2").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"2");
        assert_eq!(names(dir.path()), ["a.json"]);
    }
}
