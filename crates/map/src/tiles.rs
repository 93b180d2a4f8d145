//! Growable, tiled, copy-on-write cell storage.
//!
//! Cells live in fixed 64 × 64 tiles, each a flat array held in an [`Arc`]. A flat index of
//! optional tiles covers a rectangle of tile coordinates and is reallocated with a margin when
//! the robot leaves it, so growth costs amortised O(1) per new tile and never moves cell data.
//! Cloning a store copies only the index: the clone shares every tile, and [`Arc::make_mut`]
//! copies a tile the first time either side writes into it. This is the map sharing that lets a
//! Rao-Blackwellised particle filter keep hundreds of maps in little more than one map's memory
//! (G. Grisetti, C. Stachniss, W. Burgard, "Improved techniques for grid mapping with
//! Rao-Blackwellized particle filters", IEEE T-RO 23(1), 2007, section VI).

use std::sync::Arc;

/// log2 of the tile side length in cells.
pub(crate) const TILE_BITS: u32 = 6;
/// Tile side length in cells.
pub const TILE_SIZE: usize = 1 << TILE_BITS;
/// Mask giving a cell's coordinate inside its tile.
pub(crate) const TILE_MASK: i32 = TILE_SIZE as i32 - 1;
/// Cells per tile.
pub(crate) const TILE_CELLS: usize = TILE_SIZE * TILE_SIZE;
/// Most tiles a grid's bounding box may span: 2048 × 2048 tiles, 6.5 km square at 5 cm cells,
/// whose index alone takes 32 MB. No building needs more; a pose that asks for more is a jump.
pub const MAX_INDEX_TILES: u64 = 1 << 22;

/// One tile of cell values, row-major (`cells[y * TILE_SIZE + x]`).
#[derive(Clone)]
pub(crate) struct Tile {
    pub(crate) cells: [f32; TILE_CELLS],
}

impl Tile {
    fn new() -> Arc<Self> {
        Arc::new(Self {
            cells: [0.0; TILE_CELLS],
        })
    }
}

impl std::fmt::Debug for Tile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let known = self.cells.iter().filter(|c| **c != 0.0).count();
        write!(f, "Tile({known} known cells)")
    }
}

/// A rectangle of tiles, some allocated; unallocated tiles read as 0.
#[derive(Debug, Clone, Default)]
pub(crate) struct TileStore {
    /// Tile coordinates of `tiles[0]`.
    x0: i32,
    y0: i32,
    /// Size of the index in tiles.
    width: usize,
    height: usize,
    tiles: Vec<Option<Arc<Tile>>>,
}

impl TileStore {
    /// Flat index of tile `(tx, ty)`, when inside the index rectangle.
    #[inline]
    pub(crate) fn tile_index(&self, tx: i32, ty: i32) -> Option<usize> {
        let ix = usize::try_from(tx.checked_sub(self.x0)?).ok()?;
        let iy = usize::try_from(ty.checked_sub(self.y0)?).ok()?;
        (ix < self.width && iy < self.height).then_some(iy * self.width + ix)
    }

    /// Value of cell `(cx, cy)`; `None` outside the index rectangle.
    #[inline]
    pub(crate) fn get(&self, cx: i32, cy: i32) -> Option<f32> {
        let index = self.tile_index(cx >> TILE_BITS, cy >> TILE_BITS)?;
        Some(match &self.tiles[index] {
            Some(tile) => tile.cells[local_index(cx, cy)],
            None => 0.0,
        })
    }

    /// Cells `cx..cx + len` of row `cy` as one slice, when they lie in one tile inside the index
    /// rectangle (`len <= TILE_SIZE`); `None` otherwise. Unallocated tiles read as zeros.
    /// Reading a window row by row costs one tile lookup per row instead of one per cell.
    #[inline]
    pub(crate) fn row(&self, cx: i32, cy: i32, len: usize) -> Option<&[f32]> {
        static ZEROS: [f32; TILE_SIZE] = [0.0; TILE_SIZE];
        let last = cx.checked_add(i32::try_from(len).ok()?.checked_sub(1)?)?;
        if cx >> TILE_BITS != last >> TILE_BITS {
            return None;
        }
        let index = self.tile_index(cx >> TILE_BITS, cy >> TILE_BITS)?;
        let start = local_index(cx, cy);
        match &self.tiles[index] {
            Some(tile) => tile.cells.get(start..start + len),
            None => ZEROS.get(..len),
        }
    }

    /// Grows the index so that it covers tiles `min..=max`, keeping a margin of half the current
    /// size on each side that grows so repeated growth is amortised.
    ///
    /// The index is dense over the tiles' bounding box, so one far point (a pose or odometry
    /// jump) would ask for memory without bound: beyond [`MAX_INDEX_TILES`] the margin is
    /// dropped, and a box that does not fit even then is refused with its size in tiles.
    pub(crate) fn cover_tiles(&mut self, min: [i32; 2], max: [i32; 2]) -> Result<(), [u64; 2]> {
        if self.tile_index(min[0], min[1]).is_some() && self.tile_index(max[0], max[1]).is_some() {
            return Ok(());
        }
        let empty = self.tiles.is_empty();
        let (mut x0, mut x1) = grown_span(self.x0, self.width, min[0], max[0], empty);
        let (mut y0, mut y1) = grown_span(self.y0, self.height, min[1], max[1], empty);
        let span = |lo: i32, hi: i32| (i64::from(hi) - i64::from(lo) + 1) as u64;
        if span(x0, x1) * span(y0, y1) > MAX_INDEX_TILES {
            // no margin: the union of what is covered and what is asked for
            let old_hi = |t0: i32, n: usize| if empty { i32::MIN } else { t0 + n as i32 - 1 };
            let old_lo = |t0: i32| if empty { i32::MAX } else { t0 };
            (x0, x1) = (
                min[0].min(old_lo(self.x0)),
                max[0].max(old_hi(self.x0, self.width)),
            );
            (y0, y1) = (
                min[1].min(old_lo(self.y0)),
                max[1].max(old_hi(self.y0, self.height)),
            );
            if span(x0, x1) * span(y0, y1) > MAX_INDEX_TILES {
                return Err([span(x0, x1), span(y0, y1)]);
            }
        }
        let (width, height) = ((x1 - x0 + 1) as usize, (y1 - y0 + 1) as usize);
        let mut tiles = vec![None; width * height];
        for (i, tile) in std::mem::take(&mut self.tiles).into_iter().enumerate() {
            let tx = self.x0 + (i % self.width) as i32;
            let ty = self.y0 + (i / self.width) as i32;
            tiles[(ty - y0) as usize * width + (tx - x0) as usize] = tile;
        }
        *self = Self {
            x0,
            y0,
            width,
            height,
            tiles,
        };
        Ok(())
    }

    /// Writable tile at flat index `index` (from [`Self::tile_index`]), allocating it or copying
    /// it away from other stores that share it.
    #[inline]
    pub(crate) fn tile_mut(&mut self, index: usize) -> &mut Tile {
        Arc::make_mut(self.tiles[index].get_or_insert_with(Tile::new))
    }

    /// Writable cell `(cx, cy)`, growing the index when needed; `Err` as
    /// [`Self::cover_tiles`].
    pub(crate) fn cell_mut(&mut self, cx: i32, cy: i32) -> Result<&mut f32, [u64; 2]> {
        let (tx, ty) = (cx >> TILE_BITS, cy >> TILE_BITS);
        self.cover_tiles([tx, ty], [tx, ty])?;
        let index = self.tile_index(tx, ty).unwrap_or_default();
        Ok(&mut self.tile_mut(index).cells[local_index(cx, cy)])
    }

    /// Allocated tiles with the cell coordinates of their lower-left cell.
    pub(crate) fn tiles(&self) -> impl Iterator<Item = ([i32; 2], &Arc<Tile>)> + '_ {
        self.tiles.iter().enumerate().filter_map(|(i, tile)| {
            let tx = self.x0 + (i % self.width) as i32;
            let ty = self.y0 + (i / self.width) as i32;
            tile.as_ref()
                .map(|t| ([tx << TILE_BITS, ty << TILE_BITS], t))
        })
    }

    /// Bytes used by the tile index itself (not the tiles).
    pub(crate) fn index_bytes(&self) -> usize {
        self.tiles.capacity() * std::mem::size_of::<Option<Arc<Tile>>>()
    }
}

/// Position of cell `(cx, cy)` inside its tile's flat array.
#[inline]
pub(crate) fn local_index(cx: i32, cy: i32) -> usize {
    (((cy & TILE_MASK) as usize) << TILE_BITS) | (cx & TILE_MASK) as usize
}

/// New inclusive tile span covering the old span `t0..t0+n` and `lo..=hi`.
fn grown_span(t0: i32, n: usize, lo: i32, hi: i32, empty: bool) -> (i32, i32) {
    if empty {
        return (lo - 1, hi + 1);
    }
    let old_hi = t0 + n as i32 - 1;
    let margin = (n / 2) as i32 + 1;
    let new_lo = if lo < t0 { lo - margin } else { t0 };
    let new_hi = if hi > old_hi { hi + margin } else { old_hi };
    (new_lo, new_hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn growth_keeps_values_and_negative_cells_work() {
        let mut store = TileStore::default();
        assert_eq!(store.get(0, 0), None);
        *store.cell_mut(3, -5).unwrap() = 1.5;
        *store.cell_mut(-700, 900).unwrap() = -2.0;
        *store.cell_mut(10_000, -10_000).unwrap() = 0.25;
        assert_eq!(store.get(3, -5), Some(1.5));
        assert_eq!(store.get(-700, 900), Some(-2.0));
        assert_eq!(store.get(10_000, -10_000), Some(0.25));
        assert_eq!(store.get(4, -5), Some(0.0));
        assert_eq!(store.tiles().count(), 3);
    }

    #[test]
    fn rows_within_one_tile() {
        let mut store = TileStore::default();
        *store.cell_mut(-3, 70).unwrap() = 1.0;
        *store.cell_mut(-1, 70).unwrap() = 2.0;
        assert_eq!(store.row(-4, 70, 4), Some(&[0.0, 1.0, 0.0, 2.0][..]));
        // Crossing a tile border or outside the index: no slice.
        assert_eq!(store.row(-2, 70, 4), None);
        assert_eq!(store.row(-4, 10_000, 4), None);
        // An unallocated tile inside the index reads as zeros.
        *store.cell_mut(200, 70).unwrap() = 1.0;
        assert_eq!(store.row(64, 70, 3), Some(&[0.0; 3][..]));
    }

    #[test]
    fn clones_share_tiles_until_written() {
        let mut a = TileStore::default();
        *a.cell_mut(0, 0).unwrap() = 1.0;
        *a.cell_mut(200, 0).unwrap() = 1.0;
        let mut b = a.clone();
        *b.cell_mut(1, 1).unwrap() = 2.0;
        let shared = a
            .tiles()
            .zip(b.tiles())
            .filter(|((_, x), (_, y))| Arc::ptr_eq(x, y))
            .count();
        assert_eq!(shared, 1);
        assert_eq!(a.get(1, 1), Some(0.0));
        assert_eq!(b.get(1, 1), Some(2.0));
        assert_eq!(b.get(0, 0), Some(1.0));
    }

    #[test]
    fn repeated_growth_is_amortised() {
        let mut store = TileStore::default();
        let mut reallocations = 0;
        for i in 0..1000 {
            let before = store.width;
            *store.cell_mut(i * TILE_SIZE as i32, 0).unwrap() = 1.0;
            reallocations += usize::from(store.width != before);
        }
        assert!(reallocations < 20, "{reallocations} reallocations");
    }
}
