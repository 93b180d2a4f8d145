//! slamkit-lidar: 2D scan matching, ICP-SLAM, particle-filter SLAM and localisation.
