//! Minimum spacing between features: whether a pixel lies closer than a given distance to one
//! of a growing set of pixels, answered from a grid of cells as wide as that distance (only
//! the 3×3 cells around the pixel can hold such a neighbour) instead of against every pixel
//! of the set — the grid OpenCV's `goodFeaturesToTrack` uses for its minimum distance.

use nalgebra::Point2;

/// Marks "no pixel" in the cell lists.
const NONE: u32 = u32::MAX;

/// A set of pixels bucketed into square cells of the minimum distance.
#[derive(Debug, Clone)]
pub struct SpacingGrid {
    min_distance_sq: f64,
    cell: f64,
    cols: usize,
    rows: usize,
    /// First pixel of each cell's list (index into `pixels`).
    heads: Vec<u32>,
    /// The pixels, each with the next pixel of its cell.
    pixels: Vec<(Point2<f64>, u32)>,
}

impl SpacingGrid {
    /// An empty set for an image of `width` × `height` pixels (pixels outside it fall into the
    /// border cells); distances below `min_distance` \[px\] count as near.
    pub fn new(min_distance: f64, width: usize, height: usize) -> Self {
        let cell = min_distance.max(1.0);
        let cols = (width as f64 / cell).ceil().max(1.0) as usize;
        let rows = (height as f64 / cell).ceil().max(1.0) as usize;
        Self {
            min_distance_sq: min_distance * min_distance,
            cell,
            cols,
            rows,
            heads: vec![NONE; cols * rows],
            pixels: Vec::new(),
        }
    }

    /// The cell of `px`, clamped into the grid.
    fn cell_of(&self, px: &Point2<f64>) -> (usize, usize) {
        let clamp = |v: f64, n: usize| ((v / self.cell).floor().max(0.0) as usize).min(n - 1);
        (clamp(px.x, self.cols), clamp(px.y, self.rows))
    }

    /// Adds `px` to the set.
    pub fn insert(&mut self, px: Point2<f64>) {
        let (cx, cy) = self.cell_of(&px);
        let Ok(index) = u32::try_from(self.pixels.len()) else {
            return;
        };
        if let Some(head) = self.heads.get_mut(cy * self.cols + cx) {
            self.pixels.push((px, *head));
            *head = index;
        }
    }

    /// Whether `px` is closer than the minimum distance to a pixel of the set.
    pub fn is_near(&self, px: &Point2<f64>) -> bool {
        let (cx, cy) = self.cell_of(px);
        for y in cy.saturating_sub(1)..=(cy + 1).min(self.rows - 1) {
            for x in cx.saturating_sub(1)..=(cx + 1).min(self.cols - 1) {
                let mut next = self.heads.get(y * self.cols + x).copied().unwrap_or(NONE);
                while let Some(&(p, after)) = self.pixels.get(next as usize) {
                    if (p - px).norm_squared() < self.min_distance_sq {
                        return true;
                    }
                    next = after;
                }
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn agrees_with_checking_every_pixel() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let d = 10.0;
        let mut grid = SpacingGrid::new(d, 64, 48);
        let mut all: Vec<Point2<f64>> = Vec::new();
        let (mut near, mut far) = (0, 0);
        for _ in 0..3000 {
            // some pixels outside the image, as KLT tracks can be
            let px = Point2::new(rng.gen_range(-15.0..80.0), rng.gen_range(-15.0..60.0));
            let want = all.iter().any(|g| (g - px).norm_squared() < d * d);
            assert_eq!(grid.is_near(&px), want, "at {px}");
            if want {
                near += 1;
            } else {
                far += 1;
                grid.insert(px);
                all.push(px);
            }
        }
        assert!(near > 100 && far > 20, "{near} near, {far} far");
    }

    #[test]
    fn exactly_the_minimum_distance_is_not_near() {
        let mut grid = SpacingGrid::new(10.0, 100, 100);
        grid.insert(Point2::new(50.0, 50.0));
        assert!(!grid.is_near(&Point2::new(60.0, 50.0)));
        assert!(grid.is_near(&Point2::new(59.99, 50.0)));
        assert!(!grid.is_near(&Point2::new(f64::NAN, 50.0)));
    }
}
