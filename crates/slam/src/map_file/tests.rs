use super::*;

fn sample() -> MapFile {
    let mut header = MapHeader::new(Rig::Lidar2d, 2, Some([-1.0, -2.0, 3.0, 4.0]));
    header.created_unix_s = 1_700_000_000;
    MapFile {
        header,
        sections: vec![
            Section {
                tag: *b"KEYF",
                data: (0..5000u32).flat_map(|i| (i % 97).to_le_bytes()).collect(),
            },
            Section {
                tag: *b"EDGE",
                data: vec![1, 2, 3],
            },
        ],
    }
}

#[test]
fn round_trip_is_identical() {
    let map = sample();
    let bytes = map.to_bytes().unwrap();
    let back = MapFile::from_bytes(&bytes).unwrap();
    assert_eq!(back, map);
    assert_eq!(back.to_bytes().unwrap(), bytes);
    assert!(
        bytes.len() < 20_000 / 2,
        "compressed: {} bytes",
        bytes.len()
    );
}

#[test]
fn every_truncation_is_a_clear_error() {
    let bytes = sample().to_bytes().unwrap();
    for n in 0..bytes.len() {
        let err = MapFile::from_bytes(&bytes[..n]).unwrap_err();
        let ok = matches!(
            err,
            MapFileError::NotAMap | MapFileError::TooShort(_) | MapFileError::Checksum { .. }
        );
        assert!(ok, "truncated to {n}: {err}");
    }
}

#[test]
fn every_bit_flip_is_caught() {
    let bytes = sample().to_bytes().unwrap();
    for i in 0..bytes.len() {
        for bit in [0, 3, 7] {
            let mut b = bytes.clone();
            b[i] ^= 1 << bit;
            assert!(
                MapFile::from_bytes(&b).is_err(),
                "flip at byte {i} bit {bit}"
            );
        }
    }
}

#[test]
fn newer_major_version_and_wrong_rig_are_refused() {
    let mut bytes = sample().to_bytes().unwrap();
    bytes[8] = 2;
    let err = MapFile::from_bytes(&bytes).unwrap_err();
    assert!(matches!(err, MapFileError::NewerVersion(2, 0, 1)), "{err}");
    assert!(err.to_string().contains("newer"));
    let map = sample();
    assert!(map.expect_rig(Rig::Lidar2d).is_ok());
    let err = map.expect_rig(Rig::Rgbd).unwrap_err();
    assert_eq!(
        err.to_string(),
        "the map was built for a lidar2d rig, not rgbd"
    );
    assert!(matches!(
        map.section(b"NOPE"),
        Err(MapFileError::MissingSection(_))
    ));
}

#[test]
fn a_valid_checksum_over_garbage_is_still_an_error() {
    // What a fuzzer finds once it learns the checksum: lengths that lie.
    let mut body = Vec::new();
    body.extend_from_slice(&MAGIC);
    body.extend_from_slice(&[1, 0, 0, 0]);
    body.extend_from_slice(&2u32.to_le_bytes());
    body.extend_from_slice(b"{}");
    body.extend_from_slice(&u32::MAX.to_le_bytes());
    let crc = crc32fast::hash(&body);
    body.extend_from_slice(&crc.to_le_bytes());
    let err = MapFile::from_bytes(&body).unwrap_err();
    assert!(matches!(err, MapFileError::Malformed(_)), "{err}");
}

#[test]
fn saving_replaces_the_file_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("map.skmap");
    std::fs::write(&path, b"old").unwrap();
    sample().save(&path).unwrap();
    assert_eq!(MapFile::load(&path).unwrap(), sample());
    let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(leftovers.len(), 1, "no temporary file left behind");
    let missing = dir.path().join("no/such/dir/map.skmap");
    assert!(matches!(sample().save(&missing), Err(MapFileError::Io(_))));
}

#[test]
fn creation_dates_are_utc_calendar_dates() {
    let mut header = MapHeader::new(Rig::Lidar2d, 0, None);
    for (unix_s, date) in [
        (0, "1970-01-01 00:00:00 UTC"),
        (951_782_400, "2000-02-29 00:00:00 UTC"),
        (1_795_680_786, "2026-11-26 08:13:06 UTC"),
    ] {
        header.created_unix_s = unix_s;
        assert_eq!(header.created_utc(), date);
    }
}
