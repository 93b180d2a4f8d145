//! A world-frame point map that merges the points falling in the same voxel into their mean
//! (position and colour), so that memory grows with the explored volume, not with the number
//! of frames — the seed's point map kept every point and grew until the program died. A cap
//! on the voxel count bounds memory even for unbounded exploration: points that would open a
//! voxel beyond it are counted and dropped. This is the voxel-grid filter of PCL
//! (Rusu & Cousins, ICRA 2011) kept incrementally.
//!
//! Voxel keys are hashed with a multiply-xorshift mix (the 64-bit finaliser of MurmurHash3)
//! rather than the standard library's DoS-resistant SipHash: the keys come from the sensor, not
//! from an adversary. Consecutive points of a depth image mostly fall in the voxel of the point
//! before them, which is then updated without a second lookup.

use std::collections::hash_map::Entry;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::io::Write;
use std::path::Path;

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use slamkit_core::{PointCloud, Pose3};

use crate::error::VoError;

/// Voxel map settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VoxelMapConfig {
    /// Voxel edge \[m\].
    pub voxel_m: f64,
    /// Most voxels kept \[voxels\].
    pub max_voxels: usize,
}

impl Default for VoxelMapConfig {
    fn default() -> Self {
        Self {
            voxel_m: 0.02,
            max_voxels: 2_000_000,
        }
    }
}

impl VoxelMapConfig {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`VoError::InvalidConfig`] for a non-positive voxel size.
    pub fn validate(&self) -> Result<(), VoError> {
        if !(self.voxel_m > 0.0 && self.voxel_m.is_finite()) {
            return Err(VoError::config(
                "voxel_map.voxel_m",
                self.voxel_m,
                "must be > 0",
            ));
        }
        Ok(())
    }
}

#[derive(Debug, Clone, Copy)]
struct Voxel {
    sum: Vector3<f64>,
    color_sum: [u32; 3],
    count: u32,
}

impl Voxel {
    fn add(&mut self, p: Vector3<f64>, color: [u8; 3]) {
        self.sum += p;
        for (s, c) in self.color_sum.iter_mut().zip(color) {
            *s += u32::from(c);
        }
        self.count += 1;
    }
}

/// Hashes the three coordinates of a voxel key: each folded in with a multiply, the result
/// mixed by MurmurHash3's `fmix64` so that the low bits (the hash table's bucket) depend on
/// every coordinate.
#[derive(Debug, Default, Clone, Copy)]
struct VoxelHasher(u64);

impl Hasher for VoxelHasher {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u32(u32::from(b));
        }
    }

    fn write_u32(&mut self, v: u32) {
        self.0 = (self.0 ^ u64::from(v)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }

    fn write_i32(&mut self, v: i32) {
        self.write_u32(v as u32);
    }

    fn finish(&self) -> u64 {
        let mut h = self.0;
        h ^= h >> 33;
        h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
        h = h.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        h ^ (h >> 33)
    }
}

type VoxelKey = (i32, i32, i32);

/// The merged point map.
#[derive(Debug, Clone)]
pub struct VoxelMap {
    config: VoxelMapConfig,
    voxels: HashMap<VoxelKey, Voxel, BuildHasherDefault<VoxelHasher>>,
    dropped: usize,
}

impl VoxelMap {
    /// An empty map.
    pub fn new(config: VoxelMapConfig) -> Self {
        Self {
            config,
            voxels: HashMap::default(),
            dropped: 0,
        }
    }

    /// Number of occupied voxels (= points of the exported cloud).
    pub fn len(&self) -> usize {
        self.voxels.len()
    }

    /// True when no point was inserted.
    pub fn is_empty(&self) -> bool {
        self.voxels.is_empty()
    }

    /// Points dropped because the map was full or they were not finite.
    pub fn dropped(&self) -> usize {
        self.dropped
    }

    /// Inserts camera-frame points (with colours) seen from `world_from_camera`.
    pub fn insert(
        &mut self,
        world_from_camera: &Pose3,
        points: &[Point3<f64>],
        colors: &[[u8; 3]],
    ) {
        let inv = 1.0 / self.config.voxel_m;
        // the voxel of the previous point, updated again without a lookup
        let mut last: Option<(VoxelKey, &mut Voxel)> = None;
        for (i, p) in points.iter().enumerate() {
            let w = world_from_camera * p;
            let key = w.coords * inv;
            if !key
                .iter()
                .all(|v| v.is_finite() && v.abs() < f64::from(i32::MAX) - 1.0)
            {
                self.dropped += 1;
                continue;
            }
            let key = (
                key.x.floor() as i32,
                key.y.floor() as i32,
                key.z.floor() as i32,
            );
            let color = colors.get(i).copied().unwrap_or([255; 3]);
            if let Some((k, voxel)) = &mut last {
                if *k == key {
                    voxel.add(w.coords, color);
                    continue;
                }
            }
            last = None;
            let full = self.voxels.len() >= self.config.max_voxels;
            match self.voxels.entry(key) {
                Entry::Occupied(o) => {
                    let voxel = o.into_mut();
                    voxel.add(w.coords, color);
                    last = Some((key, voxel));
                }
                Entry::Vacant(_) if full => self.dropped += 1,
                Entry::Vacant(v) => {
                    let voxel = v.insert(Voxel {
                        sum: w.coords,
                        color_sum: color.map(u32::from),
                        count: 1,
                    });
                    last = Some((key, voxel));
                }
            }
        }
    }

    /// One point per voxel: the mean position and colour of what fell in it.
    pub fn to_cloud(&self) -> PointCloud {
        let mut keys: Vec<_> = self.voxels.keys().copied().collect();
        keys.sort_unstable();
        let (points, colors) = keys
            .iter()
            .filter_map(|k| self.voxels.get(k))
            .map(|v| {
                let n = f64::from(v.count);
                (
                    Point3::from(v.sum / n),
                    v.color_sum.map(|c| (c / v.count) as u8),
                )
            })
            .unzip();
        PointCloud {
            points,
            colors: Some(colors),
        }
    }

    /// Writes the map as a binary little-endian PLY (x, y, z float; red, green, blue uchar).
    ///
    /// # Errors
    /// [`VoError::Write`] when the file cannot be written.
    pub fn write_ply(&self, path: &Path) -> Result<(), VoError> {
        let cloud = self.to_cloud();
        let err = |e| VoError::Write {
            path: path.display().to_string(),
            source: e,
        };
        let mut out = Vec::with_capacity(64 + cloud.points.len() * 15);
        write!(
            out,
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
             property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
            cloud.points.len()
        )
        .map_err(err)?;
        let colors = cloud.colors.unwrap_or_default();
        for (p, c) in cloud.points.iter().zip(colors) {
            for v in [p.x, p.y, p.z] {
                out.extend_from_slice(&(v as f32).to_le_bytes());
            }
            out.extend_from_slice(&c);
        }
        std::fs::write(path, out).map_err(err)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_in_one_voxel_merge_and_memory_is_capped() {
        let mut map = VoxelMap::new(VoxelMapConfig {
            voxel_m: 0.1,
            max_voxels: 2,
        });
        let pose = Pose3::translation(1.0, 0.0, 0.0);
        let pts = [
            Point3::new(0.01, 0.01, 0.01),
            Point3::new(0.03, 0.05, 0.07),
            Point3::new(0.5, 0.0, 0.0),
        ];
        map.insert(&pose, &pts, &[[10, 20, 30], [30, 40, 50], [0, 0, 0]]);
        for _ in 0..100 {
            map.insert(&pose, &pts, &[]);
        }
        assert_eq!(map.len(), 2);
        let far = [Point3::new(9.0, 9.0, 9.0), Point3::new(f64::NAN, 0.0, 0.0)];
        map.insert(&pose, &far, &[]);
        assert_eq!((map.len(), map.dropped()), (2, 2));
        let cloud = map.to_cloud();
        let first = cloud.points[0];
        assert!(
            (first - Point3::new(1.02, 0.03, 0.04)).norm() < 1e-9,
            "{first}"
        );
    }

    #[test]
    fn runs_of_points_in_one_voxel_and_returns_to_a_voxel_merge_alike() {
        let mut map = VoxelMap::new(VoxelMapConfig {
            voxel_m: 1.0,
            max_voxels: 10,
        });
        // voxels a, a, b, a, c, c (c differs from a in z only, b in x only)
        let pts = [
            Point3::new(0.1, 0.5, 0.5),
            Point3::new(0.3, 0.5, 0.5),
            Point3::new(1.5, 0.5, 0.5),
            Point3::new(0.8, 0.5, 0.5),
            Point3::new(0.5, 0.5, -0.5),
            Point3::new(0.5, 0.5, -0.9),
        ];
        map.insert(
            &Pose3::identity(),
            &pts,
            &[[30, 0, 0], [0, 30, 0], [9, 9, 9]],
        );
        let cloud = map.to_cloud();
        let colors = cloud.colors.unwrap();
        // sorted keys: c (0, 0, -1), a (0, 0, 0), b (1, 0, 0)
        assert_eq!(cloud.points.len(), 3);
        assert!((cloud.points[0] - Point3::new(0.5, 0.5, -0.7)).norm() < 1e-12);
        assert!((cloud.points[1] - Point3::new(0.4, 0.5, 0.5)).norm() < 1e-12);
        assert!((cloud.points[2] - Point3::new(1.5, 0.5, 0.5)).norm() < 1e-12);
        // a: (30, 0, 0), (0, 30, 0) and white (no colour given)
        assert_eq!(colors[1], [95, 95, 85]);
        assert_eq!(colors[2], [9, 9, 9]);
    }

    #[test]
    fn ply_has_one_vertex_per_voxel() {
        let mut map = VoxelMap::new(VoxelMapConfig::default());
        map.insert(
            &Pose3::identity(),
            &[Point3::new(0.0, 0.0, 1.0), Point3::new(0.0, 0.0, 2.0)],
            &[],
        );
        let dir = std::env::temp_dir().join(format!("slamkit-vo-ply-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cloud.ply");
        map.write_ply(&path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let text = String::from_utf8_lossy(&bytes);
        assert!(text.contains("element vertex 2\n"));
        let header_end = text.find("end_header\n").unwrap() + "end_header\n".len();
        assert_eq!(bytes.len() - header_end, 2 * 15);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
