//! slamkit-map: occupancy grids, octrees and point maps.
