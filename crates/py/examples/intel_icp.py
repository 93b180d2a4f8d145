"""ICP-SLAM on the Intel Research Lab log from Python, scored as the CLI scores it.

    python crates/py/examples/intel_icp.py $SLAMKIT_DATA/lidar2d/intel OUT_DIR

Runs a ``slamkit.LidarSlam`` session over the log, prints the relations metric (the same
number ``slamkit lidar`` prints), saves the map and the trajectory, and scores the wheel
odometry against the SLAM trajectory twice, with ``slamkit.ate`` and with evo's Python API
(evo is optional: ``pip install evo``). The two ATEs agree to 1e-6 m.
"""

import pathlib
import sys

import numpy as np

import slamkit


def odometry_as_tum(log: slamkit.LidarLog) -> np.ndarray:
    """The log's wheel odometry as an (N, 8) TUM array (z = 0, rotation about z)."""
    xy_yaw = log.odometry()
    keep = np.isfinite(xy_yaw).all(axis=1)
    t, (x, y, yaw) = log.timestamps()[keep], xy_yaw[keep].T
    zero = np.zeros_like(x)
    return np.column_stack((t, x, y, zero, zero, zero, np.sin(yaw / 2), np.cos(yaw / 2)))


def evo_ate(reference: np.ndarray, estimate: np.ndarray) -> float:
    """evo_ape's translation RMSE after SE(3) alignment, through evo's Python API."""
    from evo.core import metrics, sync
    from evo.core.trajectory import PoseTrajectory3D

    def trajectory(rows: np.ndarray) -> PoseTrajectory3D:
        return PoseTrajectory3D(
            positions_xyz=rows[:, 1:4],
            orientations_quat_wxyz=rows[:, [7, 4, 5, 6]],
            timestamps=rows[:, 0],
        )

    ref, est = sync.associate_trajectories(trajectory(reference), trajectory(estimate), max_diff=0.01)
    est.align(ref, correct_scale=False)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    return float(ape.get_statistic(metrics.StatisticsType.rmse))


def main(folder: pathlib.Path, out: pathlib.Path) -> dict:
    log = slamkit.read_carmen(folder / "intel.fromrosbag.clf.gz")
    slam = slamkit.LidarSlam()  # ICP-SLAM at the defaults, as `slamkit lidar`
    slam.run(log)
    trajectory = slam.trajectory()
    relations = slamkit.relations_error(folder / "intel.relations", trajectory)
    print(f"{len(log)} scans; relations error {relations['trans_mean']:.4f} m "
          f"over {relations['count']} relations")

    out.mkdir(parents=True, exist_ok=True)
    slam.save(out / "intel.skmap")
    np.savetxt(out / "trajectory.tum", trajectory, fmt="%.9f")

    odometry = odometry_as_tum(log)
    ours = slamkit.ate(trajectory, odometry)["rmse"]
    print(f"wheel odometry against the SLAM trajectory: ATE {ours:.6f} m (slamkit)")
    result = {"relations": relations, "trajectory": trajectory, "ate_slamkit": ours}
    try:
        theirs = evo_ate(trajectory, odometry)
    except ImportError:
        return result
    print(f"wheel odometry against the SLAM trajectory: ATE {theirs:.6f} m (evo)")
    result["ate_evo"] = theirs
    return result


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: intel_icp.py INTEL_FOLDER OUT_DIR")
    main(pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]))
