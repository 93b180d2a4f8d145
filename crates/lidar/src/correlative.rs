//! Correlative scan matching (Olson, "Real-time correlative scan matching", ICRA 2009), with the
//! exact branch and bound of Hess et al., "Real-time loop closure in 2D LIDAR SLAM", ICRA 2016,
//! cut to two levels.
//!
//! The target points are rasterised into a likelihood field (each cell holds
//! `exp(−d²/2σ²)` for the distance `d` to the nearest target point). Every pose in a window
//! around the initial guess — rotations at the step where the farthest point moves by about
//! one cell, translations at one cell — is scored by the mean field value under the moved source
//! points. Rather than scoring every pose, translations are grouped in `coarse_cells`² blocks
//! whose bound is read from a sliding-window maximum of the field; blocks are expanded best
//! bound first, and the search stops once no bound beats the best exact score found, so the
//! answer equals the exhaustive one. It needs no odometry, only a window large enough to hold
//! the true pose.

use crate::cloud::floor_i64;
use crate::error::check_fields;
use crate::LidarError;
use nalgebra::{Point2, Vector2};
use serde::{Deserialize, Serialize};
use slamkit_core::Pose2;

/// Correlative matcher parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CorrelativeConfig {
    /// Half-width of the translation window around the guess, in x and y \[m\].
    pub linear_window_m: f64,
    /// Half-width of the rotation window around the guess \[rad\].
    pub angular_window_rad: f64,
    /// Cell size of the likelihood field and translation step \[m\].
    pub resolution_m: f64,
    /// Standard deviation of the likelihood field around each target point \[m\].
    pub sigma_m: f64,
    /// Largest rotation step \[rad\]; the step is smaller when the scan reaches farther.
    pub max_angular_step_rad: f64,
    /// Side of the translation blocks bounded together, in cells (>= 1).
    pub coarse_cells: usize,
    /// Fewer source points than this is an error.
    pub min_points: usize,
}

impl Default for CorrelativeConfig {
    fn default() -> Self {
        Self {
            linear_window_m: 0.5,
            angular_window_rad: 20f64.to_radians(),
            resolution_m: 0.05,
            sigma_m: 0.05,
            max_angular_step_rad: 1f64.to_radians(),
            coarse_cells: 4,
            min_points: 10,
        }
    }
}

/// Best pose found by the search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrelativeResult {
    /// The pose of the source in the target frame.
    pub target_from_source: Pose2,
    /// Mean likelihood of the moved source points, in \[0, 1\].
    pub score: f64,
}

/// A likelihood field on the cells `[first.0, first.0 + width) × [first.1, first.1 + height)`
/// of the lattice of side `resolution_m` anchored at `origin`.
struct Field {
    origin: Point2<f64>,
    first: (i64, i64),
    resolution_m: f64,
    width: usize,
    height: usize,
    cells: Vec<f32>,
}

impl Field {
    /// The field of `points` on the lattice cells from `lo` to `hi` (inclusive).
    fn new(
        points: &[Point2<f64>],
        origin: &Point2<f64>,
        (lo, hi): ((i64, i64), (i64, i64)),
        res: f64,
        sigma: f64,
    ) -> Self {
        let span = |a: i64, b: i64| usize::try_from(b - a + 1).unwrap_or(0);
        let (width, height) = (span(lo.0, hi.0), span(lo.1, hi.1));
        let mut field = Self {
            origin: *origin,
            first: lo,
            resolution_m: res,
            width,
            height,
            cells: Vec::new(),
        };
        // The likelihood falls with distance, so each cell keeps the squared distance to its
        // nearest point and takes one exponential at the end.
        let mut nearest_sq = vec![f64::INFINITY; width * height];
        let reach = (3.0 * sigma / res).ceil() as i64;
        for p in points {
            let (ci, cj) = field.cell(p);
            let (i0, i1) = ((ci - reach).max(lo.0), (ci + reach).min(hi.0));
            let (j0, j1) = ((cj - reach).max(lo.1), (cj + reach).min(hi.1));
            for j in j0..=j1 {
                let dy = origin.y + (j as f64 + 0.5) * res - p.y;
                let Some(row) = field.offset(i0, j).and_then(|k| nearest_sq.get_mut(k..)) else {
                    continue;
                };
                for (i, d2) in (i0..=i1).zip(row) {
                    let dx = origin.x + (i as f64 + 0.5) * res - p.x;
                    let e = dx * dx + dy * dy;
                    *d2 = if e < *d2 { e } else { *d2 };
                }
            }
        }
        field.cells = nearest_sq
            .into_iter()
            .map(|d2| {
                if d2.is_finite() {
                    (-d2 / (2.0 * sigma * sigma)).exp() as f32
                } else {
                    0.0
                }
            })
            .collect();
        field
    }

    /// Lattice cell of `p` (see [`lattice_cell`]).
    fn cell(&self, p: &Point2<f64>) -> (i64, i64) {
        lattice_cell(&self.origin, self.resolution_m, p)
    }

    fn offset(&self, i: i64, j: i64) -> Option<usize> {
        let (i, j) = (i - self.first.0, j - self.first.1);
        let (i, j) = (usize::try_from(i).ok()?, usize::try_from(j).ok()?);
        (i < self.width && j < self.height).then_some(j * self.width + i)
    }

    fn value(&self, i: i64, j: i64) -> f64 {
        self.offset(i, j)
            .and_then(|k| self.cells.get(k))
            .map_or(0.0, |v| f64::from(*v))
    }

    /// Cell `(i, j)` of the result holds the maximum over cells `[i, i+w) × [j, j+w)`: a pass
    /// along rows, then one along columns. Field values are never NaN, so a plain comparison
    /// gives the maximum (and is much cheaper than NaN-aware `f32::max`).
    fn sliding_max(&self, w: usize) -> Self {
        let width = self.width.max(1);
        let w = w.max(1);
        let mut rows = vec![0.0f32; self.cells.len()];
        for (src, dst) in self.cells.chunks(width).zip(rows.chunks_mut(width)) {
            for (i, out) in dst.iter_mut().enumerate() {
                *out = window_max(src.get(i..(i + w).min(src.len())).unwrap_or_default());
            }
        }
        // Columns: running maximum of `w` consecutive rows.
        let mut cells = rows.clone();
        for j in 0..self.height {
            let Some(out) = cells.get_mut(j * width..(j + 1) * width) else {
                continue;
            };
            for jj in j + 1..(j + w).min(self.height) {
                let Some(next) = rows.get(jj * width..(jj + 1) * width) else {
                    continue;
                };
                for (o, v) in out.iter_mut().zip(next) {
                    *o = if *v > *o { *v } else { *o };
                }
            }
        }
        Self {
            cells,
            origin: self.origin,
            ..*self
        }
    }

    /// The cells from the corner of the footprint shifted by `(di, dj)`, when the shifted
    /// footprint lies inside the grid (the usual case): its cells are then read by offset from
    /// there, without per-cell range checks.
    fn window(&self, footprint: &Footprint, di: i64, dj: i64) -> Option<&[f32]> {
        let (w, h) = (self.width as i64, self.height as i64);
        let (i0, j0) = (
            footprint.min.0 + di - self.first.0,
            footprint.min.1 + dj - self.first.1,
        );
        let (i1, j1) = (
            footprint.max.0 + di - self.first.0,
            footprint.max.1 + dj - self.first.1,
        );
        let inside = i0 >= 0 && j0 >= 0 && i1 < w && j1 < h && footprint.width == w;
        let corner = usize::try_from(j0 * w + i0).ok()?;
        inside.then(|| self.cells.get(corner..)).flatten()
    }

    /// Sum of the field under the footprint's cells shifted by `(di, dj)`, in footprint order.
    fn score(&self, footprint: &Footprint, di: i64, dj: i64) -> f64 {
        match self.window(footprint, di, dj) {
            Some(window) => footprint
                .relative
                .iter()
                .map(|&k| window.get(k).map_or(0.0, |v| f64::from(*v)))
                .sum(),
            None => footprint
                .cells
                .iter()
                .map(|&(i, j)| self.value(i + di, j + dj))
                .sum(),
        }
    }

    /// [`Field::score`] at `(di, dj)` for each `dj` of `djs` (at most [`LANES`]; the rest of
    /// the result is 0). Each sum is taken in the same order, so the values are the same, but
    /// side by side: one sum alone is a chain of dependent additions, four overlap.
    fn score_lanes(&self, footprint: &Footprint, di: i64, djs: &[i64]) -> [f64; LANES] {
        let mut out = [0.0; LANES];
        let window = |dj: i64| self.window(footprint, di, dj);
        if let &[d0, d1, d2, d3] = djs {
            if let (Some(w0), Some(w1), Some(w2), Some(w3)) =
                (window(d0), window(d1), window(d2), window(d3))
            {
                let read = |w: &[f32], k: usize| w.get(k).map_or(0.0, |v| f64::from(*v));
                for &k in &footprint.relative {
                    out[0] += read(w0, k);
                    out[1] += read(w1, k);
                    out[2] += read(w2, k);
                    out[3] += read(w3, k);
                }
                return out;
            }
        }
        for (o, &dj) in out.iter_mut().zip(djs) {
            *o = self.score(footprint, di, dj);
        }
        out
    }

    /// [`Field::score`] at `(di + l, dj + r)` for each lane `l` and row `r` in `0..LANES`, in
    /// one pass over the footprint: each footprint cell's values for the `LANES` translations
    /// along a row lie side by side in memory (one load), and the `LANES`² sums are
    /// independent, so the additions overlap rather than wait on each other. Each sum is
    /// taken in footprint order, as [`Field::score`]'s. (Not inlined: inside the branch and
    /// bound's loop the compiler kept the sums in memory, each addition waiting on a store.)
    #[inline(never)]
    fn score_square(&self, footprint: &Footprint, di: i64, dj: i64) -> [[f64; LANES]; LANES] {
        let far = LANES as i64 - 1;
        let inside = (
            self.window(footprint, di, dj),
            self.window(footprint, di + far, dj + far),
        );
        let (Some(window), Some(_)) = inside else {
            return std::array::from_fn(|r| {
                std::array::from_fn(|l| self.score(footprint, di + l as i64, dj + r as i64))
            });
        };
        let mut sums = [[0.0; LANES]; LANES];
        for &k in &footprint.relative {
            for (r, row) in sums.iter_mut().enumerate() {
                let at = k + r * self.width;
                if let Some(&[v0, v1, v2, v3]) = window.get(at..at + LANES) {
                    row[0] += f64::from(v0);
                    row[1] += f64::from(v1);
                    row[2] += f64::from(v2);
                    row[3] += f64::from(v3);
                }
            }
        }
        sums
    }
}

/// Cell of `p` in the lattice of side `res` anchored at `origin`; far-off (or NaN) points map
/// to cells far outside any field, clamped so that offsets added later cannot overflow.
fn lattice_cell(origin: &Point2<f64>, res: f64, p: &Point2<f64>) -> (i64, i64) {
    let d = (p - origin) / res;
    let clamp = |v: f64| floor_i64(v.clamp(-1e9, 1e9));
    (clamp(d.x), clamp(d.y))
}

/// Translations scored together by [`Field::score_lanes`].
const LANES: usize = 4;

/// Largest of `values` (non-negative, never NaN), 0 for none.
fn window_max(values: &[f32]) -> f32 {
    values
        .iter()
        .fold(0.0, |m: f32, &v| if v > m { v } else { m })
}

/// The cells of the source points at one rotation, with their bounding box and their linear
/// offsets from its corner in a grid `width` cells wide.
struct Footprint {
    cells: Vec<(i64, i64)>,
    relative: Vec<usize>,
    width: i64,
    min: (i64, i64),
    max: (i64, i64),
}

impl Footprint {
    fn new(cells: Vec<(i64, i64)>, width: usize) -> Self {
        let width = width as i64;
        let fold = |init: (i64, i64), f: fn(i64, i64) -> i64| {
            cells
                .iter()
                .fold(init, |acc, &(i, j)| (f(acc.0, i), f(acc.1, j)))
        };
        let min = fold((i64::MAX, i64::MAX), i64::min);
        let max = fold((i64::MIN, i64::MIN), i64::max);
        let relative = cells
            .iter()
            .map(|&(i, j)| usize::try_from((j - min.1) * width + i - min.0).unwrap_or(usize::MAX))
            .collect();
        Self {
            cells,
            relative,
            width,
            min,
            max,
        }
    }
}

/// A block of translations at one rotation, with its upper bound.
struct Block {
    bound: f64,
    angle: usize,
    di: i64,
    dj: i64,
}

/// Finds the pose of `source` against `target` (both point sets) within the configured window
/// around `initial` (`target_from_source`).
pub fn correlative_match(
    source: &[Point2<f64>],
    target: &[Point2<f64>],
    initial: &Pose2,
    config: &CorrelativeConfig,
) -> Result<CorrelativeResult, LidarError> {
    let heading = [initial.rotation.angle()];
    let results = correlative_match_headings(
        source,
        target,
        &initial.translation.vector,
        &heading,
        config,
    )?;
    results.into_iter().next().ok_or(LidarError::TooFewPoints {
        got: source.len(),
        min: config.min_points.max(1),
    })
}

/// [`correlative_match`] from each of `headings` \[rad\] at one `translation`, one result per
/// heading: the likelihood field is built once for all of them (a global search tries four
/// headings at every place, and the field was a third of its time). Each result equals
/// [`correlative_match`]'s from `Pose2::new(translation, heading)` when `heading` is that
/// pose's own angle (in (−π, π]).
///
/// ```
/// use nalgebra::{Point2, Vector2};
/// use slamkit_core::Pose2;
/// use slamkit_lidar::correlative::{correlative_match, correlative_match_headings, CorrelativeConfig};
///
/// // an L-shaped corner seen from the origin, and the same scan turned by 0.1 rad
/// let target: Vec<Point2<f64>> = (0..40)
///     .map(|i| Point2::new(2.0, -1.0 + 0.05 * i as f64))
///     .chain((0..40).map(|i| Point2::new(0.05 * i as f64, 1.0)))
///     .collect();
/// let truth = Pose2::new(Vector2::new(0.1, 0.0), 0.1);
/// let source: Vec<Point2<f64>> = target.iter().map(|p| truth.inverse() * p).collect();
/// let config = CorrelativeConfig::default();
/// let guesses = [Pose2::identity(), Pose2::new(Vector2::zeros(), 0.3)];
/// let headings: Vec<f64> = guesses.iter().map(|g| g.rotation.angle()).collect();
/// let all = correlative_match_headings(&source, &target, &Vector2::zeros(), &headings, &config)?;
/// for (result, guess) in all.iter().zip(&guesses) {
///     assert_eq!(result, &correlative_match(&source, &target, guess, &config)?);
/// }
/// let err = truth.inverse() * all[0].target_from_source;
/// assert!(err.translation.vector.norm() < 0.05 && err.rotation.angle().abs() < 0.02);
/// # Ok::<(), slamkit_lidar::LidarError>(())
/// ```
pub fn correlative_match_headings(
    source: &[Point2<f64>],
    target: &[Point2<f64>],
    translation: &Vector2<f64>,
    headings: &[f64],
    config: &CorrelativeConfig,
) -> Result<Vec<CorrelativeResult>, LidarError> {
    validate(config)?;
    let res = config.resolution_m;
    let centre = Point2::from(*translation);
    let half = LikelihoodField::half_m_for_reach(reach(source), config);
    let origin = centre - Vector2::new(half, half);
    let side = (2.0 * half / res).ceil() as i64 + 1;
    let sweeps = Sweeps::new(source, translation, headings, &origin, config)?;
    let w = (config.linear_window_m / res).ceil() as i64;
    // Only the cells the shifted footprints (and the bound's windows beyond them) can read are
    // built: the same cells, with the same values, as the whole square around the guess.
    let (lo, hi) = sweeps
        .per_heading
        .iter()
        .flat_map(|(_, f)| f.iter().flatten())
        .fold(
            ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN)),
            |(lo, hi), &(i, j)| ((lo.0.min(i), lo.1.min(j)), (hi.0.max(i), hi.1.max(j))),
        );
    let reach_cells = w + config.coarse_cells.max(1) as i64 - 1;
    let lo = ((lo.0 - w).max(0), (lo.1 - w).max(0));
    let hi = (
        (hi.0 + reach_cells).min(side - 1),
        (hi.1 + reach_cells).min(side - 1),
    );
    let field = LikelihoodField::build(target, &origin, (lo, hi), config);
    Ok(field.best_per_heading(sweeps, translation, headings, source.len()))
}

/// Distance of the farthest of `points` from the origin.
fn reach(points: &[Point2<f64>]) -> f64 {
    points.iter().map(|p| p.coords.norm()).fold(0.0, f64::max)
}

/// Most cells a [`LikelihoodField::square`] may have (0.8 GB of cells): a larger square is a
/// mistake in its size, better reported than allocated.
const MAX_SQUARE_CELLS: f64 = 1e8;

/// A likelihood field of target points with the maxima the branch and bound reads, built once
/// and matched against many sources ([`LikelihoodField::match_headings`]). A map that does not
/// change between queries (the anchors of a global search) then builds its fields once rather
/// than at every query.
///
/// ```
/// use nalgebra::{Point2, Vector2};
/// use slamkit_core::Pose2;
/// use slamkit_lidar::correlative::{CorrelativeConfig, LikelihoodField};
///
/// // an L-shaped corner seen from the origin, and the same scan moved by 0.1 m and 0.1 rad
/// let target: Vec<Point2<f64>> = (0..40)
///     .map(|i| Point2::new(2.0, -1.0 + 0.05 * i as f64))
///     .chain((0..40).map(|i| Point2::new(0.05 * i as f64, 1.0)))
///     .collect();
/// let truth = Pose2::new(Vector2::new(0.1, 0.0), 0.1);
/// let source: Vec<Point2<f64>> = target.iter().map(|p| truth.inverse() * p).collect();
/// let config = CorrelativeConfig::default();
/// // sources reaching up to 3 m from the field's centre
/// let half = LikelihoodField::half_m_for_reach(3.0, &config);
/// let field = LikelihoodField::square(&target, &Vector2::zeros(), half, &config)?;
/// let best = field.match_headings(&source, &Vector2::zeros(), &[0.0])?;
/// let err = truth.inverse() * best[0].target_from_source;
/// assert!(err.translation.vector.norm() < 0.05 && err.rotation.angle().abs() < 0.02);
/// # Ok::<(), slamkit_lidar::LidarError>(())
/// ```
pub struct LikelihoodField {
    config: CorrelativeConfig,
    field: Field,
    bound: Field,
}

impl LikelihoodField {
    /// The half-side [`LikelihoodField::square`] needs for sources whose points reach up to
    /// `reach_m` from their own origin to be scored in full at every pose of `config`'s window:
    /// the window, the reach, the field's tail (4σ) and one cell for rounding.
    pub fn half_m_for_reach(reach_m: f64, config: &CorrelativeConfig) -> f64 {
        reach_m + config.linear_window_m + 4.0 * config.sigma_m + config.resolution_m
    }

    /// The field of `target` on the square of half-side `half_m` around `centre`, on the
    /// lattice of side `config.resolution_m` anchored at the square's corner, for matches with
    /// `config`'s windows. Cells beyond the square read as empty, so a source should reach no
    /// farther than [`LikelihoodField::half_m_for_reach`] allows.
    pub fn square(
        target: &[Point2<f64>],
        centre: &Vector2<f64>,
        half_m: f64,
        config: &CorrelativeConfig,
    ) -> Result<Self, LidarError> {
        validate(config)?;
        let side_f = (2.0 * half_m / config.resolution_m).ceil() + 1.0;
        check_fields(
            [(
                "half_m",
                half_m,
                half_m > 0.0 && side_f * side_f <= MAX_SQUARE_CELLS,
            )],
            "out of range (> 0, finite, at most 10⁸ cells of resolution_m)",
        )?;
        let origin = Point2::from(centre - Vector2::new(half_m, half_m));
        let side = side_f as i64;
        Ok(Self::build(
            target,
            &origin,
            ((0, 0), (side - 1, side - 1)),
            config,
        ))
    }

    /// The field of `target` on the lattice cells from `lo` to `hi` (inclusive), with its
    /// maxima over the branch and bound's blocks.
    fn build(
        target: &[Point2<f64>],
        origin: &Point2<f64>,
        cells: ((i64, i64), (i64, i64)),
        config: &CorrelativeConfig,
    ) -> Self {
        let field = Field::new(target, origin, cells, config.resolution_m, config.sigma_m);
        let bound = field.sliding_max(config.coarse_cells.max(1));
        Self {
            config: config.clone(),
            field,
            bound,
        }
    }

    /// Bytes the field's cells take (the field and its maxima).
    pub fn bytes(&self) -> usize {
        (self.field.cells.len() + self.bound.cells.len()) * std::mem::size_of::<f32>()
    }

    /// [`correlative_match_headings`] of `source` against this field: the best pose in the
    /// field's window around `translation` from each of `headings`, one result per heading.
    pub fn match_headings(
        &self,
        source: &[Point2<f64>],
        translation: &Vector2<f64>,
        headings: &[f64],
    ) -> Result<Vec<CorrelativeResult>, LidarError> {
        let sweeps = Sweeps::new(
            source,
            translation,
            headings,
            &self.field.origin,
            &self.config,
        )?;
        Ok(self.best_per_heading(sweeps, translation, headings, source.len()))
    }

    /// The branch and bound over each heading's sweep: its best pose and mean score.
    fn best_per_heading(
        &self,
        sweeps: Sweeps,
        translation: &Vector2<f64>,
        headings: &[f64],
        n_source: usize,
    ) -> Vec<CorrelativeResult> {
        let res = self.config.resolution_m;
        let coarse = self.config.coarse_cells.max(1);
        let w = (self.config.linear_window_m / res).ceil() as i64;
        let starts: Vec<i64> = (-w..=w).step_by(coarse).collect();
        let n_ang = sweeps.n_ang;
        sweeps
            .per_heading
            .into_iter()
            .zip(headings)
            .map(|((angles, footprints), &theta0)| {
                let rotated: Vec<Footprint> = footprints
                    .into_iter()
                    .map(|cells| Footprint::new(cells, self.field.width))
                    .collect();
                let blocks = bound_blocks(&self.bound, &rotated, &starts);
                let best = best_in_blocks(&self.field, &rotated, &blocks, coarse as i64, w, n_ang);
                let (score, angle, di, dj) = best;
                let theta = angles.get(angle).copied().unwrap_or(theta0);
                let t = translation + Vector2::new(di as f64, dj as f64) * res;
                CorrelativeResult {
                    target_from_source: Pose2::new(t, theta),
                    score: score.max(0.0) / n_source as f64,
                }
            })
            .collect()
    }
}

/// The rotations tried from each heading and the source's lattice cells at each, and the
/// number of rotation steps on each side of a heading.
struct Sweeps {
    per_heading: Vec<Sweep>,
    n_ang: usize,
}

impl Sweeps {
    /// The rotations of `source` about `translation` in `config`'s angular window around each
    /// of `headings`, its points' cells in the lattice anchored at `origin`.
    fn new(
        source: &[Point2<f64>],
        translation: &Vector2<f64>,
        headings: &[f64],
        origin: &Point2<f64>,
        config: &CorrelativeConfig,
    ) -> Result<Self, LidarError> {
        if source.len() < config.min_points.max(1) {
            return Err(LidarError::TooFewPoints {
                got: source.len(),
                min: config.min_points.max(1),
            });
        }
        let res = config.resolution_m;
        // Rotation step: the farthest point moves by at most one cell (Olson 2009, eq. 11).
        let step = (1.0 - res * res / (2.0 * reach(source).max(res).powi(2)))
            .clamp(-1.0, 1.0)
            .acos()
            .min(config.max_angular_step_rad)
            .max(1e-4);
        let n_ang = (config.angular_window_rad / step).ceil() as i64;
        let per_heading = headings
            .iter()
            .map(|&theta0| {
                let angles: Vec<f64> = (-n_ang..=n_ang).map(|a| theta0 + a as f64 * step).collect();
                let footprints = angles
                    .iter()
                    .map(|&theta| {
                        let pose = Pose2::new(*translation, theta);
                        source
                            .iter()
                            .map(|p| lattice_cell(origin, res, &(pose * p)))
                            .collect()
                    })
                    .collect();
                (angles, footprints)
            })
            .collect();
        Ok(Self {
            per_heading,
            n_ang: n_ang as usize,
        })
    }
}

/// The rotations tried from one heading, and the source's lattice cells at each.
type Sweep = (Vec<f64>, Vec<Vec<(i64, i64)>>);

/// Every block of translations (starting at `starts` in both axes) at every rotation, with its
/// bound, best bound first.
fn bound_blocks(bound_field: &Field, rotated: &[Footprint], starts: &[i64]) -> Vec<Block> {
    let mut blocks: Vec<Block> = Vec::with_capacity(rotated.len() * starts.len().pow(2));
    for (angle, cells) in rotated.iter().enumerate() {
        for &di in starts {
            for djs in starts.chunks(LANES) {
                let bounds = bound_field.score_lanes(cells, di, djs);
                for (&dj, &bound) in djs.iter().zip(&bounds) {
                    blocks.push(Block {
                        bound,
                        angle,
                        di,
                        dj,
                    });
                }
            }
        }
    }
    blocks.sort_by(|a, b| b.bound.total_cmp(&a.bound));
    blocks
}

/// Scores every translation of the blocks, best bound first, until no bound beats the best
/// score: `(score, angle, di, dj)` of the best (the first found among equals). Translations run
/// up to `w` cells; `centre_angle` is reported when nothing scores.
fn best_in_blocks(
    field: &Field,
    rotated: &[Footprint],
    blocks: &[Block],
    coarse: i64,
    w: i64,
    centre_angle: usize,
) -> (f64, usize, i64, i64) {
    let mut best = (f64::NEG_INFINITY, centre_angle, 0, 0);
    for block in blocks {
        if block.bound <= best.0 {
            break;
        }
        let Some(cells) = rotated.get(block.angle) else {
            continue;
        };
        let (di_end, dj_end) = (
            (block.di + coarse).min(w + 1),
            (block.dj + coarse).min(w + 1),
        );
        // The block's best, the first in translation order (`di`, then `dj`) among equals, as
        // when scored one by one; a later block must beat it.
        let mut block_best: Option<(f64, i64, i64)> = None;
        for dj0 in (block.dj..dj_end).step_by(LANES) {
            for di0 in (block.di..di_end).step_by(LANES) {
                let square = field.score_square(cells, di0, dj0);
                for (dj, row) in (dj0..dj_end).zip(square) {
                    for (di, s) in (di0..di_end).zip(row) {
                        let better = block_best.map_or(true, |(b, bdi, bdj)| {
                            s > b || (s == b && (di, dj) < (bdi, bdj))
                        });
                        if better {
                            block_best = Some((s, di, dj));
                        }
                    }
                }
            }
        }
        if let Some((s, di, dj)) = block_best.filter(|(s, _, _)| *s > best.0) {
            best = (s, block.angle, di, dj);
        }
    }
    best
}

fn validate(config: &CorrelativeConfig) -> Result<(), LidarError> {
    let checks = [
        (
            "linear_window_m",
            config.linear_window_m,
            config.linear_window_m >= 0.0,
        ),
        (
            "angular_window_rad",
            config.angular_window_rad,
            config.angular_window_rad >= 0.0,
        ),
        (
            "resolution_m",
            config.resolution_m,
            config.resolution_m > 0.0,
        ),
        ("sigma_m", config.sigma_m, config.sigma_m > 0.0),
        (
            "max_angular_step_rad",
            config.max_angular_step_rad,
            config.max_angular_step_rad > 0.0,
        ),
    ];
    check_fields(
        checks,
        "out of range (windows >= 0, steps and sizes > 0, finite)",
    )
}

#[cfg(test)]
mod tests;
