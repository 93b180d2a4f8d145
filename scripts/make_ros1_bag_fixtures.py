#!/usr/bin/env python3
"""Writes the small ROS 1 bags slamkit-io's tests read (crates/io/tests/data/ros1/), with an
independent writer: PyPI `rosbags` (pure Python; `pip install rosbags==0.11.9`), never by hand.

A robot drives along x at 0.1 m per step and turns 0.05 rad per step; 20 steps at 10 Hz.
Topics: /odom (nav_msgs/Odometry, at 100 + 0.1 k s), /scan (sensor_msgs/LaserScan, 8 beams,
stamped 0.05 s after each odometry reading; beam i of scan k reads 1 + 0.01 k + 0.1 i m, beam
0 of every fifth scan reads 0.01 m, below range_min), /tf_static (base_link -> laser at
x 0.1, y -0.05, z 0.2, yaw 0.3), /chatter (std_msgs/String, a type slamkit does not read).
The same messages are written uncompressed, with bz2 and with lz4 chunks (small chunks, so
each bag has several); two_lasers.bag adds /scan_rear (a second LaserScan topic).

Usage: python3 scripts/make_ros1_bag_fixtures.py crates/io/tests/data/ros1
"""

import math
import sys
from pathlib import Path

from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

ts = get_typestore(Stores.ROS1_NOETIC)
if "tf2_msgs/msg/TFMessage" not in ts.types:
    # The noetic store of rosbags 0.11 has no tf2_msgs; its one-line definition, as in ROS.
    ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
Header = ts.types["std_msgs/msg/Header"]
Time = ts.types["builtin_interfaces/msg/Time"]
LaserScan = ts.types["sensor_msgs/msg/LaserScan"]
Odometry = ts.types["nav_msgs/msg/Odometry"]
PoseWithCovariance = ts.types["geometry_msgs/msg/PoseWithCovariance"]
TwistWithCovariance = ts.types["geometry_msgs/msg/TwistWithCovariance"]
Pose = ts.types["geometry_msgs/msg/Pose"]
Twist = ts.types["geometry_msgs/msg/Twist"]
Point = ts.types["geometry_msgs/msg/Point"]
Quaternion = ts.types["geometry_msgs/msg/Quaternion"]
Vector3 = ts.types["geometry_msgs/msg/Vector3"]
Transform = ts.types["geometry_msgs/msg/Transform"]
TransformStamped = ts.types["geometry_msgs/msg/TransformStamped"]
TFMessage = ts.types["tf2_msgs/msg/TFMessage"]
String = ts.types["std_msgs/msg/String"]

import numpy as np  # rosbags depends on numpy


def stamp(t):
    sec = int(t)
    return Time(sec=sec, nanosec=int(round((t - sec) * 1e9)))


def yaw_quat(yaw):
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def scan(k, t, frame):
    ranges = np.array([1.0 + 0.01 * k + 0.1 * i for i in range(8)], dtype=np.float32)
    if k % 5 == 0:
        ranges[0] = 0.01
    return LaserScan(
        header=Header(seq=k, stamp=stamp(t), frame_id=frame),
        angle_min=-1.5, angle_max=1.5, angle_increment=3.0 / 7, time_increment=0.0,
        scan_time=0.1, range_min=0.05, range_max=30.0, ranges=ranges,
        intensities=np.array([], dtype=np.float32))


def odom(k, t):
    return Odometry(
        header=Header(seq=k, stamp=stamp(t), frame_id="odom"), child_frame_id="base_link",
        pose=PoseWithCovariance(
            pose=Pose(position=Point(x=0.1 * k, y=0.0, z=0.0), orientation=yaw_quat(0.05 * k)),
            covariance=np.zeros(36)),
        twist=TwistWithCovariance(
            twist=Twist(linear=Vector3(x=1.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.5)),
            covariance=np.zeros(36)))


def tf_static():
    t = TransformStamped(
        header=Header(seq=0, stamp=stamp(100.0), frame_id="base_link"), child_frame_id="laser",
        transform=Transform(translation=Vector3(x=0.1, y=-0.05, z=0.2), rotation=yaw_quat(0.3)))
    return TFMessage(transforms=[t])


def write(path, compression, rear):
    path.unlink(missing_ok=True)
    w = Writer(path)
    if compression:
        w.set_compression(compression)
    w.chunk_threshold = 2048
    w.open()
    try:
        c_static = w.add_connection("/tf_static", TFMessage.__msgtype__, typestore=ts, latching=1)
        c_odom = w.add_connection("/odom", Odometry.__msgtype__, typestore=ts)
        c_scan = w.add_connection("/scan", LaserScan.__msgtype__, typestore=ts)
        c_chat = w.add_connection("/chatter", String.__msgtype__, typestore=ts)
        c_rear = w.add_connection("/scan_rear", LaserScan.__msgtype__, typestore=ts) if rear else None
        ns = lambda t: int(round(t * 1e9))
        w.write(c_static, ns(100.0), ts.serialize_ros1(tf_static(), TFMessage.__msgtype__))
        for k in range(20):
            t = 100.0 + 0.1 * k
            w.write(c_odom, ns(t), ts.serialize_ros1(odom(k, t), Odometry.__msgtype__))
            w.write(c_scan, ns(t + 0.05), ts.serialize_ros1(scan(k, t + 0.05, "laser"), LaserScan.__msgtype__))
            if rear:
                w.write(c_rear, ns(t + 0.06), ts.serialize_ros1(scan(k, t + 0.06, "laser_rear"), LaserScan.__msgtype__))
            if k % 4 == 0:
                w.write(c_chat, ns(t), ts.serialize_ros1(String(data=f"step {k}"), String.__msgtype__))
    finally:
        w.close()


def main():
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "crates/io/tests/data/ros1")
    out.mkdir(parents=True, exist_ok=True)
    fmt = Writer.CompressionFormat
    write(out / "robot_none.bag", None, False)
    write(out / "robot_bz2.bag", fmt.BZ2, False)
    write(out / "robot_lz4.bag", fmt.LZ4, False)
    write(out / "two_lasers.bag", fmt.LZ4, True)
    for p in sorted(out.glob("*.bag")):
        print(p, p.stat().st_size)


if __name__ == "__main__":
    main()
