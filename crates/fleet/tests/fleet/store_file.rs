//! [`StoreFile`]: a robot's sent messages on disk survive a crash in the middle of a write.

use slamkit_fleet::store::StoreFile;
use std::path::Path;

#[test]
fn a_record_cut_short_is_dropped_and_the_file_goes_on_after_the_last_whole_one() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s");
    let (mut store, _) = StoreFile::open(&path).unwrap();
    store.append(b"one").unwrap();
    store.append(b"two").unwrap();
    drop(store);
    // a crash in the middle of the third record
    let mut bytes = std::fs::read(&path).unwrap();
    bytes.extend_from_slice(&5u32.to_le_bytes());
    bytes.extend_from_slice(b"thr");
    std::fs::write(&path, &bytes).unwrap();
    let (mut store, held) = StoreFile::open(&path).unwrap();
    assert_eq!(held, [b"one".to_vec(), b"two".to_vec()]);
    store.append(b"three").unwrap();
    drop(store);
    let (_, held) = StoreFile::open(&path).unwrap();
    assert_eq!(held.len(), 3);
    assert_eq!(held[2], b"three");
}

#[test]
fn a_missing_folder_is_a_store_error_naming_the_file() {
    let err = StoreFile::open(Path::new("/nonexistent-dir/x.skmu")).unwrap_err();
    assert!(err.to_string().contains("/nonexistent-dir/x.skmu"), "{err}");
}
