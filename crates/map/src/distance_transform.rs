//! Exact Euclidean distance transform of a binary image.
//!
//! P. F. Felzenszwalb and D. P. Huttenlocher, "Distance transforms of sampled functions",
//! Theory of Computing 8(19), 2012: the squared distance transform is separable, and in 1D it is
//! the lower envelope of parabolas rooted at the sites, found in O(n). Running it down every
//! column and then along every row gives the exact squared Euclidean distance in O(width·height).

/// Squared distance \[cells²\] from every cell of a `width × height` row-major image to the nearest
/// cell where `is_site` is true; `f32::INFINITY` everywhere when there is no site.
pub fn squared_distance_transform(is_site: &[bool], width: usize, height: usize) -> Vec<f32> {
    debug_assert_eq!(is_site.len(), width * height);
    let mut out: Vec<f64> = is_site
        .iter()
        .map(|&s| if s { 0.0 } else { f64::INFINITY })
        .collect();
    let mut envelope = Envelope::with_capacity(width.max(height));
    let mut line = vec![0.0; height];
    for x in 0..width {
        for (y, v) in line.iter_mut().enumerate() {
            *v = out[y * width + x];
        }
        envelope.transform(&mut line);
        for (y, v) in line.iter().enumerate() {
            out[y * width + x] = *v;
        }
    }
    for row in out.chunks_exact_mut(width.max(1)) {
        envelope.transform(row);
    }
    out.into_iter().map(|d| d as f32).collect()
}

/// Work space of the 1D transform: the parabolas of the lower envelope and their boundaries.
struct Envelope {
    /// Positions of the parabolas' roots.
    roots: Vec<usize>,
    /// `bounds[k]..bounds[k + 1]` is where parabola k is lowest.
    bounds: Vec<f64>,
    /// Copy of the input line.
    input: Vec<f64>,
}

impl Envelope {
    fn with_capacity(n: usize) -> Self {
        Self {
            roots: Vec::with_capacity(n),
            bounds: Vec::with_capacity(n + 1),
            input: Vec::with_capacity(n),
        }
    }

    /// Replaces `f` by `d(q) = min_p (q - p)² + f(p)` (infinite sites are skipped).
    fn transform(&mut self, f: &mut [f64]) {
        self.input.clear();
        self.input.extend_from_slice(f);
        self.roots.clear();
        self.bounds.clear();
        let input = &self.input;
        let parabola = |p: usize| input[p] + (p * p) as f64;
        for q in (0..f.len()).filter(|&q| input[q].is_finite()) {
            let mut s = f64::NEG_INFINITY;
            while let Some(&p) = self.roots.last() {
                s = (parabola(q) - parabola(p)) / (2.0 * (q - p) as f64);
                if s > *self.bounds.last().unwrap_or(&f64::NEG_INFINITY) {
                    break;
                }
                self.roots.pop();
                self.bounds.pop();
                s = f64::NEG_INFINITY;
            }
            self.roots.push(q);
            self.bounds.push(s);
        }
        if self.roots.is_empty() {
            f.fill(f64::INFINITY);
            return;
        }
        let mut k = 0;
        for (q, out) in f.iter_mut().enumerate() {
            while k + 1 < self.roots.len() && self.bounds[k + 1] < q as f64 {
                k += 1;
            }
            let p = self.roots[k];
            let d = q as f64 - p as f64;
            *out = d * d + input[p];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn brute_force(is_site: &[bool], width: usize, height: usize) -> Vec<f32> {
        let sites: Vec<(i64, i64)> = (0..width * height)
            .filter(|&i| is_site[i])
            .map(|i| ((i % width) as i64, (i / width) as i64))
            .collect();
        (0..width * height)
            .map(|i| {
                let (x, y) = ((i % width) as i64, (i / width) as i64);
                let best = sites
                    .iter()
                    .map(|(sx, sy)| (sx - x).pow(2) + (sy - y).pow(2))
                    .min();
                best.map_or(f32::INFINITY, |d| d as f32)
            })
            .collect()
    }

    #[test]
    fn matches_brute_force_on_random_images() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for (width, height, density) in [(37, 23, 0.02), (50, 50, 0.2), (1, 30, 0.1), (64, 5, 0.01)]
        {
            for _ in 0..5 {
                let sites: Vec<bool> = (0..width * height).map(|_| rng.gen_bool(density)).collect();
                assert_eq!(
                    squared_distance_transform(&sites, width, height),
                    brute_force(&sites, width, height),
                    "{width}x{height} density {density}"
                );
            }
        }
    }

    #[test]
    fn single_site_and_no_site() {
        let mut sites = vec![false; 5 * 4];
        assert!(squared_distance_transform(&sites, 5, 4)
            .iter()
            .all(|d| d.is_infinite()));
        sites[2 * 5 + 1] = true; // (1, 2)
        let d = squared_distance_transform(&sites, 5, 4);
        assert_eq!(d[2 * 5 + 1], 0.0);
        assert_eq!(d[4], 9.0 + 4.0); // (4, 0)
        assert_eq!(d[3 * 5], 1.0 + 1.0); // (0, 3)
        assert!(squared_distance_transform(&[], 0, 0).is_empty());
    }
}
