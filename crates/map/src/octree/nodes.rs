//! Node storage of the octree: nodes live in blocks of eight siblings inside one vector.
//!
//! A node is 8 bytes, its log-odds (`f32`) and the index of its first child (`u32`, or
//! [`NO_CHILDREN`]); the eight children of a node sit side by side, and a child that does not
//! exist holds NaN. OctoMap keeps a heap-allocated array of eight child pointers per inner node
//! plus a 16-byte node; the block layout needs neither pointers nor per-node allocations, and
//! freed blocks (pruning) are reused.

/// First-child index of a node without children.
pub const NO_CHILDREN: u32 = u32::MAX;
/// Node index of the root (slot 0 of block 0; the block's other slots stay empty).
pub const ROOT: u32 = 0;

/// Blocks of eight sibling nodes; see the module documentation.
#[derive(Debug, Clone)]
pub struct NodePool {
    values: Vec<f32>,
    children: Vec<u32>,
    free_blocks: Vec<u32>,
}

impl NodePool {
    /// A pool holding only the root, with log-odds `root_value` (NaN: no root yet).
    pub fn new(root_value: f32) -> Self {
        let mut values = vec![f32::NAN; 8];
        values[0] = root_value;
        Self {
            values,
            children: vec![NO_CHILDREN; 8],
            free_blocks: Vec::new(),
        }
    }

    /// Log-odds of `node` (NaN when the node does not exist).
    #[inline]
    pub fn value(&self, node: u32) -> f32 {
        self.values[node as usize]
    }

    /// Sets the log-odds of `node`.
    #[inline]
    pub fn set_value(&mut self, node: u32, value: f32) {
        self.values[node as usize] = value;
    }

    /// Index of the first of `node`'s eight child slots, or [`NO_CHILDREN`].
    #[inline]
    pub fn first_child(&self, node: u32) -> u32 {
        self.children[node as usize]
    }

    /// Whether the node exists.
    #[inline]
    pub fn exists(&self, node: u32) -> bool {
        !self.values[node as usize].is_nan()
    }

    /// Gives `node` eight child slots, all empty, and returns the first.
    pub fn add_children(&mut self, node: u32) -> u32 {
        let first = match self.free_blocks.pop() {
            Some(first) => first,
            None => {
                let first = self.values.len() as u32;
                self.values.resize(self.values.len() + 8, f32::NAN);
                self.children.resize(self.children.len() + 8, NO_CHILDREN);
                first
            }
        };
        self.children[node as usize] = first;
        first
    }

    /// Removes `node`'s children (which must have none themselves) and frees their block.
    pub fn drop_children(&mut self, node: u32) {
        let first = self.children[node as usize];
        if first == NO_CHILDREN {
            return;
        }
        self.values[first as usize..first as usize + 8].fill(f32::NAN);
        self.children[node as usize] = NO_CHILDREN;
        self.free_blocks.push(first);
    }

    /// Collapses `node` when its eight children all exist, have no children and hold the same
    /// value (OctoMap's `pruneNode`); otherwise sets its value to the largest child's
    /// (`updateOccupancyChildren`). Returns whether it collapsed. `node` must have children.
    pub fn prune_or_update(&mut self, node: u32) -> bool {
        let first = self.children[node as usize] as usize;
        let values = &self.values[first..first + 8];
        let leaves = self.children[first..first + 8]
            .iter()
            .all(|&c| c == NO_CHILDREN);
        let v0 = values[0];
        if leaves && values.iter().all(|&v| v == v0) {
            self.drop_children(node);
            self.values[node as usize] = v0;
            return true;
        }
        let max = values
            .iter()
            .filter(|v| !v.is_nan())
            .fold(f32::MIN, |m, &v| if v > m { v } else { m });
        self.values[node as usize] = max;
        false
    }

    /// Bytes held by the node arrays and the free list.
    pub fn bytes(&self) -> usize {
        self.values.capacity() * 4 + self.children.capacity() * 4 + self.free_blocks.capacity() * 4
    }

    /// Nodes that exist.
    pub fn count_existing(&self) -> usize {
        self.values.iter().filter(|v| !v.is_nan()).count()
    }

    /// Sets every existing node to `f(value)`.
    pub fn map_values(&mut self, f: impl Fn(f32) -> f32) {
        for v in self.values.iter_mut().filter(|v| !v.is_nan()) {
            *v = f(*v);
        }
    }
}
