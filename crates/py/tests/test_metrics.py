"""Trajectory files and metrics from Python against evo's Python API and the CLI, on evo's own
test trajectories (real SLAM output and ground truth)."""

import json

import numpy as np
import pytest

import slamkit

evo_main_ape = pytest.importorskip("evo.core.metrics")
from evo.core import metrics, sync  # noqa: E402
from evo.tools import file_interface  # noqa: E402

PAIRS = [
    ("fr2_desk_groundtruth.txt", "fr2_desk_ORB.txt", "tum"),
    ("freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt", "tum"),
    ("V102_groundtruth.csv", "V102.txt", "euroc"),
]


def evo_trajectory(path, kind):
    if kind == "euroc":
        return file_interface.read_euroc_csv_trajectory(str(path))
    return file_interface.read_tum_trajectory_file(str(path))


@pytest.mark.parametrize("gt_name, est_name, kind", PAIRS)
@pytest.mark.parametrize("align", ["se3", "sim3"])
def test_ate_equals_evo_and_the_cli(data, cli, gt_name, est_name, kind, align):
    folder = data / "trajectories" / "evo_test_data"
    gt, _ = slamkit.read_trajectory(folder / gt_name)
    est, fmt = slamkit.read_trajectory(folder / est_name)
    ours = slamkit.ate(gt, est, align=align)

    ref, traj = sync.associate_trajectories(
        evo_trajectory(folder / gt_name, kind),
        file_interface.read_tum_trajectory_file(str(folder / est_name)),
        max_diff=slamkit.DEFAULT_MAX_DIFF_S,
    )
    traj.align(ref, correct_scale=(align == "sim3"))
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, traj))
    assert ours["pairs"] == len(ref.timestamps)
    assert ours["rmse"] == pytest.approx(ape.get_statistic(metrics.StatisticsType.rmse), abs=1e-6)
    assert ours["max"] == pytest.approx(ape.get_statistic(metrics.StatisticsType.max), abs=1e-6)
    assert len(ours["errors"]) == ours["pairs"]

    printed = cli("eval", "ate", "--gt", folder / gt_name, "--est", folder / est_name,
                  "--align", align, "--json")
    assert json.loads(printed.stdout)["rmse"] == pytest.approx(ours["rmse"], abs=1e-12)


def test_rpe_equals_evo(data):
    folder = data / "trajectories" / "evo_test_data"
    gt, _ = slamkit.read_trajectory(folder / "fr2_desk_groundtruth.txt")
    est, _ = slamkit.read_trajectory(folder / "fr2_desk_ORB.txt")
    ours = slamkit.rpe(gt, est, delta=1.0, unit="m", all_pairs=True)

    ref, traj = sync.associate_trajectories(
        file_interface.read_tum_trajectory_file(str(folder / "fr2_desk_groundtruth.txt")),
        file_interface.read_tum_trajectory_file(str(folder / "fr2_desk_ORB.txt")),
        max_diff=slamkit.DEFAULT_MAX_DIFF_S,
    )
    rpe = metrics.RPE(metrics.PoseRelation.translation_part, delta=1.0,
                      delta_unit=metrics.Unit.meters, all_pairs=True)
    rpe.process_data((ref, traj))
    assert ours["pairs"] == len(rpe.error)
    assert ours["rmse"] == pytest.approx(rpe.get_statistic(metrics.StatisticsType.rmse), abs=1e-6)


def test_trajectory_arrays_round_trip(tmp_path):
    rows = np.array([[0.0, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 2.0],
                     [0.1, 1.5, 2.0, 3.0, 0.0, 0.0, 1.0, 1.0]])
    path = tmp_path / "t.tum"
    np.savetxt(path, rows)
    read, fmt = slamkit.read_trajectory(path)
    assert fmt == "tum"
    # quaternions come back normalised, as the TUM reader normalises them
    assert read[0, 7] == pytest.approx(1.0)
    assert read[1, 6] == pytest.approx(np.sqrt(0.5))
    assert slamkit.ate(read, read, align="none")["rmse"] == pytest.approx(0.0, abs=1e-12)


def test_bad_input_gives_one_line_errors(tmp_path):
    with pytest.raises(slamkit.SlamkitError) as error:
        slamkit.read_trajectory(tmp_path / "missing.tum")
    assert "missing.tum" in str(error.value) and "\n" not in str(error.value)

    good = np.zeros((3, 8))
    good[:, 7] = 1.0
    with pytest.raises(slamkit.SlamkitError, match=r"estimate: an \(N, 8\) array"):
        slamkit.ate(good, np.zeros((3, 7)))
    bad = good.copy()
    bad[1, 2] = np.nan
    with pytest.raises(slamkit.SlamkitError, match="row 1: NaN is not a finite number"):
        slamkit.ate(good, bad)
    with pytest.raises(slamkit.SlamkitError, match="unit must be"):
        slamkit.rpe(good, good, unit="feet")
    with pytest.raises(slamkit.SlamkitError, match="max_diff must be"):
        slamkit.ate(good, good, max_diff=-1.0)
