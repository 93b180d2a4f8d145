//! slamkit-map: 2D occupancy grids and the sensor models that read them.
//!
//! * [`occupancy_grid`]: log-odds occupancy grid with clamping, Bresenham ray tracing of laser
//!   scans and copy-on-write tiles so particle-filter maps share memory.
//! * [`likelihood_field`]: Euclidean distance transform and the likelihood-field sensor model
//!   that scores a scan against a map (particle-filter SLAM, Monte Carlo localisation).
//! * [`grid_io`]: ROS `map_server` maps (PGM + YAML) and PNG images, both ways.
//! * [`octree`]: 3D occupancy octree with OctoMap's semantics and `.bt` export.
//! * [`tri_grid`]: dense tri-state grids for planners, and inflation by the robot's radius.
//! * [`floor`]: the floor plane (RANSAC or three image regions) and the floor-aligned map frame
//!   (Rodrigues' rotation).
//! * [`floor_grid`]: 2D grids from 3D points in a height band, by point count or log-odds.
//! * [`raycast`]: Bresenham ray traversal between grid cells (Bresenham 1965).
//! * [`distance_transform`]: exact Euclidean distance transform of a binary image
//!   (Felzenszwalb & Huttenlocher 2012), under the likelihood field.
//! * [`error`]: [`MapError`] and [`MapFileError`].
//!
//! Frames: the grid lives in the world frame (x, y in metres, cell (0, 0) at the grid origin);
//! scans are inserted with the laser's pose `world_from_laser`.

pub mod distance_transform;
pub mod error;
pub mod floor;
pub mod floor_grid;
pub mod grid_io;
pub mod likelihood_field;
pub mod occupancy_grid;
pub mod octree;
pub mod raycast;
mod tiles;
pub mod tri_grid;

#[cfg(test)]
mod test_room;

pub use error::{MapError, MapFileError};
pub use grid_io::{load_map_yaml, save_grid_files, save_map_yaml, save_png, MapYaml};
pub use likelihood_field::{LikelihoodField, LikelihoodFieldConfig};
pub use occupancy_grid::{
    shared_tile_stats, CellBounds, CellIndex, InsertStats, Occupancy, OccupancyGrid,
    OccupancyGridConfig, TileStats,
};
pub use octree::{Octree, OctreeConfig, OctreeInsertStats, OctreeLeaf, OctreeStats};
pub use tiles::{MAX_INDEX_TILES, TILE_SIZE};
pub use tri_grid::TriGrid;
