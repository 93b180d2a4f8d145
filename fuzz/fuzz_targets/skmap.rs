//! The `.skmap` reader on arbitrary bytes: never panics. The input is tried as it is (what a
//! corrupt file gives: nearly always refused at the magic or the checksum) and, to reach the
//! parsers behind those gates, as the body of a file with the right magic and checksum. A map
//! the 2D lidar reader accepts has finite, unit poses and writes back to a readable file; the
//! drone, visual and floor-grid readers, and the grid a planner takes, never panic either, and a
//! drone map read writes back to a readable file.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_slam::drone::map::DroneMap;
use slamkit_slam::ground_robot::map::floor_grid;
use slamkit_slam::lidar::LidarMap;
use slamkit_slam::map_file::export::planning_grid;
use slamkit_slam::map_file::{MapFile, Rig, MAGIC};
use slamkit_slam::visual::keyframes::VisualMap;

fuzz_target!(|data: &[u8]| {
    let _ = MapFile::from_bytes(data);
    let mut bytes = MAGIC.to_vec();
    bytes.extend_from_slice(data);
    let crc = crc32fast::hash(&bytes);
    bytes.extend_from_slice(&crc.to_le_bytes());
    let Ok(file) = MapFile::from_bytes(&bytes) else {
        return;
    };
    if let Ok(drone) = DroneMap::from_file(&file) {
        let back = drone.to_map_file().and_then(|f| f.to_bytes());
        assert!(matches!(back.as_deref().map(MapFile::from_bytes), Ok(Ok(_))));
    }
    let _ = VisualMap::from_map_file(&file, Rig::Rgbd);
    let _ = VisualMap::from_map_file(&file, Rig::Stereo);
    let _ = floor_grid(&file);
    // the grids are only built for small maps: a grid as large as a fuzzed extent asks is a
    // clear error (MapError::TooLarge) but slow to reach
    if data.len() < 4096 {
        let _ = planning_grid(&file, std::path::Path::new("fuzz.skmap"));
    }
    let Ok(map) = LidarMap::from_file(&file) else {
        return;
    };
    for kf in &map.keyframes {
        let p = kf.world_from_base;
        assert!(p.translation.vector.iter().all(|v| v.is_finite()));
        assert!((p.rotation.norm() - 1.0).abs() < 1e-6);
    }
    let again = map.to_file(file.header.clone()).and_then(|f| f.to_bytes());
    let back = again.as_deref().map(MapFile::from_bytes);
    assert!(matches!(back, Ok(Ok(_))), "a map read must write back readable");
});
