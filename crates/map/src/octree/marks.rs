//! Per-cloud marks: which voxels a cloud's rays passed through or ended in.
//!
//! Marks are kept in 8 × 8 × 8 chunks (512 bytes, one per voxel, in Morton order) found
//! through a hash map keyed by the chunk's Morton code, with the last chunk cached since
//! consecutive voxels of a ray mostly share a chunk. Draining visits the chunks in Morton order,
//! so the voxel updates come out sorted without sorting voxels: a dense window's speed without
//! its size limit.

use super::key::OctreeKey;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// Mark of a voxel a ray passed through.
const PASSED: u8 = 1;
/// Mark of a voxel holding a ray's end point.
const HIT: u8 = 2;
/// Voxels per chunk.
const CHUNK: usize = 512;

/// Multiplicative hash of a `u64` key (Fibonacci hashing); chunk codes need no more.
#[derive(Debug, Default, Clone, Copy)]
pub struct MortonHasher(u64);

impl Hasher for MortonHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = v.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

/// Marks of the current cloud; see the module documentation.
#[derive(Debug, Clone, Default)]
pub struct Marks {
    index: HashMap<u64, u32, BuildHasherDefault<MortonHasher>>,
    chunks: Vec<[u8; CHUNK]>,
    last: Option<(u64, u32)>,
    order: Vec<(u64, u32)>,
}

impl Marks {
    /// Marks `key` as hit (`true`) or passed through; a hit is never downgraded.
    #[inline]
    pub fn mark(&mut self, key: OctreeKey, hit: bool) {
        let morton = key.morton();
        let chunk_code = morton >> 9;
        let slot = match self.last {
            Some((code, slot)) if code == chunk_code => slot,
            _ => {
                let next = self.index.len() as u32;
                let slot = *self.index.entry(chunk_code).or_insert(next);
                if slot as usize == self.chunks.len() {
                    self.chunks.push([0; CHUNK]);
                }
                self.last = Some((chunk_code, slot));
                slot
            }
        };
        let cell = &mut self.chunks[slot as usize][(morton & 511) as usize];
        *cell |= if hit { HIT } else { PASSED };
    }

    /// Writes every marked voxel as `morton << 1 | hit` into `updates` in Morton order, and
    /// clears the marks (keeping their memory for the next cloud).
    pub fn drain_sorted(&mut self, updates: &mut Vec<u64>) {
        updates.clear();
        self.order.clear();
        self.order.extend(self.index.drain());
        self.order.sort_unstable_by_key(|&(code, _)| code);
        for &(code, slot) in &self.order {
            let chunk = &self.chunks[slot as usize];
            for (local, &mark) in chunk.iter().enumerate() {
                if mark != 0 {
                    let morton = (code << 9) | local as u64;
                    updates.push((morton << 1) | u64::from(mark & HIT != 0));
                }
            }
        }
        self.chunks.truncate(0);
        self.last = None;
    }
}
