//! Point clouds: the common currency between depth cameras, lidars, mappers and PLY files.
//!
//! A cloud is a plain list of points with optional per-point colours; it is frame-agnostic, so
//! whoever holds it names the frame (`cloud_camera`, `cloud_world`). Sensors produce NaN points
//! for missing returns; [`PointCloud::drop_non_finite`] removes them once, at the edge, so
//! downstream code can assume finite coordinates.

use crate::{GeometryError, Pose3};
use nalgebra::{Point3, Vector3};

/// Points with optional RGB colours, `colors[i]` belonging to `points[i]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    /// Positions \[m\].
    pub points: Vec<Point3<f64>>,
    /// One 8-bit RGB colour per point, when the sensor gives colour.
    pub colors: Option<Vec<[u8; 3]>>,
}

/// An axis-aligned box holding a set of points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundingBox {
    /// Smallest coordinate along each axis \[m\].
    pub min: Point3<f64>,
    /// Largest coordinate along each axis \[m\].
    pub max: Point3<f64>,
}

impl BoundingBox {
    /// Size along each axis \[m\].
    pub fn extent(&self) -> Vector3<f64> {
        self.max - self.min
    }

    /// Centre of the box.
    pub fn center(&self) -> Point3<f64> {
        nalgebra::center(&self.min, &self.max)
    }
}

impl PointCloud {
    /// A cloud without colours.
    pub fn new(points: Vec<Point3<f64>>) -> Self {
        Self {
            points,
            colors: None,
        }
    }

    /// A coloured cloud.
    ///
    /// # Errors
    /// [`GeometryError::LengthMismatch`] when there is not exactly one colour per point.
    pub fn with_colors(
        points: Vec<Point3<f64>>,
        colors: Vec<[u8; 3]>,
    ) -> Result<Self, GeometryError> {
        if points.len() != colors.len() {
            return Err(GeometryError::LengthMismatch {
                src: points.len(),
                dst: colors.len(),
            });
        }
        Ok(Self {
            points,
            colors: Some(colors),
        })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when there is no point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The cloud expressed in another frame: each point `p` becomes `target_from_source * p`.
    /// Colours are carried along.
    pub fn transformed(&self, target_from_source: &Pose3) -> PointCloud {
        PointCloud {
            points: self.points.iter().map(|p| target_from_source * p).collect(),
            colors: self.colors.clone(),
        }
    }

    /// Moves the cloud into another frame in place, without allocating.
    pub fn transform(&mut self, target_from_source: &Pose3) {
        for p in &mut self.points {
            *p = target_from_source * *p;
        }
    }

    /// The smallest axis-aligned box holding every finite point, or `None` when there is none.
    pub fn bounding_box(&self) -> Option<BoundingBox> {
        let mut finite = self.points.iter().filter(|p| is_finite(p));
        let first = *finite.next()?;
        let init = BoundingBox {
            min: first,
            max: first,
        };
        Some(finite.fold(init, |b, p| BoundingBox {
            min: b.min.inf(p),
            max: b.max.sup(p),
        }))
    }

    /// Removes every point with a NaN or infinite coordinate, and its colour; returns how many
    /// were removed.
    pub fn drop_non_finite(&mut self) -> usize {
        let keep: Vec<bool> = self.points.iter().map(is_finite).collect();
        let before = self.points.len();
        self.points.retain(is_finite);
        if let Some(colors) = &mut self.colors {
            *colors = colors
                .iter()
                .zip(&keep)
                .filter_map(|(c, &k)| k.then_some(*c))
                .collect();
        }
        before - self.points.len()
    }
}

fn is_finite(p: &Point3<f64>) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.z.is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;
    use nalgebra::UnitQuaternion;

    fn sample() -> PointCloud {
        let points = vec![
            Point3::new(1.0, 2.0, 3.0),
            Point3::new(f64::NAN, 0.0, 0.0),
            Point3::new(-1.0, 5.0, 0.5),
            Point3::new(0.0, f64::INFINITY, 0.0),
            Point3::new(0.0, -2.0, 4.0),
        ];
        let colors = vec![[1, 1, 1], [2, 2, 2], [3, 3, 3], [4, 4, 4], [5, 5, 5]];
        PointCloud::with_colors(points, colors).unwrap()
    }

    #[test]
    fn bounding_box_ignores_non_finite_points() {
        let b = sample().bounding_box().unwrap();
        assert_eq!(b.min, Point3::new(-1.0, -2.0, 0.5));
        assert_eq!(b.max, Point3::new(1.0, 5.0, 4.0));
        assert_eq!(b.extent(), Vector3::new(2.0, 7.0, 3.5));
        assert_eq!(b.center(), Point3::new(0.0, 1.5, 2.25));
        assert_eq!(PointCloud::default().bounding_box(), None);
        let only_nan = PointCloud::new(vec![Point3::new(f64::NAN, 0.0, 0.0)]);
        assert_eq!(only_nan.bounding_box(), None);
    }

    #[test]
    fn dropping_non_finite_points_keeps_colours_aligned() {
        let mut cloud = sample();
        assert_eq!(cloud.drop_non_finite(), 2);
        assert_eq!(cloud.len(), 3);
        assert_eq!(cloud.colors, Some(vec![[1, 1, 1], [3, 3, 3], [5, 5, 5]]));
        assert_eq!(cloud.points[1], Point3::new(-1.0, 5.0, 0.5));
        assert_eq!(cloud.drop_non_finite(), 0);
    }

    #[test]
    fn transform_moves_every_point() {
        let pose = Pose3::from_parts(
            Translation3::new(1.0, 0.0, -1.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        );
        let mut cloud =
            PointCloud::new(vec![Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 2.0, 3.0)]);
        let moved = cloud.transformed(&pose);
        cloud.transform(&pose);
        assert_eq!(moved, cloud);
        assert!((cloud.points[0] - Point3::new(1.0, 1.0, -1.0)).norm() < 1e-12);
        assert!((cloud.points[1] - Point3::new(-1.0, 0.0, 2.0)).norm() < 1e-12);
        assert!(!cloud.is_empty());
    }

    #[test]
    fn colours_must_match_points() {
        let result = PointCloud::with_colors(vec![Point3::origin()], vec![]);
        assert_eq!(
            result,
            Err(GeometryError::LengthMismatch { src: 1, dst: 0 })
        );
    }
}
