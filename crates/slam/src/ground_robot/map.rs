//! A ground robot's map file: the camera session's keyframes ([`crate::visual::keyframes`],
//! rig [`Rig::Rgbd`]) and the floor grid it planned on, so that `slamkit plan` and
//! `slamkit map export` can use the map another day.
//!
//! ```text
//! FGRD  f64 resolution [m], f64 origin x, y [m] (corner of cell (0, 0), world frame),
//!       u32 width, u32 height, then width × height cells row by row from y = 0:
//!       u8 0 free, 1 occupied, 2 unknown
//! ```
//!
//! The grid is stored, not rebuilt: the keyframes keep the 3D points VO tracked, not the
//! depth images whose rays cleared the free space.

use crate::map_file::codec::{Reader, Writer};
use crate::map_file::{MapFile, MapFileError, Rig, Section};
use nalgebra::Point2;
use slamkit_map::{Occupancy, TriGrid};

/// Tag of the floor grid section.
pub const FLOOR_TAG: [u8; 4] = *b"FGRD";

/// The floor grid section of `grid`.
pub fn floor_section(grid: &TriGrid) -> Result<Section, MapFileError> {
    let mut w = Writer::new();
    w.f64(grid.resolution_m());
    w.f64(grid.origin_m().x);
    w.f64(grid.origin_m().y);
    w.len(grid.width())?;
    w.len(grid.height())?;
    let cells: Vec<u8> = grid
        .cells()
        .iter()
        .map(|c| match c {
            Occupancy::Free => 0,
            Occupancy::Occupied => 1,
            Occupancy::Unknown => 2,
        })
        .collect();
    w.bytes(&cells);
    Ok(Section {
        tag: FLOOR_TAG,
        data: w.into_bytes(),
    })
}

/// The floor grid of a ground robot's map file; `None` when the file has none (a camera
/// session's map, not a ground robot's).
///
/// # Errors
/// [`MapFileError::WrongRig`] for a map of another rig than RGB-D, [`MapFileError::Malformed`]
/// for a section whose sizes or cells are not a grid.
///
/// ```
/// use nalgebra::Point2;
/// use slamkit_map::{Occupancy, TriGrid};
/// use slamkit_slam::ground_robot::map::{floor_grid, floor_section};
/// use slamkit_slam::map_file::{MapFile, MapHeader, Rig};
///
/// let mut grid = TriGrid::new(3, 2, 0.05, Point2::new(-1.0, 2.0), Occupancy::Unknown).unwrap();
/// grid.set(2, 1, Occupancy::Occupied);
/// grid.set(0, 0, Occupancy::Free);
/// let file = MapFile {
///     header: MapHeader::new(Rig::Rgbd, 0, None),
///     sections: vec![floor_section(&grid)?],
/// };
/// assert_eq!(floor_grid(&file)?, Some(grid));
/// # Ok::<(), slamkit_slam::map_file::MapFileError>(())
/// ```
pub fn floor_grid(file: &MapFile) -> Result<Option<TriGrid>, MapFileError> {
    file.expect_rig(Rig::Rgbd)?;
    let Some(section) = file.sections.iter().find(|s| s.tag == FLOOR_TAG) else {
        return Ok(None);
    };
    let mut r = Reader::new(&section.data, "the floor grid section");
    let [resolution_m, x, y] = [r.f64()?, r.f64()?, r.f64()?];
    let width = r.u32()? as usize;
    let height = r.len(width)?;
    let mut grid = TriGrid::new(
        width,
        height,
        resolution_m,
        Point2::new(x, y),
        Occupancy::Unknown,
    )
    .ok_or_else(|| {
        MapFileError::Malformed(format!(
            "the floor grid is {width} × {height} cells of {resolution_m} m"
        ))
    })?;
    let cells = r.take(width * height)?;
    for (i, &cell) in cells.iter().enumerate() {
        let state = match cell {
            0 => Occupancy::Free,
            1 => Occupancy::Occupied,
            2 => continue,
            other => {
                return Err(MapFileError::Malformed(format!(
                    "a floor grid cell holds {other} (0 free, 1 occupied, 2 unknown)"
                )))
            }
        };
        grid.set(i % width, i / width, state);
    }
    r.finish()?;
    Ok(Some(grid))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map_file::MapHeader;

    fn file_with(data: Vec<u8>) -> MapFile {
        MapFile {
            header: MapHeader::new(Rig::Rgbd, 0, None),
            sections: vec![Section {
                tag: FLOOR_TAG,
                data,
            }],
        }
    }

    #[test]
    fn damaged_sections_are_errors_and_other_rigs_are_refused() {
        let grid = TriGrid::new(4, 3, 0.1, Point2::origin(), Occupancy::Free).unwrap();
        let good = floor_section(&grid).unwrap().data;
        assert_eq!(floor_grid(&file_with(good.clone())).unwrap(), Some(grid));
        // one cell short, one cell too many, a cell value out of range, a zero width
        assert!(floor_grid(&file_with(good[..good.len() - 1].to_vec())).is_err());
        assert!(floor_grid(&file_with([good.clone(), vec![0]].concat())).is_err());
        let mut bad = good.clone();
        *bad.last_mut().unwrap() = 7;
        assert!(floor_grid(&file_with(bad)).is_err());
        let mut zero = good;
        zero[24..28].copy_from_slice(&0u32.to_le_bytes());
        assert!(floor_grid(&file_with(zero)).is_err());
        let mut lidar = file_with(Vec::new());
        lidar.header.rig = Rig::Lidar2d;
        assert!(matches!(
            floor_grid(&lidar),
            Err(MapFileError::WrongRig { .. })
        ));
        lidar.header.rig = Rig::Rgbd;
        lidar.sections.clear();
        assert_eq!(floor_grid(&lidar).unwrap(), None);
    }
}
