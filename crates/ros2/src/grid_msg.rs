//! slamkit's occupancy grid as a ROS `nav_msgs/OccupancyGrid`: trinary (100 occupied, 0 free,
//! -1 unknown), as `slam_toolbox` publishes it and as `map_server` serves a map saved by
//! `map_saver`. The cells are those of the map slamkit writes (`map.pgm`,
//! [`slamkit_map::grid_io::trinary_image`]) with the rows in ROS order: row 0 at the origin
//! (the image's bottom row).

use crate::msgs::{Header, MapMetaData, OccupancyGrid, Pose, Time, Vector3};
use slamkit_map::grid_io::{trinary_image, TrinaryImage, FREE_PIXEL, OCCUPIED_PIXEL};

/// Value of an occupied cell.
pub const OCCUPIED: i8 = 100;
/// Value of a free cell.
pub const FREE: i8 = 0;
/// Value of an unknown cell.
pub const UNKNOWN: i8 = -1;

/// The known part of `grid` as a map message in `frame_id` at `stamp`.
pub fn occupancy_grid_msg(
    grid: &slamkit_map::OccupancyGrid,
    frame_id: &str,
    stamp: Time,
) -> OccupancyGrid {
    image_msg(&trinary_image(grid), grid.resolution_m(), frame_id, stamp)
}

/// A trinary image (top row first) as a map message.
///
/// ```
/// use nalgebra::Point2;
/// use slamkit_map::grid_io::TrinaryImage;
/// use slamkit_ros2::grid_msg::image_msg;
/// use slamkit_ros2::msgs::Time;
/// // top row: occupied, free; bottom row: unknown, free
/// let image = TrinaryImage { width: 2, height: 2, pixels: vec![0, 254, 205, 254],
///                            origin_m: Point2::new(-1.0, 2.0) };
/// let msg = image_msg(&image, 0.05, "map", Time::default());
/// assert_eq!(msg.data, [-1, 0, 100, 0]);
/// assert_eq!((msg.info.width, msg.info.height), (2, 2));
/// assert_eq!(msg.info.origin.position.x, -1.0);
/// ```
pub fn image_msg(
    image: &TrinaryImage,
    resolution_m: f64,
    frame_id: &str,
    stamp: Time,
) -> OccupancyGrid {
    let width = image.width as usize;
    let mut data = Vec::with_capacity(image.pixels.len());
    for row in image.pixels.chunks(width.max(1)).rev() {
        data.extend(row.iter().map(|&p| match p {
            OCCUPIED_PIXEL => OCCUPIED,
            FREE_PIXEL => FREE,
            _ => UNKNOWN,
        }));
    }
    OccupancyGrid {
        header: Header {
            stamp,
            frame_id: frame_id.to_string(),
        },
        info: MapMetaData {
            map_load_time: stamp,
            resolution: resolution_m as f32,
            width: image.width,
            height: image.height,
            origin: Pose {
                position: Vector3 {
                    x: image.origin_m.x,
                    y: image.origin_m.y,
                    z: 0.0,
                },
                ..Pose::default()
            },
        },
        data,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point2;
    use slamkit_map::occupancy_grid::CellIndex;
    use slamkit_map::{Occupancy, OccupancyGridConfig};

    #[test]
    fn cells_land_where_ros_puts_them() {
        let mut grid = slamkit_map::OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
        let res = grid.resolution_m();
        let a = grid.cell_at(&Point2::new(0.0, 0.0)).unwrap();
        let b = grid.cell_at(&Point2::new(3.0 * res, 2.0 * res)).unwrap();
        grid.set_log_odds(a, 2.0).unwrap();
        grid.set_log_odds(b, -2.0).unwrap();
        let msg = occupancy_grid_msg(&grid, "map", Time::default());
        let (w, h) = (msg.info.width as usize, msg.info.height as usize);
        assert_eq!((w, h), (4, 3));
        assert_eq!(msg.data.len(), w * h);
        // message cell (i, j) covers origin + [i, i+1)·res × [j, j+1)·res: each grid cell's
        // centre lands in the message cell that holds its value
        let at = |cell: CellIndex| {
            let c = grid.cell_center_m(cell);
            let r = f64::from(msg.info.resolution);
            let i = ((c.x - msg.info.origin.position.x) / r).floor() as usize;
            let j = ((c.y - msg.info.origin.position.y) / r).floor() as usize;
            msg.data[j * w + i]
        };
        assert_eq!(grid.occupancy(a), Some(Occupancy::Occupied));
        assert_eq!(at(a), OCCUPIED);
        assert_eq!(at(b), FREE);
        assert_eq!(
            at(CellIndex {
                x: a.x + 1,
                y: a.y + 1
            }),
            UNKNOWN
        );
    }
}
