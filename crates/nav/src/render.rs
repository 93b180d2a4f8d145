//! Drawing a path on its grid, for `map.png`.

use nalgebra::Point2;
use slamkit_core::image::RgbImage;
use slamkit_map::{Occupancy, TriGrid};

/// Colour of free cells.
const FREE: [u8; 3] = [254, 254, 254];
/// Colour of occupied cells.
const OCCUPIED: [u8; 3] = [0, 0, 0];
/// Colour of unknown cells (map_server's 205).
const UNKNOWN: [u8; 3] = [205, 205, 205];
/// Colour of cells occupied only after inflation.
const INFLATED: [u8; 3] = [150, 150, 170];
/// Colour of the path.
const PATH: [u8; 3] = [220, 30, 30];

/// The grid as an image (row 0 at the top, the largest y), `original` cells shown occupied or
/// not and cells occupied only in `inflated` shaded, with the path's cells in red and the start
/// and goal as 3 × 3 green and blue squares. `original` and `inflated` must have the same size.
pub fn draw_path(original: &TriGrid, inflated: &TriGrid, cells: &[(usize, usize)]) -> RgbImage {
    let (w, h) = (original.width(), original.height());
    let mut image = RgbImage::filled(w, h, UNKNOWN);
    for y in 0..h {
        for x in 0..w {
            let colour = match (original.get(x, y), inflated.get(x, y)) {
                (Some(Occupancy::Occupied), _) => OCCUPIED,
                (_, Some(Occupancy::Occupied)) => INFLATED,
                (Some(Occupancy::Free), _) => FREE,
                _ => UNKNOWN,
            };
            put(&mut image, x, y, colour);
        }
    }
    for &(x, y) in cells {
        put(&mut image, x, y, PATH);
    }
    let ends = [
        (cells.first(), [30, 170, 30]),
        (cells.last(), [30, 60, 220]),
    ];
    for (end, colour) in ends {
        let Some(&(x, y)) = end else { continue };
        for dy in 0..3 {
            for dx in 0..3 {
                if let (Some(px), Some(py)) = ((x + dx).checked_sub(1), (y + dy).checked_sub(1)) {
                    put(&mut image, px, py, colour);
                }
            }
        }
    }
    image
}

/// Colours grid cell `(x, y)` (image row `h - 1 - y`); ignored outside.
fn put(image: &mut RgbImage, x: usize, y: usize, colour: [u8; 3]) {
    let h = image.height();
    if y < h {
        if let Some(p) = image.get_mut(x, h - 1 - y) {
            *p = colour;
        }
    }
}

/// The pixel `(column, row)` of `point_m` in an image drawn by [`draw_path`].
pub fn pixel_of(grid: &TriGrid, point_m: &Point2<f64>) -> Option<(usize, usize)> {
    let (x, y) = grid.cell_at(point_m)?;
    Some((x, grid.height() - 1 - y))
}

/// Colours the pixel of each of `points` (metres) in an image drawn by [`draw_path`] on
/// `grid`; points outside the grid are left out.
pub fn mark_points(
    image: &mut RgbImage,
    grid: &TriGrid,
    points: impl IntoIterator<Item = Point2<f64>>,
    colour: [u8; 3],
) {
    for p in points {
        if let Some((col, row)) = pixel_of(grid, &p) {
            if let Some(px) = image.get_mut(col, row) {
                *px = colour;
            }
        }
    }
}

/// `image` with each pixel grown into a `k` × `k` block, so that a small grid stays legible.
///
/// ```
/// use slamkit_core::image::RgbImage;
/// let mut image = RgbImage::filled(2, 1, [0, 0, 0]);
/// *image.get_mut(1, 0).unwrap() = [9, 9, 9];
/// let big = slamkit_nav::render::upscale(&image, 3);
/// assert_eq!((big.width(), big.height()), (6, 3));
/// assert_eq!(big.get(2, 2), Some(&[0, 0, 0]));
/// assert_eq!(big.get(3, 0), Some(&[9, 9, 9]));
/// ```
pub fn upscale(image: &RgbImage, k: usize) -> RgbImage {
    let mut out = RgbImage::filled(image.width() * k, image.height() * k, [0, 0, 0]);
    for y in 0..out.height() {
        for x in 0..out.width() {
            if let (Some(src), Some(dst)) = (image.get(x / k, y / k).copied(), out.get_mut(x, y)) {
                *dst = src;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn path_start_and_goal_are_drawn() {
        let mut g = TriGrid::new(10, 8, 0.1, Point2::origin(), Occupancy::Free).unwrap();
        g.set(5, 5, Occupancy::Occupied);
        let inflated = g.inflated(1);
        let cells = [(1, 1), (2, 2), (3, 3), (8, 3)];
        let image = draw_path(&g, &inflated, &cells);
        assert_eq!(image.get(5, 8 - 1 - 5), Some(&OCCUPIED));
        assert_eq!(image.get(4, 8 - 1 - 5), Some(&INFLATED));
        assert_eq!(image.get(3, 8 - 1 - 3), Some(&PATH));
        let (col, row) = pixel_of(&g, &Point2::new(0.15, 0.15)).unwrap();
        assert_eq!(image.get(col, row), Some(&[30, 170, 30]));
        assert_eq!(image.get(9, 0), Some(&FREE));
    }
}
