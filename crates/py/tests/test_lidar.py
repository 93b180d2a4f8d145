"""2D lidar from Python: the Intel example gives the CLI's trajectory and relations metric, the
map it saves opens as the CLI reads it, and a saved map localises a robot again."""

import base64
import importlib.util
import json
import pathlib

import numpy as np
import pytest

import slamkit

EXAMPLE = pathlib.Path(__file__).parents[1] / "examples" / "intel_icp.py"


def load_example():
    spec = importlib.util.spec_from_file_location("intel_icp", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def intel(data, cli, tmp_path_factory):
    """The example's run and the CLI's run on the Intel log."""
    folder = data / "lidar2d" / "intel"
    out = tmp_path_factory.mktemp("intel")
    example = load_example().main(folder, out / "python")
    # recorded, which must not change the run: the comparisons below would see it
    cli("lidar", folder / "intel.fromrosbag.clf.gz", "--out", out / "cli",
        "--record", out / "intel.mcap")
    report = json.loads((out / "cli" / "report.json").read_text())
    cli_trajectory, _ = slamkit.read_trajectory(out / "cli" / "trajectory.tum")
    return {"folder": folder, "out": out, "example": example, "report": report,
            "cli_trajectory": cli_trajectory, "recording": out / "intel.mcap"}


def test_recording_opens_in_an_independent_mcap_reader(intel, read_recording):
    """`--record` as Foxglove would read it, through the MCAP project's own Python reader: every
    channel with its Foxglove schema, counts equal to the run's, log times in order, the last
    pose the trajectory's last, the last map a valid grid."""
    report = intel["report"]
    schemas = {"/scan": "foxglove.LaserScan", "/pose": "foxglove.PoseInFrame",
               "/tf": "foxglove.FrameTransform", "/map": "foxglove.Grid",
               "/path": "foxglove.PosesInFrame"}
    counts, _, last = read_recording(intel["recording"], schemas)
    assert counts == report["recording"]["messages"]
    assert counts["/scan"] == report["frames"]["read"]
    poses = intel["cli_trajectory"]
    assert counts["/pose"] == counts["/tf"] == len(poses)

    pose = json.loads(last["/pose"].data)["pose"]
    position = [pose["position"][k] for k in "xyz"]
    assert np.abs(np.array(position) - poses[-1, 1:4]).max() < 1e-6
    path = json.loads(last["/path"].data)["poses"]
    assert len(path) == len(poses)

    grid = json.loads(last["/map"].data)
    cells = np.frombuffer(base64.b64decode(grid["data"]), dtype=np.int8)
    assert grid["fields"] == [{"name": "occupancy", "offset": 0, "type": 2}]
    assert cells.size % grid["column_count"] == 0 and cells.size > 100_000
    assert set(np.unique(cells)) <= {-1, 0, 100}
    assert (cells == 100).sum() > 1000 and (cells == 0).sum() > (cells == 100).sum()


def test_intel_example_gives_the_cli_result(intel):
    ours, theirs = intel["example"]["trajectory"], intel["cli_trajectory"]
    assert ours.shape == theirs.shape
    # trajectory.tum holds 6-9 decimals; the runs themselves are the same computation
    assert np.abs(ours[:, :4] - theirs[:, :4]).max() < 1e-6
    relations = intel["example"]["relations"]
    printed = intel["report"]["metrics"]["relations"]
    assert relations["count"] == printed["count"]
    # the same poses, but through an array: quaternions normalised again, last-digit changes
    assert relations == pytest.approx(printed, rel=1e-12)
    assert relations["trans_mean"] < 0.02  # the benchmark's bound for ICP-SLAM on Intel


def test_intel_ate_equals_evo(intel):
    pytest.importorskip("evo")
    example = intel["example"]
    assert example["ate_slamkit"] > 0.1  # wheel odometry drifts by metres on Intel
    assert example["ate_slamkit"] == pytest.approx(example["ate_evo"], abs=1e-6)


def test_saved_map_opens_and_localises(intel, cli):
    path = intel["out"] / "python" / "intel.skmap"
    saved = slamkit.Map(path)
    assert saved.rig == "lidar2d"
    info = saved.info()
    printed = json.loads(cli("map", "info", path, "--json").stdout)
    for key in ("rig", "format_version", "keyframes", "edges", "scans", "extent_m", "file_bytes"):
        assert info[key] == printed[key], key
    assert info["file_bytes"] < 3_000_000  # the map file's size target for Intel
    grid = saved.grid()
    assert grid.data.dtype == np.int8 and grid.data.ndim == 2
    assert set(np.unique(grid.data)) <= {-1, 0, 100}
    occupied, free = (grid.data == 100).sum(), (grid.data == 0).sum()
    assert occupied > 1000 and free > occupied  # walls, and the rooms between them
    assert grid.resolution > 0

    # the first 400 scans again, in the saved map, from an unknown start
    log = slamkit.read_carmen(intel["folder"] / "intel.fromrosbag.clf.gz")
    session = slamkit.LidarSlam.localise(path)
    statuses = []
    for i in range(400):
        s = log.scan(i)
        update = session.push_scan(s["timestamp"], s["ranges"], s["angle_min"],
                                   s["angle_increment"], s["max_range"], s["odometry"],
                                   s["base_from_laser"])
        statuses.append(update["status"])
    assert "tracking" in statuses
    found = session.stats()["session"]["first_fix_scan"]
    assert found is not None and found < 300
    # where it is found, it agrees with the mapping run
    mapped = intel["example"]["trajectory"]
    localised = session.trajectory()
    last = localised[-1]
    row = mapped[np.argmin(np.abs(mapped[:, 0] - last[0]))]
    assert np.hypot(*(last[1:3] - row[1:3])) < 0.1


def test_push_scan_equals_run(intel):
    log = slamkit.read_carmen(intel["folder"] / "intel.fromrosbag.clf.gz")
    one_by_one = slamkit.LidarSlam()
    for i in range(200):
        s = log.scan(i)
        one_by_one.push_scan(s["timestamp"], s["ranges"], s["angle_min"], s["angle_increment"],
                             s["max_range"], s["odometry"], s["base_from_laser"])
    whole = slamkit.LidarSlam()
    assert whole.run(log.slice(0, 200)) == 200
    # odometry and mounting cross as (x, y, yaw): the rotations rebuilt from the angle differ
    # in the last bit, nothing more
    np.testing.assert_allclose(one_by_one.trajectory(), whole.trajectory(), rtol=0, atol=1e-12)
    with pytest.raises(IndexError):
        log.slice(0, len(log) + 1)


def test_bad_input_gives_one_line_errors(tmp_path):
    with pytest.raises(slamkit.SlamkitError, match="method must be"):
        slamkit.LidarSlam(method="gmapping")
    with pytest.raises(slamkit.SlamkitError, match="no-such-robot"):
        slamkit.LidarSlam(profile="no-such-robot")
    broken = tmp_path / "broken.skmap"
    broken.write_bytes(b"\x89SKMAP\r\n" + b"\x01" * 40)
    with pytest.raises(slamkit.SlamkitError) as error:
        slamkit.Map(broken)
    assert "broken.skmap" in str(error.value) and "\n" not in str(error.value)
    with pytest.raises(slamkit.SlamkitError, match="broken.skmap"):
        slamkit.LidarSlam.localise(broken)
    with pytest.raises(slamkit.SlamkitError):
        slamkit.read_carmen(tmp_path / "missing.clf")
