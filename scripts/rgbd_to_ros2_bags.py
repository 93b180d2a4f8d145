#!/usr/bin/env python3
"""Writes ROS 2 bags of RGB-D camera topics from a 7-Scenes folder, with PyPI `rosbags` (an
independent writer of CDR and of both ROS 2 storages), for slamkit's `vo_bags` tests
(crates/cli/tests/cli/vo_bags.rs): `slamkit vo` on each bag must give the trajectory it gives on
the reference folder written beside them.

Usage: rgbd_to_ros2_bags.py SRC_7SCENES_DIR OUT_DIR [FRAMES]     (default 60 frames)

OUT_DIR/<name>_ref/   the first FRAMES frames as a 7-Scenes folder: the colour as PNG of the
                      pixels Pillow decodes from the JPEG (the bags carry those pixels; slamkit's
                      own JPEG decoder rounds some differently), depth, poses and intrinsics
                      linked to the originals.
OUT_DIR/<name>_mcap/  MCAP, zstd chunks: rgb8 colour, 16UC1 depth [mm] (a RealSense driver's
                      topics), one CameraInfo topic.
OUT_DIR/<name>_db3/   SQLite: bgr8 colour, 32FC1 depth [m], NaN where there is none (an
                      openni driver's topics), a CameraInfo topic for each camera.
Frame N is stamped N/30 s as the folder reader stamps it; depth 4 ms after its colour image,
as two sensors' clocks are never equal (the reader pairs them by TUM's rule, within 0.02 s).

Usage: rgbd_to_ros2_bags.py --sim SRC_SIM_DIR OUT_BAG

A simulated camera (the output folder of `slamkit sim --sensors rgbd`: report.json and
tum_rgbd_fr1/) as one MCAP bag, zstd chunks, of a RealSense driver's compressed topics: the
colour images as `sensor_msgs/CompressedImage` (the folder's PNG files as they are), depth as
32FC1 [m] (the folder's 16-bit units over report.json's units per metre, NaN where there is
none), one CameraInfo topic from report.json's intrinsics; stamped with the folder's times.
The folder itself is the reference: `slamkit vo` must give the same trajectory on both.
"""
import json
import sys
from pathlib import Path

import numpy as np
from PIL import Image as PilImage
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

RATE_HZ = 30.0
DEPTH_DELAY_NS = 4_000_000


def stamp(ts, ns):
    return ts.types['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9)


def header(ts, ns, frame):
    return ts.types['std_msgs/msg/Header'](stamp=stamp(ts, ns), frame_id=frame)


def image(ts, ns, frame, pixels, encoding):
    h, w = pixels.shape[:2]
    data = np.ascontiguousarray(pixels).view(np.uint8).reshape(-1)
    return ts.types['sensor_msgs/msg/Image'](
        header=header(ts, ns, frame), height=h, width=w, encoding=encoding,
        is_bigendian=0, step=data.size // h, data=data)


def camera_info(ts, ns, frame, k, size):
    fx, fy, cx, cy = k
    roi = ts.types['sensor_msgs/msg/RegionOfInterest'](
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    return ts.types['sensor_msgs/msg/CameraInfo'](
        header=header(ts, ns, frame), height=size[1], width=size[0],
        distortion_model='plumb_bob', d=np.zeros(5),
        k=np.array([fx, 0, cx, 0, fy, cy, 0, 0, 1], dtype=float),
        r=np.eye(3).reshape(-1),
        p=np.array([fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0], dtype=float),
        binning_x=0, binning_y=0, roi=roi)


def write_bag(path, storage, topics, frames, ts, k):
    writer = Writer(path, version=9, storage_plugin=storage)
    if storage == StoragePlugin.MCAP:
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer:
        conns = {
            name: writer.add_connection(topic, msgtype, typestore=ts)
            for name, (topic, msgtype) in topics['connections'].items()
        }
        for n, rgb, depth_mm in frames():
            t = round(n / RATE_HZ * 1e9)
            size = (rgb.shape[1], rgb.shape[0])
            msgs = topics['messages'](ts, t, rgb, depth_mm, k, size)
            for name, ns, msg in sorted(msgs, key=lambda m: m[1]):
                msgtype = topics['connections'][name][1]
                writer.write(conns[name], ns, ts.serialize_cdr(msg, msgtype))


def realsense(ts, t, rgb, depth_mm, k, size):
    frame = 'camera_color_optical_frame'
    return [
        ('rgb', t, image(ts, t, frame, rgb, 'rgb8')),
        ('info', t, camera_info(ts, t, frame, k, size)),
        ('depth', t + DEPTH_DELAY_NS,
         image(ts, t + DEPTH_DELAY_NS, frame, depth_mm.astype('<u2'), '16UC1')),
    ]


def openni(ts, t, rgb, depth_mm, k, size):
    frame = 'camera_rgb_optical_frame'
    metres = np.where(depth_mm == 0, np.nan, depth_mm / 1000.0).astype('<f4')
    td = t + DEPTH_DELAY_NS
    return [
        ('rgb', t, image(ts, t, frame, np.ascontiguousarray(rgb[:, :, ::-1]), 'bgr8')),
        ('info', t, camera_info(ts, t, frame, k, size)),
        ('depth', td, image(ts, td, frame, metres, '32FC1')),
        ('depth_info', td, camera_info(ts, td, frame, k, size)),
    ]


def simulated(src, bag):
    """Writes the simulated RGB-D folder `src` as the MCAP bag `bag` (see the module's help)."""
    report = json.loads((src / 'report.json').read_text())
    rgbd = report['config']['rgbd']
    cam = rgbd['intrinsics']
    k = (cam['fx'], cam['fy'], cam['cx'], cam['cy'])
    size = (cam['width'], cam['height'])
    units = float(rgbd['depth_units_per_metre'])
    tum = src / 'tum_rgbd_fr1'
    frame = 'camera_color_optical_frame'
    ts = get_typestore(Stores.ROS2_HUMBLE)
    writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    compressed = 'sensor_msgs/msg/CompressedImage'
    with writer:
        rgb_conn = writer.add_connection('/camera/color/image_raw/compressed', compressed,
                                         typestore=ts)
        depth_conn = writer.add_connection('/camera/aligned_depth_to_color/image_raw',
                                           'sensor_msgs/msg/Image', typestore=ts)
        info_conn = writer.add_connection('/camera/color/camera_info',
                                          'sensor_msgs/msg/CameraInfo', typestore=ts)
        for line in (tum / 'associations.txt').read_text().splitlines():
            if not line.strip() or line.startswith('#'):
                continue
            t_rgb, rgb_file, t_depth, depth_file = line.split()[:4]
            tc, td = round(float(t_rgb) * 1e9), round(float(t_depth) * 1e9)
            png = np.frombuffer((tum / rgb_file).read_bytes(), dtype=np.uint8)
            rgb = ts.types[compressed](header=header(ts, tc, frame), format='png', data=png)
            raw = np.asarray(PilImage.open(tum / depth_file)).astype(np.float64)
            metres = np.where(raw == 0, np.nan, raw / units).astype('<f4')
            msgs = [
                (rgb_conn, tc, rgb, compressed),
                (info_conn, tc, camera_info(ts, tc, frame, k, size),
                 'sensor_msgs/msg/CameraInfo'),
                (depth_conn, td, image(ts, td, frame, metres, '32FC1'), 'sensor_msgs/msg/Image'),
            ]
            for conn, ns, msg, msgtype in sorted(msgs, key=lambda m: m[1]):
                writer.write(conn, ns, ts.serialize_cdr(msg, msgtype))


def main():
    if sys.argv[1] == '--sim':
        simulated(Path(sys.argv[2]), Path(sys.argv[3]))
        return
    src, out = Path(sys.argv[1]), Path(sys.argv[2])
    count = int(sys.argv[3]) if len(sys.argv) > 3 else 60
    name = 'redkitchen'
    kmat = np.loadtxt(src / 'camera-intrinsics.txt')
    k = (kmat[0, 0], kmat[1, 1], kmat[0, 2], kmat[1, 2])
    ref = out / f'{name}_ref'
    ref.mkdir(parents=True, exist_ok=True)
    (ref / 'camera-intrinsics.txt').unlink(missing_ok=True)
    (ref / 'camera-intrinsics.txt').symlink_to((src / 'camera-intrinsics.txt').resolve())

    def frames():
        for n in range(count):
            stem = f'frame-{n:06d}'
            rgb = np.asarray(PilImage.open(src / f'{stem}.color.jpg').convert('RGB'))
            depth_mm = np.asarray(PilImage.open(src / f'{stem}.depth.png')).astype(np.uint16)
            yield n, rgb, depth_mm

    for n, rgb, _ in frames():
        stem = f'frame-{n:06d}'
        PilImage.fromarray(rgb).save(ref / f'{stem}.color.png')
        for kind in ('depth.png', 'pose.txt'):
            link = ref / f'{stem}.{kind}'
            link.unlink(missing_ok=True)
            link.symlink_to((src / f'{stem}.{kind}').resolve())

    ts = get_typestore(Stores.ROS2_HUMBLE)
    write_bag(out / f'{name}_mcap', StoragePlugin.MCAP, {
        'connections': {
            'rgb': ('/camera/color/image_raw', 'sensor_msgs/msg/Image'),
            'depth': ('/camera/aligned_depth_to_color/image_raw', 'sensor_msgs/msg/Image'),
            'info': ('/camera/color/camera_info', 'sensor_msgs/msg/CameraInfo'),
        },
        'messages': realsense,
    }, frames, ts, k)
    write_bag(out / f'{name}_db3', StoragePlugin.SQLITE3, {
        'connections': {
            'rgb': ('/camera/rgb/image_color', 'sensor_msgs/msg/Image'),
            'info': ('/camera/rgb/camera_info', 'sensor_msgs/msg/CameraInfo'),
            'depth': ('/camera/depth_registered/image', 'sensor_msgs/msg/Image'),
            'depth_info': ('/camera/depth_registered/camera_info', 'sensor_msgs/msg/CameraInfo'),
        },
        'messages': openni,
    }, frames, ts, k)


if __name__ == '__main__':
    main()
