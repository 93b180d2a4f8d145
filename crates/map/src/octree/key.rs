//! Octree keys: integer voxel addresses, their Morton order, and the voxel traversal of a ray.
//!
//! A key holds one 16-bit index per axis, `floor(coordinate / resolution) + 2^15`, exactly as
//! OctoMap's `OcTreeKey` (Hornung et al. 2013, section 4.1), so a tree of depth 16 covers
//! ±2^15 voxels around the origin. Sorting keys by their Morton code (bits interleaved, x lowest,
//! as OctoMap's `computeChildIdx`) visits the tree depth first, child 0 to 7.
//!
//! [`ray_keys`] is OctoMap's `computeRayKeys`: the voxel traversal of J. Amanatides and A. Woo,
//! "A fast voxel traversal algorithm for ray tracing", Eurographics 1987, computed with the same
//! float and double arithmetic so both libraries visit the same voxels.

/// Depth of the tree: 16 levels of octants below the root.
pub const TREE_DEPTH: u32 = 16;
/// Key of the voxel whose lower corner is the world origin.
pub const TREE_MAX_VAL: i32 = 1 << 15;

/// Integer address of a voxel at the finest level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct OctreeKey(pub [u16; 3]);

/// Key of coordinate `c` along one axis; `None` for NaN or beyond the tree.
#[inline]
pub fn coord_to_key(c: f64, inv_resolution: f64) -> Option<u16> {
    let scaled = (c * inv_resolution).floor();
    // NaN fails the comparison.
    if scaled.abs() <= f64::from(TREE_MAX_VAL) {
        let key = scaled as i32 + TREE_MAX_VAL;
        u16::try_from(key).ok()
    } else {
        None
    }
}

/// Centre coordinate of key `k` along one axis at the finest level.
#[inline]
pub fn key_to_coord(k: u16, resolution: f64) -> f64 {
    (f64::from(i32::from(k) - TREE_MAX_VAL) + 0.5) * resolution
}

/// Spreads the low 16 bits of `v` so that bit i lands on bit 3i.
#[inline]
fn spread(v: u16) -> u64 {
    let mut x = u64::from(v);
    x = (x | (x << 16)) & 0x0000_FF00_00FF;
    x = (x | (x << 8)) & 0x00F0_0F00_F00F;
    x = (x | (x << 4)) & 0x0C30_C30C_30C3;
    (x | (x << 2)) & 0x2492_4924_9249
}

/// Gathers every third bit of `m` (bits 0, 3, 6, ...) into the low 16 bits.
#[inline]
fn compact(m: u64) -> u16 {
    let mut x = m & 0x2492_4924_9249;
    x = (x | (x >> 2)) & 0x0C30_C30C_30C3;
    x = (x | (x >> 4)) & 0x00F0_0F00_F00F;
    x = (x | (x >> 8)) & 0x0000_FF00_00FF;
    ((x | (x >> 16)) & 0xFFFF) as u16
}

impl OctreeKey {
    /// Morton code: x, y, z bits interleaved, x lowest; bits `3d..3d+3` give the child index at
    /// level `15 - d` below the root.
    #[inline]
    pub fn morton(self) -> u64 {
        let [x, y, z] = self.0;
        spread(x) | (spread(y) << 1) | (spread(z) << 2)
    }

    /// The key whose Morton code is `m`.
    #[inline]
    pub fn from_morton(m: u64) -> Self {
        Self([compact(m), compact(m >> 1), compact(m >> 2)])
    }
}

/// Calls `visit` for every voxel a ray from `origin` to `end` passes through, origin voxel
/// included and end voxel excluded; nothing when both lie in the same voxel. Returns `false`
/// (visiting nothing) when either end lies outside the tree or is not finite.
///
/// The arithmetic follows OctoMap 1.10 `computeRayKeys` step for step (points in `f32`, the
/// traversal in `f64`), so the voxels agree with OctoMap's even at ties.
pub fn ray_keys(
    origin: [f32; 3],
    end: [f32; 3],
    resolution: f64,
    mut visit: impl FnMut(OctreeKey),
) -> bool {
    let inv = 1.0 / resolution;
    let key_of = |p: [f32; 3]| -> Option<[u16; 3]> {
        Some([
            coord_to_key(f64::from(p[0]), inv)?,
            coord_to_key(f64::from(p[1]), inv)?,
            coord_to_key(f64::from(p[2]), inv)?,
        ])
    };
    let (Some(key_origin), Some(key_end)) = (key_of(origin), key_of(end)) else {
        return false;
    };
    if key_origin == key_end {
        return true;
    }
    visit(OctreeKey(key_origin));
    let mut direction = [end[0] - origin[0], end[1] - origin[1], end[2] - origin[2]];
    let norm_sq =
        direction[0] * direction[0] + direction[1] * direction[1] + direction[2] * direction[2];
    let length = f64::from(norm_sq).sqrt() as f32;
    for d in &mut direction {
        *d /= length;
    }
    let mut step = [0i32; 3];
    let mut t_max = [f64::MAX; 3];
    let mut t_delta = [f64::MAX; 3];
    for i in 0..3 {
        let di = f64::from(direction[i]);
        if direction[i] > 0.0 {
            step[i] = 1;
        } else if direction[i] < 0.0 {
            step[i] = -1;
        }
        if step[i] != 0 {
            let border = key_to_coord(key_origin[i], resolution)
                + f64::from((f64::from(step[i]) * resolution * 0.5) as f32);
            t_max[i] = (border - f64::from(origin[i])) / di;
            t_delta[i] = resolution / di.abs();
        }
    }
    let length = f64::from(length);
    let mut current = [
        i32::from(key_origin[0]),
        i32::from(key_origin[1]),
        i32::from(key_origin[2]),
    ];
    let end_key = key_end.map(i32::from);
    loop {
        let dim = if t_max[0] < t_max[1] {
            if t_max[0] < t_max[2] {
                0
            } else {
                2
            }
        } else if t_max[1] < t_max[2] {
            1
        } else {
            2
        };
        current[dim] += step[dim];
        t_max[dim] += t_delta[dim];
        if current == end_key {
            return true;
        }
        let travelled = t_max[0].min(t_max[1]).min(t_max[2]);
        // Both ends lie inside the tree, so the traversal stays inside it too; the guard only
        // protects against rounding at the tree's very edge.
        if travelled > length || current.iter().any(|c| !(0..2 * TREE_MAX_VAL).contains(c)) {
            return true;
        }
        visit(OctreeKey(current.map(|c| c as u16)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_roundtrip_and_child_order() {
        for key in [
            [0u16, 0, 0],
            [1, 2, 3],
            [65535, 0, 65535],
            [32768, 12345, 54321],
        ] {
            let k = OctreeKey(key);
            assert_eq!(OctreeKey::from_morton(k.morton()), k);
        }
        // Lowest three bits: x, y, z of the finest level.
        assert_eq!(OctreeKey([1, 0, 0]).morton(), 1);
        assert_eq!(OctreeKey([0, 1, 0]).morton(), 2);
        assert_eq!(OctreeKey([0, 0, 1]).morton(), 4);
        assert_eq!(OctreeKey([2, 0, 0]).morton(), 8);
    }

    #[test]
    fn keys_and_centres() {
        assert_eq!(coord_to_key(0.0, 10.0), Some(32768));
        assert_eq!(coord_to_key(-0.01, 10.0), Some(32767));
        assert_eq!(coord_to_key(f64::NAN, 10.0), None);
        assert_eq!(coord_to_key(1e9, 10.0), None);
        assert!((key_to_coord(32768, 0.1) - 0.05).abs() < 1e-12);
    }

    #[test]
    fn ray_visits_a_connected_line_excluding_the_end() {
        let mut keys = Vec::new();
        assert!(ray_keys(
            [0.05, 0.05, 0.05],
            [1.03, 0.47, -0.33],
            0.1,
            |k| keys.push(k)
        ));
        let end = [1.03f64, 0.47, -0.33].map(|c| coord_to_key(c, 10.0));
        assert_eq!(keys.first(), Some(&OctreeKey([32768; 3])));
        for w in keys.windows(2) {
            let diff: i32 = (0..3)
                .map(|i| (i32::from(w[0].0[i]) - i32::from(w[1].0[i])).abs())
                .sum();
            assert_eq!(diff, 1, "face-connected steps");
        }
        let last = keys.last().map(|k| k.0.map(Some));
        assert_ne!(last, Some(end));
        // 10 + 4 + 4 voxel borders crossed, the last step reaches the end voxel.
        assert_eq!(keys.len(), 10 + 4 + 4);
        assert!(!ray_keys(
            [0.0, 0.0, f32::NAN],
            [1.0, 0.0, 0.0],
            0.1,
            |_| {}
        ));
    }
}
