"""The drone from Python: `DroneSlam` on a simulated flight's recording gives the CLI's
trajectory, whether it runs the recording whole or takes it reading by reading; its layers,
grids and saved map are those of a drone; and the bag readers read the real ROS 1 bag."""

import csv
import json
import math

import numpy as np
import pytest

import slamkit


@pytest.fixture(scope="module")
def flight(cli, tmp_path_factory):
    """The first minute of a simulated flight through the `small` world (CARMEN log and CSV
    files) and the CLI's run of the drone session on it."""
    out = tmp_path_factory.mktemp("drone")
    rec = out / "rec"
    cli("sim", "--world", "small", "--sensors", "lidar2d,range,imu,flow", "--seed", "1",
        "--duration", "60", "--out", rec)
    files = {"log": rec / "lidar.clf", "ranges": rec / "ranges.csv", "imu": rec / "imu.csv",
             "flow": rec / "flow.csv"}
    cli("lidar", files["log"], "--ranges", files["ranges"], "--imu", files["imu"],
        "--flow", files["flow"], "--out", out / "cli")
    trajectory, _ = slamkit.read_trajectory(out / "cli" / "trajectory.tum")
    report = json.loads((out / "cli" / "report.json").read_text())
    return {"out": out, "files": files, "trajectory": trajectory, "report": report}


def number(text: str):
    """A CSV field as slamkit reads it: empty, nan or inf is no reading."""
    value = float(text) if text.strip() else math.nan
    return value if math.isfinite(value) else None


def test_a_recorded_flight_gives_the_cli_trajectory(flight, tmp_path):
    f = flight["files"]
    session = slamkit.DroneSlam()
    counts = session.run(slamkit.read_lidar_log(f["log"]), f["ranges"], f["imu"], f["flow"])
    assert counts == flight["report"]["readings"]
    ours, theirs = session.trajectory(), flight["trajectory"]
    assert ours.shape == theirs.shape
    assert np.abs(ours[:, :4] - theirs[:, :4]).max() < 1e-6  # the file holds 6-9 decimals
    assert session.pf_trajectory() is None  # no particles asked for

    layers = session.layers()
    assert len(layers) == len(flight["report"]["layers"]) >= 2
    assert [l["scans"] for l in layers] == [l["scans"] for l in flight["report"]["layers"]]
    whole, first = session.grid(), session.grid(layers[0]["layer"])
    for grid in (whole, first):
        assert set(np.unique(grid.data)) <= {-1, 0, 100}
        assert (grid.data == 100).sum() > 100 and (grid.data == 0).sum() > (grid.data == 100).sum()
    assert (whole.data == 100).sum() >= (first.data == 100).sum()
    with pytest.raises(KeyError):
        session.grid(999)
    stats = session.stats()
    assert stats["frames"]["processed"] == flight["report"]["frames"]["processed"]

    session.save(tmp_path / "drone.skmap")
    assert slamkit.Map(tmp_path / "drone.skmap").rig == "drone"


def test_reading_by_reading_gives_the_whole_runs_trajectory(flight):
    """Every reading pushed in time order (at equal times the readings before the scan, as
    the session's own merge orders them) gives what `run` gives."""
    f = flight["files"]
    log = slamkit.read_lidar_log(f["log"])
    events = []
    with open(f["ranges"]) as file:
        for row in csv.DictReader(file):
            events.append((float(row["timestamp"]), 0, "range",
                           (number(row["up_m"]), number(row["down_m"]))))
    with open(f["imu"]) as file:
        for row in csv.DictReader(file):
            events.append((float(row["timestamp"]), 0, "imu",
                           (float(row["roll_rad"]), float(row["pitch_rad"]),
                            number(row["gyro_yaw_rad"]))))
    with open(f["flow"]) as file:
        for row in csv.DictReader(file):
            forward, left = number(row["forward_mps"]), number(row["left_mps"])
            velocity = None if forward is None or left is None else (forward, left)
            events.append((float(row["timestamp"]), 0, "flow",
                           (float(row["integration_s"]), velocity)))
    for i in range(len(log)):
        events.append((log.scan(i)["timestamp"], 1, "scan", i))
    events.sort(key=lambda e: (e[0], e[1]))  # stable: each file's order kept

    session, updates = slamkit.DroneSlam(), []
    for t, _, kind, value in events:
        if kind == "range":
            session.push_range(t, *value)
        elif kind == "imu":
            session.push_attitude(t, *value)
        elif kind == "flow":
            session.push_flow(t, *value)
        else:
            s = log.scan(value)
            updates.append(session.push_scan(t, s["ranges"], s["angle_min"], s["angle_increment"],
                                             s["max_range"], s["odometry"], s["base_from_laser"]))
    ours, theirs = session.trajectory(), flight["trajectory"]
    assert ours.shape == theirs.shape
    assert np.abs(ours[:, :4] - theirs[:, :4]).max() < 1e-6
    last = updates[-1]
    assert last["status"] == "tracking" and last["layer"] is not None
    assert abs(last["height"] - ours[-1, 3]) < 1e-9
    assert np.allclose(last["pose"][:2], ours[-1, 1:3], atol=1e-9)


def test_the_real_ros1_bag_reads_as_its_carmen_log(data):
    folder = data / "lidar2d" / "intel"
    bag = folder / "intel.clf.orig.bag"
    info = slamkit.bag_info(bag)
    topics = {t["topic"]: t for t in info["topics"]}
    assert topics["/scan"]["message_type"] == "sensor_msgs/LaserScan"
    assert info["duration_s"] > 0
    from_bag = slamkit.read_lidar_log(bag)
    carmen = slamkit.read_carmen(folder / "intel.fromrosbag.clf.gz")
    assert len(from_bag) == len(carmen) == topics["/scan"]["messages"]
    assert "/scan" in from_bag.description and carmen.description is None
    # the CARMEN text rounds the bag's float32 ranges to its printed digits
    a, b = from_bag.scan(100), carmen.scan(100)
    assert np.abs(a["ranges"] - b["ranges"]).max() < 1e-3
    with pytest.raises(slamkit.SlamkitError, match="topic"):
        slamkit.read_lidar_log(bag, scan_topic="/no_such_topic")
    with pytest.raises(slamkit.SlamkitError):
        slamkit.bag_info(folder / "intel.relations")
