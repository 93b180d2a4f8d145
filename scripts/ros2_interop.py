"""Interoperability of `slamkit ros2 lidar` with a DDS stack slamkit did not write.

Eclipse Cyclone DDS (PyPI `cyclonedds`) plays the first scans of the Intel log (its ROS 1 bag,
read by PyPI `rosbags`, in record-time order) as ROS 2 messages (`/scan`, `/odom`, `/tf_static`)
into `slamkit ros2 lidar` at a multiple of real time, and receives `/map`, `/tf` and `/pose`.
The same messages, written by `rosbags` into a ROS 1 bag, are the file run (`slamkit lidar`).
Checks: every scan processed (none dropped), `/map` a valid trinary OccupancyGrid in `map`,
the map saved on a `std_msgs/String` sent to `/slamkit/save_map`, and a second node localising
in the file run's map from an unknown start (the log from its 1000th scan),
`map -> odom` on `/tf` for every scan, one `/pose` per scan with the scan's stamp, and the
node's trajectory equal to the file run's within 1e-3 m. Measures the latency from writing a
scan to receiving its `/pose` (median, p95), as Cyclone sees it.

Run by scripts/ros2_interop.sh inside a network namespace holding only `lo`: nothing leaves the
machine. Prints one JSON summary line; exits non-zero when a check fails.
"""

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from cyclonedds.core import Listener, Qos, Policy
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float32, float64, int8, int32, sequence, uint32
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore


# ROS 2 message types as DDS sees them (rosidl's IDL names; final, XCDR1 as ROS 2 writes).
@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose = field(default_factory=Pose)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist = field(default_factory=Twist)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


@dataclass
class LaserScan(IdlStruct, typename="sensor_msgs::msg::dds_::LaserScan_"):
    header: Header = field(default_factory=Header)
    angle_min: float32 = 0.0
    angle_max: float32 = 0.0
    angle_increment: float32 = 0.0
    time_increment: float32 = 0.0
    scan_time: float32 = 0.0
    range_min: float32 = 0.0
    range_max: float32 = 0.0
    ranges: sequence[float32] = field(default_factory=list)
    intensities: sequence[float32] = field(default_factory=list)


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: sequence[TransformStamped] = field(default_factory=list)


@dataclass
class PoseWithCovarianceStamped(
    IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"
):
    header: Header = field(default_factory=Header)
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)


@dataclass
class MapMetaData(IdlStruct, typename="nav_msgs::msg::dds_::MapMetaData_"):
    map_load_time: Time = field(default_factory=Time)
    resolution: float32 = 0.0
    width: uint32 = 0
    height: uint32 = 0
    origin: Pose = field(default_factory=Pose)


@dataclass
class OccupancyGrid(IdlStruct, typename="nav_msgs::msg::dds_::OccupancyGrid_"):
    header: Header = field(default_factory=Header)
    info: MapMetaData = field(default_factory=MapMetaData)
    data: sequence[int8] = field(default_factory=list)


@dataclass
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str = ""


CHILDREN = []  # the slamkit processes started


def start(command, log):
    p = subprocess.Popen(command, stdout=open(log, "w"), stderr=subprocess.STDOUT)
    CHILDREN.append(p)
    return p


def header(h):
    return Header(Time(h.stamp.sec, h.stamp.nanosec), h.frame_id)


def vec(v, cls=Vector3):
    return cls(v.x, v.y, v.z)


def quat(q):
    return Quaternion(q.x, q.y, q.z, q.w)


def to_dds(msg, msgtype):
    """A ROS 1 message read by rosbags as the ROS 2 message Cyclone writes."""
    if msgtype == "sensor_msgs/msg/LaserScan":
        return LaserScan(
            header(msg.header), msg.angle_min, msg.angle_max, msg.angle_increment,
            msg.time_increment, msg.scan_time, msg.range_min, msg.range_max,
            [float(r) for r in msg.ranges], [float(i) for i in msg.intensities],
        )
    if msgtype == "nav_msgs/msg/Odometry":
        p, t = msg.pose, msg.twist
        return Odometry(
            header(msg.header), msg.child_frame_id,
            PoseWithCovariance(Pose(vec(p.pose.position, Point), quat(p.pose.orientation)),
                               [float(c) for c in p.covariance]),
            TwistWithCovariance(Twist(vec(t.twist.linear), vec(t.twist.angular)),
                                [float(c) for c in t.covariance]),
        )
    if msgtype == "tf2_msgs/msg/TFMessage":
        return TFMessage([
            TransformStamped(header(t.header), t.child_frame_id,
                             Transform(vec(t.transform.translation), quat(t.transform.rotation)))
            for t in msg.transforms
        ])
    raise ValueError(msgtype)


def read_prefix(bag, scans, prefix_bag):
    """The bag's /scan, /odom and /tf_static messages up to its `scans`-th scan, in record-time
    order; written as they are into `prefix_bag` (the file run's input)."""
    store = get_typestore(Stores.ROS1_NOETIC)
    out = []
    with AnyReader([Path(bag)], default_typestore=store) as reader:
        conns = [c for c in reader.connections if c.topic in ("/scan", "/odom", "/tf_static")]
        with Writer(prefix_bag) as writer:
            wconn = {}
            for c in conns:
                wconn[c.id] = writer.add_connection(
                    c.topic, c.msgtype, typestore=store,
                    msgdef=c.msgdef.data, md5sum=c.digest, latching=c.ext.latching,
                )
            seen = 0
            for conn, stamp, raw in reader.messages(connections=conns):
                if conn.topic == "/scan":
                    if seen == scans:
                        break
                    seen += 1
                writer.write(wconn[conn.id], stamp, raw)
                out.append((conn.topic, stamp, to_dds(reader.deserialize(raw, conn.msgtype), conn.msgtype)))
    return out


class Received(Listener):
    """Keeps what a reader receives, with the monotonic time of receipt."""

    def __init__(self):
        super().__init__()
        self.samples = []
        self.lock = threading.Lock()

    def on_data_available(self, reader):
        now = time.monotonic()
        for s in reader.take(N=1000):
            # Writers that go away leave invalid samples (dispose, unregister): not data.
            if isinstance(s, IdlStruct):
                with self.lock:
                    self.samples.append((now, s))


def play(messages, rate, w_scan, w_odom, w_static):
    """Writes the messages in order at `rate` times their record times (never backwards);
    returns the (monotonic time, stamp) of each scan written, and the seconds taken."""
    written = []
    start_wall, start_rec, last_due = time.monotonic(), messages[0][1], 0.0
    for topic, rec, msg in messages:
        due = max(last_due, (rec - start_rec) * 1e-9 / rate)
        last_due = due
        wait = start_wall + due - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        if topic == "/scan":
            w_scan.write(msg)
            written.append((time.monotonic(), (msg.header.stamp.sec, msg.header.stamp.nanosec)))
        elif topic == "/odom":
            w_odom.write(msg)
        else:
            w_static.write(msg)
    return written, time.monotonic() - start_wall


def localise(args, out, messages, writers, failures):
    """A second node localises in the file run's map from an unknown start: the log from its
    1000th scan on (500 scans at 4x the rate), matched against the file run's poses."""
    before = [set(w.get_matched_subscriptions()) for w in writers]
    node = start(
        [args.slamkit, "ros2", "lidar", "--localize", str(out / "file" / "map.skmap"),
         "--idle-exit", "3", "--out", str(out / "localize")],
        out / "localize.log",
    )
    deadline = time.monotonic() + 30
    while not all(set(w.get_matched_subscriptions()) - b for w, b in zip(writers, before)):
        if time.monotonic() > deadline or node.poll() is not None:
            failures.append("localisation node not discovered within 30 s")
            node.kill()
            return None
        time.sleep(0.05)
    time.sleep(0.5)
    scans = [i for i, m in enumerate(messages) if m[0] == "/scan"]
    tail = [m for m in messages[scans[1000]:scans[1500]] if m[0] != "/tf_static"]
    static = [m for m in messages if m[0] == "/tf_static"]
    play(static + tail, args.rate * 4, *writers)
    try:
        node.wait(timeout=120)
    except subprocess.TimeoutExpired:
        node.kill()
        failures.append("the localisation node did not finish")
        return None
    try:
        report = json.loads((out / "localize" / "report.json").read_text())
        first_fix = report["session"]["first_fix_scan"]
        file_poses = {round(r[0], 6): r for r in read_tum(out / "file" / "trajectory.tum")}
        errors = [math.hypot(r[1] - f[1], r[2] - f[2])
                  for r in read_tum(out / "localize" / "trajectory.tum")
                  if (f := file_poses.get(round(r[0], 6)))]
    except (OSError, KeyError, ValueError) as e:
        failures.append(f"localisation outputs: {e}")
        return None
    if first_fix is None or not errors:
        failures.append("the localisation node never found the robot")
        return None
    result = {"first_fix_scan": first_fix, "poses": len(errors),
              "median_error_m": round(statistics.median(errors), 4),
              "max_error_m": round(max(errors), 4)}
    if not result["median_error_m"] <= 0.05:
        failures.append(f"localised poses {result['median_error_m']} m from the file run's")
    return result


def read_tum(path):
    rows = []
    for line in Path(path).read_text().splitlines():
        f = line.split()
        if f and not line.startswith("#"):
            rows.append([float(x) for x in f])
    return rows


def percentile(values, q):
    v = sorted(values)
    return v[min(len(v) - 1, max(0, math.ceil(q * len(v)) - 1))]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--slamkit", required=True)
    ap.add_argument("--bag", required=True)
    ap.add_argument("--scans", type=int, default=3000)
    ap.add_argument("--rate", type=float, default=5.0, help="multiple of real time")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    failures = []

    began = time.monotonic()
    prefix_bag = out / "prefix.bag"
    prefix_bag.unlink(missing_ok=True)
    messages = read_prefix(args.bag, args.scans, prefix_bag)
    n_scans = sum(1 for t, _, _ in messages if t == "/scan")
    read_seconds = time.monotonic() - began

    node = start(
        [args.slamkit, "ros2", "lidar", "--idle-exit", "3", "--out", str(out / "node")],
        out / "node.log",
    )
    file_run = start(
        [args.slamkit, "lidar", str(prefix_bag), "--out", str(out / "file")], out / "file.log"
    )

    dp = DomainParticipant(0)
    # ROS 2's QoS: sensor data (best effort, volatile) for the sensors, reliable and transient
    # local for tf_static and the map, reliable for tf and pose; XCDR1 as ROS 2 writes.
    xcdr1 = Policy.DataRepresentation(use_cdrv0_representation=True)
    second = 1_000_000_000
    sensor = Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile,
                 Policy.History.KeepLast(100), xcdr1)
    latched = Qos(Policy.Reliability.Reliable(second), Policy.Durability.TransientLocal,
                  Policy.History.KeepLast(1), xcdr1)
    reliable = Qos(Policy.Reliability.Reliable(second), Policy.Durability.Volatile,
                   Policy.History.KeepLast(1000), xcdr1)
    w_scan = DataWriter(dp, Topic(dp, "rt/scan", LaserScan), qos=sensor)
    w_odom = DataWriter(dp, Topic(dp, "rt/odom", Odometry), qos=sensor)
    w_static = DataWriter(dp, Topic(dp, "rt/tf_static", TFMessage), qos=latched)
    w_save = DataWriter(dp, Topic(dp, "rt/slamkit/save_map", String),
                        qos=Qos(Policy.Reliability.Reliable(second), Policy.Durability.Volatile,
                                Policy.History.KeepLast(10), xcdr1))
    got_map, got_tf, got_pose = Received(), Received(), Received()
    # Kept referenced: a reader that is garbage-collected is deleted.
    readers = [
        DataReader(dp, Topic(dp, "rt/map", OccupancyGrid), qos=latched, listener=got_map),
        DataReader(dp, Topic(dp, "rt/tf", TFMessage), qos=reliable, listener=got_tf),
        DataReader(dp, Topic(dp, "rt/pose", PoseWithCovarianceStamped), qos=reliable,
                   listener=got_pose),
    ]

    deadline = time.monotonic() + 30
    while not (w_scan.get_matched_subscriptions() and w_odom.get_matched_subscriptions()
               and w_static.get_matched_subscriptions()
               and w_save.get_matched_subscriptions()
               and all(r.get_matched_publications() for r in readers)):
        if time.monotonic() > deadline or node.poll() is not None:
            print("slamkit's readers were not discovered within 30 s", file=sys.stderr)
            node.kill()
            return 1
        time.sleep(0.05)
    time.sleep(0.5)

    written, play_seconds = play(messages, args.rate, w_scan, w_odom, w_static)
    # Save the map while the node runs (before its idle exit).
    saved = out / "saved"
    for f in ("office.skmap", "office.pgm", "office.yaml"):
        (saved / f).unlink(missing_ok=True)
    saved.mkdir(exist_ok=True)
    w_save.write(String(str((saved / "office").resolve())))

    try:
        node.wait(timeout=120)
        file_run.wait(timeout=600)
    except subprocess.TimeoutExpired:
        node.kill()
        file_run.kill()
        failures.append("slamkit did not finish")
    time.sleep(0.5)
    if node.returncode != 0:
        failures.append(f"slamkit ros2 lidar exited with {node.returncode}")
    if file_run.returncode != 0:
        failures.append(f"slamkit lidar exited with {file_run.returncode}")

    # /pose: one per scan, in order, with the scan's stamp; latency from write to receipt.
    poses = [(t, (s.header.stamp.sec, s.header.stamp.nanosec), s.header.frame_id) for t, s in got_pose.samples]
    latencies = []
    if len(poses) != len(written):
        failures.append(f"{len(poses)} poses received for {len(written)} scans written")
    for (tw, stamp), (tr, pstamp, frame) in zip(written, poses):
        if stamp != pstamp or frame != "map":
            failures.append(f"pose stamp {pstamp} in {frame} for scan {stamp}")
            break
        latencies.append((tr - tw) * 1e3)
    # /tf: map -> odom for every scan.
    tfs = [t for _, m in got_tf.samples for t in m.transforms]
    map_odom = [t for t in tfs if t.header.frame_id == "map" and t.child_frame_id == "odom"]
    if len(map_odom) != len(written):
        failures.append(f"{len(map_odom)} map->odom transforms for {len(written)} scans")
    # /map: a valid trinary grid in the map frame (the last one received).
    maps = [m for _, m in got_map.samples]
    if not maps:
        failures.append("no /map received")
    else:
        m = maps[-1]
        if m.header.frame_id != "map" or m.info.width * m.info.height != len(m.data):
            failures.append(f"/map: {m.info.width}x{m.info.height} cells, {len(m.data)} values, frame {m.header.frame_id}")
        if set(m.data) - {-1, 0, 100} or not (0 < m.info.resolution < 1):
            failures.append("/map: values other than -1, 0, 100 or a bad resolution")
        occupied = sum(1 for v in m.data if v == 100)
        if occupied == 0:
            failures.append("/map has no occupied cell")

    missing = [f for f in ("office.skmap", "office.pgm", "office.yaml") if not (saved / f).is_file()]
    if missing:
        failures.append(f"save_map: {', '.join(missing)} not written")

    # The node's trajectory against the file run's.
    worst = float("nan")
    try:
        a = read_tum(out / "node" / "trajectory.tum")
        b = read_tum(out / "file" / "trajectory.tum")
        if len(a) != len(b) or any(abs(x[0] - y[0]) > 1e-9 for x, y in zip(a, b)):
            failures.append(f"trajectories differ in poses: {len(a)} vs {len(b)}")
        else:
            worst = max(math.hypot(x[1] - y[1], x[2] - y[2]) for x, y in zip(a, b))
            if not worst <= 1e-3:
                failures.append(f"trajectory differs from the file run by {worst} m")
        report = json.loads((out / "node" / "report.json").read_text())
        received = report["node"]["scans_received"]
        if received != n_scans:
            failures.append(f"the node received {received} of {n_scans} scans")
    except (OSError, KeyError, ValueError) as e:
        failures.append(f"outputs: {e}")
        report = {}

    localised = None if failures else localise(args, out, messages, (w_scan, w_odom, w_static), failures)

    summary = {
        "scans": n_scans,
        "rate": args.rate,
        "read_seconds": round(read_seconds, 1),
        "play_seconds": round(play_seconds, 1),
        "total_seconds": round(time.monotonic() - began, 1),
        "poses": len(poses),
        "map_odom_transforms": len(map_odom),
        "maps": len(maps),
        "trajectory_max_difference_m": worst,
        "latency_ms_median": round(statistics.median(latencies), 2) if latencies else None,
        "latency_ms_p95": round(percentile(latencies, 0.95), 2) if latencies else None,
        "node_latency_ms": report.get("node_latency_ms"),
        "localisation": localised,
        "failures": failures,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    print(json.dumps(summary))
    return 1 if failures else 0


def run():
    """main(), and no slamkit process left running whatever happens."""
    try:
        return main()
    finally:
        for p in CHILDREN:
            if p.poll() is None:
                p.kill()


if __name__ == "__main__":
    sys.exit(run())
