//! Nearest-neighbour search over 2D points, keeping the points (and optional surface normals)
//! beside the index, so matchers get geometry back rather than bare indices: [`PointIndex`], a
//! thin wrapper over kiddo's immutable k-d tree (unbounded queries), and [`GridIndex`], a
//! uniform grid that answers the radius-bounded queries of ICP and the k-nearest queries of
//! the normals faster. ICP takes either through [`NearestNeighbours`].

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Point2, UnitComplex, Vector2};
use std::collections::HashSet;

pub mod grid;
pub use grid::GridIndex;

/// A point set with optional unit normals, indexed for the queries ICP makes.
pub trait NearestNeighbours {
    /// The nearest point to `query` at most `max_dist_m` away, or `None` when there is none or
    /// the query is not finite.
    fn nearest_within(&self, query: &Point2<f64>, max_dist_m: f64) -> Option<Neighbour>;

    /// [`NearestNeighbours::nearest_within`], and a clearance `c`: every indexed point other
    /// than the one returned (every point, when none is) is at least `c` from `query`. A query
    /// moved by `m` then has the same answer while the others stay farther than the nearest:
    /// see [`crate::icp`]'s correspondence cache. The default gives the clearance the answer
    /// alone implies.
    fn nearest_within_clear(
        &self,
        query: &Point2<f64>,
        max_dist_m: f64,
    ) -> (Option<Neighbour>, f64) {
        let nearest = self.nearest_within(query, max_dist_m);
        let usable = query.x.is_finite() && query.y.is_finite() && max_dist_m >= 0.0;
        let clear = match nearest {
            Some(n) => n.distance_m,
            None if usable => max_dist_m,
            None => 0.0,
        };
        (nearest, clear)
    }

    /// The points, in the order given.
    fn points(&self) -> &[Point2<f64>];

    /// One normal per point (`None` where the surface has no clear direction).
    fn normals(&self) -> &[Option<Vector2<f64>>];

    /// Number of points.
    fn len(&self) -> usize {
        self.points().len()
    }

    /// True when there are no points.
    fn is_empty(&self) -> bool {
        self.points().is_empty()
    }

    /// Point `i`.
    fn point(&self, i: usize) -> Option<&Point2<f64>> {
        self.points().get(i)
    }

    /// Unit normal of point `i`, when it has one.
    fn normal(&self, i: usize) -> Option<Vector2<f64>> {
        self.normals().get(i).copied().flatten()
    }
}

/// `normals` when there is one per point, else no normal anywhere.
fn normals_or_none(
    normals: Option<Vec<Option<Vector2<f64>>>>,
    points: usize,
) -> Vec<Option<Vector2<f64>>> {
    match normals {
        Some(n) if n.len() == points => n,
        _ => vec![None; points],
    }
}

impl NearestNeighbours for PointIndex {
    fn nearest_within(&self, query: &Point2<f64>, max_dist_m: f64) -> Option<Neighbour> {
        self.nearest(query).filter(|n| n.distance_m <= max_dist_m)
    }

    fn points(&self) -> &[Point2<f64>] {
        &self.points
    }

    fn normals(&self) -> &[Option<Vector2<f64>>] {
        &self.normals
    }
}

/// Points with optional unit normals, indexed for nearest-neighbour queries.
pub struct PointIndex {
    points: Vec<Point2<f64>>,
    normals: Vec<Option<Vector2<f64>>>,
    tree: Option<ImmutableKdTree<f64, 2>>,
    /// Index into `points` of each tree item.
    tree_items: Vec<usize>,
    /// The tree holds the points turned by this rotation (see [`PointIndex::new`]).
    tree_from_world: UnitComplex<f64>,
}

/// kiddo 4's immutable tree overflows a leaf (and panics) when more than its bucket size (32)
/// of items share one coordinate value; below half of that it has never failed in our tests.
const MAX_SHARED_COORDINATE: usize = 16;

/// Largest number of `coords` sharing one value on either axis.
fn max_shared_coordinate(coords: &[[f64; 2]]) -> usize {
    (0..2)
        .map(|axis| {
            let mut values: Vec<u64> = coords.iter().map(|c| c[axis].to_bits()).collect();
            values.sort_unstable();
            values
                .chunk_by(|a, b| a == b)
                .map(<[u64]>::len)
                .max()
                .unwrap_or(0)
        })
        .max()
        .unwrap_or(0)
}

/// One neighbour found by a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbour {
    /// Index of the point in the index.
    pub index: usize,
    /// Euclidean distance to the query \[m\].
    pub distance_m: f64,
}

impl PointIndex {
    /// Indexes `points`; `normals`, when given, must have one entry per point (`None` where the
    /// local surface has no clear direction). A length mismatch drops the normals.
    pub fn new(points: Vec<Point2<f64>>, normals: Option<Vec<Option<Vector2<f64>>>>) -> Self {
        let normals = normals_or_none(normals, points.len());
        // kiddo's immutable tree misbuilds on exact duplicates, and NaN has no place in it:
        // index each distinct finite position once.
        let mut seen = HashSet::with_capacity(points.len());
        let (tree_items, mut coords): (Vec<usize>, Vec<[f64; 2]>) = points
            .iter()
            .enumerate()
            .filter(|(_, p)| {
                p.x.is_finite() && p.y.is_finite() && seen.insert((p.x.to_bits(), p.y.to_bits()))
            })
            .map(|(i, p)| (i, [p.x, p.y]))
            .unzip();
        // Many points on one axis-aligned line (simulated or grid-snapped walls) share a
        // coordinate and would break the tree: index them turned by 1 rad instead, which breaks
        // the ties; input that still ties gets no tree (queries then find nothing).
        let mut tree_from_world = UnitComplex::identity();
        if max_shared_coordinate(&coords) > MAX_SHARED_COORDINATE {
            tree_from_world = UnitComplex::new(1.0);
            for c in &mut coords {
                let p = tree_from_world * Point2::new(c[0], c[1]);
                *c = [p.x, p.y];
            }
        }
        let buildable =
            !coords.is_empty() && max_shared_coordinate(&coords) <= MAX_SHARED_COORDINATE;
        let tree = buildable.then(|| ImmutableKdTree::new_from_slice(&coords));
        Self {
            points,
            normals,
            tree,
            tree_items,
            tree_from_world,
        }
    }

    /// `query` in the tree's frame, when finite.
    fn tree_query(&self, query: &Point2<f64>) -> Option<[f64; 2]> {
        let q = self.tree_from_world * query;
        (q.x.is_finite() && q.y.is_finite()).then_some([q.x, q.y])
    }

    /// The nearest indexed point to `query`, or `None` when the index is empty or the query is
    /// not finite.
    pub fn nearest(&self, query: &Point2<f64>) -> Option<Neighbour> {
        let q = self.tree_query(query)?;
        let tree = self.tree.as_ref()?;
        let nn = tree.nearest_one::<SquaredEuclidean>(&q);
        Some(Neighbour {
            index: self.item_index(nn.item)?,
            distance_m: nn.distance.sqrt(),
        })
    }

    fn item_index(&self, item: u64) -> Option<usize> {
        self.tree_items.get(usize::try_from(item).ok()?).copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Distance from `q` to the nearest of `pts`, by brute force.
    fn brute_nearest(pts: &[Point2<f64>], q: &Point2<f64>) -> f64 {
        pts.iter()
            .map(|p| (p - q).norm())
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn nearest_matches_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let pts: Vec<Point2<f64>> = (0..500)
            .map(|_| Point2::new(rng.gen_range(-10.0..10.0), rng.gen_range(-10.0..10.0)))
            .collect();
        let index = PointIndex::new(pts.clone(), None);
        for _ in 0..200 {
            let q = Point2::new(rng.gen_range(-12.0..12.0), rng.gen_range(-12.0..12.0));
            let brute = brute_nearest(&pts, &q);
            let nn = index.nearest(&q).unwrap();
            assert!((nn.distance_m - brute).abs() < 1e-9);
        }
    }

    #[test]
    fn lattice_with_shared_coordinates_matches_brute_force() {
        let mut pts = Vec::new();
        for i in 0..60 {
            for j in 0..3 {
                pts.push(Point2::new(i as f64 * 0.05, j as f64));
                pts.push(Point2::new(j as f64, i as f64 * 0.05));
            }
        }
        let index = PointIndex::new(pts.clone(), None);
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        for _ in 0..300 {
            let q = Point2::new(rng.gen_range(-1.0..4.0), rng.gen_range(-1.0..4.0));
            let brute = brute_nearest(&pts, &q);
            assert!((index.nearest(&q).unwrap().distance_m - brute).abs() < 1e-9);
        }
    }

    #[test]
    fn long_axis_aligned_walls_are_indexed() {
        // 200 points on each of two axis-aligned walls: kiddo 4 panics on such ties unless the
        // index breaks them.
        let mut pts = Vec::new();
        for i in 0..200 {
            pts.push(Point2::new(6.0, -4.0 + i as f64 * 0.04));
            pts.push(Point2::new(-6.0 + i as f64 * 0.06, 4.0));
        }
        let index = PointIndex::new(pts.clone(), None);
        let q = Point2::new(5.5, 0.013);
        let brute = brute_nearest(&pts, &q);
        assert!((index.nearest(&q).unwrap().distance_m - brute).abs() < 1e-9);
    }

    #[test]
    fn empty_index_and_duplicates() {
        let empty = PointIndex::new(Vec::new(), None);
        assert!(empty.nearest(&Point2::origin()).is_none());
        let mut pts = vec![Point2::new(1.0, 1.0); 100];
        pts.push(Point2::new(f64::NAN, 0.0));
        let dup = PointIndex::new(pts, None);
        assert!((dup.nearest(&Point2::new(1.0, 2.0)).unwrap().distance_m - 1.0).abs() < 1e-12);
    }
}
