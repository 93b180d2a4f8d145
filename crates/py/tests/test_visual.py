"""Cameras from Python: a VisualSlam session over KITTI 06 (stereo) gives `slamkit vo`'s
trajectory and accuracy, and a `vo --record` of 7-Scenes opens in the MCAP project's reader."""

import base64
import io
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


def test_recording_of_7_scenes_opens_in_an_independent_mcap_reader(data, cli, tmp_path,
                                                                   read_recording):
    """`vo --slam --record` as Foxglove would read it, through the MCAP project's own Python
    reader: every channel with its Foxglove schema, counts equal to the run's, log times in
    order, every frame's image a JPEG of the camera's size, the last path the (loop-closed)
    trajectory, the map the run's point cloud."""
    folder = data / "rgbd" / "7scenes_redkitchen_frames_0000-0599"
    out, recording = tmp_path / "vo", tmp_path / "7scenes.mcap"
    cli("vo", folder, "--slam", "--out", out, "--record", recording)
    report = json.loads((out / "report.json").read_text())
    trajectory, _ = slamkit.read_trajectory(out / "trajectory.tum")

    schemas = {"/camera/image": "foxglove.CompressedImage", "/pose": "foxglove.PoseInFrame",
               "/tf": "foxglove.FrameTransform", "/path": "foxglove.PosesInFrame",
               "/map": "foxglove.PointCloud"}
    counts, first, last = read_recording(recording, schemas)
    assert counts == report["recording"]["messages"]
    assert counts["/camera/image"] == report["frames"]["read"] == 600
    assert counts["/pose"] == counts["/tf"] == len(trajectory)

    image = json.loads(first["/camera/image"].data)
    jpeg = base64.b64decode(image["data"])
    assert image["format"] == "jpeg" and jpeg[:2] == b"\xff\xd8"
    pil = pytest.importorskip("PIL.Image")
    assert pil.open(io.BytesIO(jpeg)).size == (640, 480)

    path = json.loads(last["/path"].data)["poses"]
    positions = np.array([[p["position"][k] for k in "xyz"] for p in path])
    assert positions.shape == (len(trajectory), 3)
    assert np.abs(positions - trajectory[:, 1:4]).max() < 1e-6

    cloud = json.loads(last["/map"].data)
    assert [f["name"] for f in cloud["fields"]] == ["x", "y", "z", "red", "green", "blue", "alpha"]
    points = len(base64.b64decode(cloud["data"])) // cloud["point_stride"]
    header = (out / "cloud.ply").read_bytes()[:400].decode("ascii", "replace")
    assert f"element vertex {points}\n" in header
