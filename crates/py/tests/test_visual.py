"""Cameras from Python: a VisualSlam session over KITTI 06 (stereo) gives `slamkit vo`'s
trajectory and accuracy."""

import json

import numpy as np
import pytest

import slamkit


def test_kitti_equals_the_cli(data, cli, tmp_path):
    folder = data / "stereo" / "kitti_odometry_06_0000-0050"
    dataset = slamkit.Dataset(folder)
    assert len(dataset) == 51
    session = slamkit.VisualSlam(dataset)
    counts = session.run(dataset)
    assert counts["session"]["processed"] == 51
    ours = session.trajectory()

    cli("vo", folder, "--out", tmp_path)
    theirs, _ = slamkit.read_trajectory(tmp_path / "trajectory.tum")
    assert ours.shape == theirs.shape
    assert np.abs(ours[:, 1:4] - theirs[:, 1:4]).max() < 1e-6

    gt = dataset.ground_truth()
    ate = slamkit.ate(gt, ours, pairing="index")
    report = json.loads((tmp_path / "report.json").read_text())
    assert ate["rmse"] == pytest.approx(report["metrics"]["ate"]["rmse"], abs=1e-6)
    assert ate["rmse"] < 0.1

    session.save(tmp_path / "kitti.skmap")
    assert slamkit.Map(tmp_path / "kitti.skmap").rig == "stereo"


def test_bad_input_gives_one_line_errors(tmp_path):
    with pytest.raises(slamkit.SlamkitError, match="cannot tell the layout"):
        slamkit.Dataset(tmp_path)
    with pytest.raises(slamkit.SlamkitError):
        slamkit.Dataset(tmp_path, format="betamax")
