//! A map file as files people and other tools read (`slamkit map export`), for every rig:
//!
//! | rig | files |
//! |---|---|
//! | 2D lidar | `map.pgm/.yaml/.png` (the keyframe scans' grid), `cloud.ply`, `trajectory.tum` |
//! | drone | `map.pgm/.yaml/.png` (every layer's keyframes in one grid), `cloud.ply` (points at their layer's middle height), `trajectory.tum` (keyframes) |
//! | RGB-D, stereo | `cloud.ply` (keyframe points in the map frame), `trajectory.tum` (keyframes); `map.pgm/.yaml/.png` when a ground robot saved its floor grid |
//!
//! Grids go out as ROS `map_server` maps ([`slamkit_map::grid_io`]), clouds as ASCII PLY,
//! poses as TUM trajectories (`timestamp tx ty tz qx qy qz qw`).

use super::MapFileError;
use super::{MapFile, Rig};
use crate::drone::map::DroneMap;
use crate::ground_robot::map::floor_grid;
use crate::lidar::LidarMap;
use crate::visual::keyframes::VisualMap;
use crate::SlamError;
use nalgebra::Point3;
use slamkit_core::{Pose3, Trajectory};
use slamkit_io::ply::write_ply;
use slamkit_io::trajectory_file::write_tum;
use slamkit_map::grid_io::{save_image_png, save_image_yaml, tri_grid_image};
use slamkit_map::{OccupancyGridConfig, TriGrid};
use std::path::Path;

/// What [`export`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Exported {
    /// The files written, by name, in `dir`.
    pub files: Vec<&'static str>,
    /// Points in `cloud.ply`.
    pub cloud_points: usize,
}

/// Writes `file`'s map, read from `source` (named in errors and in the PLY header), into the
/// folder `dir`, which must exist.
///
/// # Errors
/// [`SlamError::MapFile`] for a map whose sections cannot be decoded, [`SlamError::Grid`] for
/// a map larger than a grid may be, and the writers' errors.
pub fn export(file: &MapFile, source: &Path, dir: &Path) -> Result<Exported, SlamError> {
    let decode = decode_error(source);
    let (cloud, trajectory) = match file.header.rig {
        Rig::Lidar2d => {
            let map = LidarMap::from_file(file).map_err(decode)?;
            (map.cloud(), map.trajectory())
        }
        Rig::Drone => {
            let map = DroneMap::from_file(file).map_err(decode)?;
            (map.cloud(), map.trajectory())
        }
        rig @ (Rig::Rgbd | Rig::Stereo) => {
            visual_cloud(&VisualMap::from_map_file(file, rig).map_err(decode)?)
        }
    };
    let mut files = Vec::new();
    if let Some(grid) = planning_grid(file, source)? {
        let image = tri_grid_image(&grid);
        save_image_yaml(&image, grid.resolution_m(), &dir.join("map.yaml"))?;
        save_image_png(image, &dir.join("map.png"))?;
        files.extend(["map.pgm", "map.yaml", "map.png"]);
    }
    let comment = format!("slamkit map export of {}", source.display());
    write_ply(&dir.join("cloud.ply"), &cloud, &comment)?;
    write_tum(&dir.join("trajectory.tum"), &trajectory)?;
    files.extend(["cloud.ply", "trajectory.tum"]);
    Ok(Exported {
        files,
        cloud_points: cloud.len(),
    })
}

/// The grid a robot plans in on `file`'s map (read from `source`, named in errors): for 2D
/// lidar and drone maps the known part of the keyframe scans' grid, for a ground robot's RGB-D
/// map the floor grid it saved; `None` for a camera's map without one.
///
/// # Errors
/// [`SlamError::MapFile`] for sections that cannot be decoded, [`SlamError::Grid`] for a map
/// larger than a grid may be.
pub fn planning_grid(file: &MapFile, source: &Path) -> Result<Option<TriGrid>, SlamError> {
    let decode = decode_error(source);
    let config = OccupancyGridConfig::default();
    let grid = match file.header.rig {
        Rig::Lidar2d => LidarMap::from_file(file).map_err(decode)?.grid(config)?,
        Rig::Drone => DroneMap::from_file(file).map_err(decode)?.grid(config)?,
        Rig::Rgbd => return floor_grid(file).map_err(decode),
        Rig::Stereo => return Ok(None),
    };
    Ok(Some(TriGrid::from_occupancy_grid(&grid)))
}

/// The grid to plan in from the map file at `path`: a `.skmap` ([`planning_grid`]) or a ROS
/// map_server YAML (its known part), as `slamkit plan --map` takes them.
///
/// # Errors
/// As [`MapFile::load`] and [`planning_grid`]; [`SlamError::Map`] for a camera's map without
/// a grid; [`SlamError::GridFile`] for a YAML map that cannot be read.
pub fn load_planning_grid(path: &Path) -> Result<TriGrid, SlamError> {
    if !super::is_skmap(path) {
        let grid = slamkit_map::load_map_yaml(path)?;
        return Ok(TriGrid::from_occupancy_grid(&grid));
    }
    let file = MapFile::load(path).map_err(decode_error(path))?;
    planning_grid(&file, path)?.ok_or_else(|| {
        SlamError::Map(format!(
            "a {} map without a grid to plan on",
            file.header.rig
        ))
    })
}

fn decode_error(source: &Path) -> impl Fn(MapFileError) -> SlamError + '_ {
    move |e| SlamError::MapFile {
        path: source.to_path_buf(),
        source: e,
    }
}

/// Every keyframe's points in the map frame, and the keyframes' poses.
fn visual_cloud(map: &VisualMap) -> (Vec<Point3<f64>>, Trajectory) {
    let mut cloud = Vec::new();
    let mut trajectory = Trajectory::new();
    for k in &map.keyframes {
        let map_from_camera: &Pose3 = &k.pose;
        cloud.extend(k.points.iter().map(|(p, _)| map_from_camera * p));
        trajectory.push(k.timestamp, k.pose);
    }
    (cloud, trajectory)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ground_robot::map::floor_section;
    use crate::visual::keyframes::Keyframe;
    use nalgebra::{Point2, Translation3, UnitQuaternion};
    use slamkit_map::{Occupancy, TriGrid};

    #[test]
    fn a_visual_map_exports_its_points_in_the_map_frame_and_its_floor_grid() {
        let pose = Pose3::from_parts(
            Translation3::new(1.0, 2.0, 0.5),
            UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        );
        let map = VisualMap {
            keyframes: vec![Keyframe {
                timestamp: 3.0,
                pose,
                points: vec![(Point3::new(1.0, 0.0, 0.0), None)],
            }],
        };
        let mut file = map.to_map_file(Rig::Rgbd).unwrap();
        let grid = TriGrid::new(4, 2, 0.5, Point2::new(-1.0, -1.0), Occupancy::Free).unwrap();
        file.sections.push(floor_section(&grid).unwrap());
        let dir = std::env::temp_dir().join(format!("skmap-export-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let exported = export(&file, Path::new("test.skmap"), &dir).unwrap();
        assert_eq!(exported.cloud_points, 1);
        assert_eq!(
            exported.files,
            [
                "map.pgm",
                "map.yaml",
                "map.png",
                "cloud.ply",
                "trajectory.tum"
            ]
        );
        let ply = std::fs::read_to_string(dir.join("cloud.ply")).unwrap();
        // (1, 0, 0) turned a quarter about z is (0, 1, 0), then moved by (1, 2, 0.5)
        let vertex = ply.lines().last().unwrap();
        let xyz: Vec<f64> = vertex
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect();
        assert!(
            (xyz[0] - 1.0).abs() < 1e-6 && (xyz[1] - 3.0).abs() < 1e-6,
            "{vertex}"
        );
        let yaml = std::fs::read_to_string(dir.join("map.yaml")).unwrap();
        assert!(yaml.contains("resolution: 0.5"), "{yaml}");
        let pgm = std::fs::read(dir.join("map.pgm")).unwrap();
        assert!(pgm.ends_with(&[254; 8]));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
