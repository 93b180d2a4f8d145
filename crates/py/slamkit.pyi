"""slamkit: SLAM for small robots (2D lidar, drone and visual SLAM sessions, map files, metrics).

Trajectories are (N, 8) float64 arrays of TUM rows: ``t x y z qx qy qz qw``. Heavy work runs
with the GIL released. Every error is a :class:`SlamkitError` whose message is the CLI's line.
"""

from os import PathLike
from typing import Any, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, PathLike]
_Trajectory = npt.NDArray[np.float64]

__version__: str
DEFAULT_MAX_DIFF_S: float

class SlamkitError(Exception):
    """A file that cannot be read, bad settings, a failed run."""

# --- trajectories and metrics -------------------------------------------------------------

def read_trajectory(path: _Path) -> Tuple[_Trajectory, str]:
    """Reads a TUM, KITTI or EuRoC CSV trajectory (told from its content): (array, format)."""

def read_relations(path: _Path) -> npt.NDArray[np.float64]:
    """Reads a ``.relations`` file: (M, 8) rows ``t1 t2 x y z roll pitch yaw`` (radians)."""

def ate(
    reference: _Trajectory,
    estimate: _Trajectory,
    align: str = "se3",
    max_diff: float = ...,
    pairing: str = "time",
) -> dict[str, Any]:
    """Absolute trajectory error after ``align`` ("se3", "sim3", "none"), as evo_ape computes it.

    Returns ``rmse, mean, median, std, min, max, sse, pairs`` and the per-pair ``errors`` and
    ``timestamps`` arrays. ``pairing`` is "time" (nearest within ``max_diff`` s) or "index".
    """

def rpe(
    reference: _Trajectory,
    estimate: _Trajectory,
    delta: float = 1.0,
    unit: str = "frames",
    all_pairs: bool = False,
    max_diff: float = ...,
    pairing: str = "time",
) -> dict[str, Any]:
    """Relative pose error over ``delta`` ("frames" or "m"), as evo_rpe computes it."""

def relations_error(relations: _Path, estimate: _Trajectory) -> dict[str, Any]:
    """The relations metric (Kümmerle et al. 2009): ``trans_mean`` [m], ``rot_mean_deg``, ..."""

# --- maps ----------------------------------------------------------------------------------

class Grid:
    """An occupancy grid: ``data[j, i]`` (int8: -1 unknown, 0 free, 100 occupied) is the cell
    whose lower-left corner is ``origin + (i, j) * resolution``."""

    data: npt.NDArray[np.int8]
    resolution: float
    origin: Tuple[float, float]

class Map:
    """A ``.skmap`` file, read and checked (magic, version, checksum) when opened."""

    def __init__(self, path: _Path) -> None: ...
    @property
    def rig(self) -> str:
        """"lidar2d", "drone", "rgbd" or "stereo"."""
    def info(self) -> dict[str, Any]:
        """What ``slamkit map info --json`` prints."""
    def grid(self) -> Optional[Grid]:
        """The grid a robot plans in; None for a camera map without one."""
    def export(self, out: _Path) -> list[str]:
        """Writes PGM/YAML, PNG, PLY and TUM files into the folder ``out``; their names."""

# --- 2D lidar ------------------------------------------------------------------------------

class LidarLog:
    """The laser scans (with odometry) of a log."""

    description: Optional[str]
    """What was read from a bag (topics, counts, mounting); None for a CARMEN log."""
    warnings: list[str]
    """Damage worth a warning: timestamps stepping back, a tilted laser, skipped messages."""
    def __len__(self) -> int: ...
    def slice(self, start: int, stop: int) -> "LidarLog":
        """The scans ``start..stop`` as a log of their own."""
    def timestamps(self) -> npt.NDArray[np.float64]: ...
    def odometry(self) -> npt.NDArray[np.float64]:
        """(N, 3) rows ``x y yaw``; NaN where a scan has no odometry."""
    def scan(self, index: int) -> dict[str, Any]:
        """``timestamp, angle_min, angle_increment, ranges, max_range, odometry, base_from_laser``."""

def read_carmen(path: _Path) -> LidarLog:
    """Reads a CARMEN log (plain or gzip)."""

def read_lidar_log(
    path: _Path, scan_topic: Optional[str] = None, odom_topic: Optional[str] = None
) -> LidarLog:
    """A CARMEN log or a ROS 1 / ROS 2 bag (``.bag``, MCAP, ``.db3``, or a ROS 2 bag folder);
    topics found by type when there is one of each; the laser's mounting from ``/tf_static``."""

def bag_info(path: _Path) -> dict[str, Any]:
    """``slamkit bag info --json``: ``format, topics`` (``topic, message_type, messages, ...``),
    ``messages, start_s, end_s, duration_s, ...``."""

class LidarSlam:
    """2D lidar SLAM: ``method`` "icp" (ICP-SLAM) or "rbpf" (particle filter)."""

    def __init__(
        self,
        method: str = "icp",
        particles: Optional[int] = None,
        seed: Optional[int] = None,
        profile: Optional[str] = None,
        config: Optional[_Path] = None,
    ) -> None: ...
    @staticmethod
    def localise(
        map: _Path, profile: Optional[str] = None, config: Optional[_Path] = None
    ) -> "LidarSlam":
        """Localisation in a saved map (not changed); the start pose is found by global search."""
    @staticmethod
    def resume(
        map: _Path, profile: Optional[str] = None, config: Optional[_Path] = None
    ) -> "LidarSlam":
        """Continues a saved map once the robot is found in it."""
    def push_scan(
        self,
        timestamp: float,
        ranges: npt.NDArray[np.float64],
        angle_min: float,
        angle_increment: float,
        max_range: float,
        odometry: Optional[Tuple[float, float, float]] = None,
        base_from_laser: Tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> dict[str, Any]:
        """One scan in; the update out: ``timestamp, pose, status, keyframes_added, ...``."""
    def run(self, log: LidarLog) -> int:
        """Pushes every scan of ``log``; returns how many."""
    def trajectory(self) -> _Trajectory: ...
    def stats(self) -> dict[str, Any]: ...
    def config(self) -> dict[str, Any]: ...
    def grid(self) -> Grid: ...
    def save(self, path: _Path) -> None:
        """Writes the map as a ``.skmap`` file, atomically."""

# --- drone -------------------------------------------------------------------------------

class DroneSlam:
    """Layered 2D lidar SLAM for a drone, the layers switched by up/down range finders; with
    ``particles``, the particle filter on the layered increments too."""

    def __init__(
        self,
        particles: Optional[int] = None,
        seed: Optional[int] = None,
        profile: Optional[str] = None,
        config: Optional[_Path] = None,
    ) -> None: ...
    @staticmethod
    def localise(
        map: _Path, profile: Optional[str] = None, config: Optional[_Path] = None
    ) -> "DroneSlam":
        """Localisation in a drone's saved map (not changed), found by global search."""
    @staticmethod
    def resume(
        map: _Path, profile: Optional[str] = None, config: Optional[_Path] = None
    ) -> "DroneSlam":
        """Continues a drone's saved map once the drone is found in it."""
    def push_scan(
        self,
        timestamp: float,
        ranges: npt.NDArray[np.float64],
        angle_min: float,
        angle_increment: float,
        max_range: float,
        odometry: Optional[Tuple[float, float, float]] = None,
        base_from_laser: Tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> dict[str, Any]:
        """One scan in (push the readings up to its time first); the update out:
        ``timestamp, pose, height, layer, status, keyframes_added, ...``."""
    def push_range(
        self, timestamp: float, up: Optional[float] = None, down: Optional[float] = None
    ) -> None:
        """Distances to the ceiling (up) and the floor (down) [m]; None: no reading."""
    def push_attitude(
        self, timestamp: float, roll: float, pitch: float, gyro_yaw: Optional[float] = None
    ) -> None:
        """Roll and pitch [rad] and the gyro's integrated heading (any origin)."""
    def push_flow(
        self,
        timestamp: float,
        integration: float,
        velocity: Optional[Tuple[float, float]] = None,
    ) -> None:
        """Optical flow: mean body-frame velocity (forward, left) [m/s] over ``integration`` s."""
    def run(
        self,
        log: LidarLog,
        ranges: _Path,
        imu: Optional[_Path] = None,
        flow: Optional[_Path] = None,
    ) -> dict[str, int]:
        """A recorded flight: ``log``'s scans with the CSV files; the readings per file."""
    def trajectory(self) -> _Trajectory: ...
    def pf_trajectory(self) -> Optional[_Trajectory]: ...
    def layers(self) -> list[dict[str, Any]]:
        """``layer, z_range, scans`` of every height layer mapped."""
    def grid(self, layer: Optional[int] = None) -> Grid:
        """One layer's grid, or every layer's with None."""
    def stats(self) -> dict[str, Any]: ...
    def save(self, path: _Path) -> None:
        """Writes the map as a ``.skmap`` file, atomically."""

# --- cameras -------------------------------------------------------------------------------

class Dataset:
    """An RGB-D or stereo folder, or an RGB-D camera's bag: ``format`` "tum", "kitti",
    "7scenes", "redwood", "euroc", "rosbag" or None (told from the path)."""

    def __init__(
        self,
        path: _Path,
        format: Optional[str] = None,
        rgb_topic: Optional[str] = None,
        depth_topic: Optional[str] = None,
        camera_info_topic: Optional[str] = None,
    ) -> None: ...
    def __len__(self) -> int: ...
    def ground_truth(self) -> Optional[_Trajectory]: ...

class VisualSlam:
    """Visual odometry (``slam=True``: with loop closure) for a dataset's camera rig."""

    def __init__(
        self,
        dataset: Dataset,
        frontend: str = "klt",
        profile: Optional[str] = None,
        config: Optional[_Path] = None,
        slam: bool = False,
    ) -> None: ...
    def run(self, dataset: Dataset) -> dict[str, Any]:
        """Runs over every frame; the frame counts."""
    def trajectory(self) -> _Trajectory: ...
    def save(self, path: _Path) -> None: ...
