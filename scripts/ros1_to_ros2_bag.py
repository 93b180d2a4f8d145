#!/usr/bin/env python3
"""Converts a ROS 1 bag into a ROS 2 bag with PyPI `rosbags`, keeping the order the ROS 1 bag
stores its messages in: the order its recorder received them.

Usage: ros1_to_ros2_bag.py SRC.bag DST_DIR {mcap|sqlite3}

Why not `rosbags-convert` alone: it writes the messages by record time. In the Freiburg bags
the record time is each scan's header stamp, and Intel's stamps jitter against the order the
laser took the scans in (in the file's order they step back 631 times, by up to 0.9 s), so the
converted bag holds the scans in another sequence than the robot saw them, and ICP-SLAM on it
is a different run (relations error 0.978 m against 0.016 m). A rosbag2 recorder stamps each
message with its receive time, which never steps back; this script does the same: messages in
the file's order, each record time the larger of its own and 1 ns after the one before.
The message stamps (`header.stamp`) are kept as they are.

The conversion itself is rosbags' own (`create_connections_converters`: the connections, the
message definitions, ROS 1 to CDR); only the order and the record times are this script's.
MCAP is written with zstd-compressed chunks (rosbag2's default MCAP profile); a bag is written
into DST_DIR.tmp and renamed, so a killed run leaves no half bag behind.
"""
import heapq
import shutil
import sys
from pathlib import Path

from rosbags.convert.converter import create_connections_converters
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer


def file_order(reader):
    """The messages of a one-file `AnyReader` over a ROS 1 bag as (position in the file,
    connection, record time, raw data).

    rosbags' ROS 1 reader yields messages by record time, merging the per-connection index
    entries; each entry also names the chunk and the offset in it the message is stored at.
    The same merge over the same entries pairs every yielded message with its entry.
    """
    (bag,) = reader.readers
    entries = heapq.merge(*(bag.indexes[c.id] for c in bag.connections))
    out = []
    for entry, (conn, time, data) in zip(entries, reader.messages(), strict=True):
        if entry.time != time:
            sys.exit(f'ros1_to_ros2_bag: index and messages disagree at {time} ns')
        out.append(((entry.chunk_pos, entry.offset), conn, time, data))
    out.sort(key=lambda m: m[0])
    return out


def main():
    if len(sys.argv) != 4 or sys.argv[3] not in ('mcap', 'sqlite3'):
        sys.exit(__doc__)
    src, dst, storage = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
    tmp = dst.with_name(dst.name + '.tmp')
    shutil.rmtree(tmp, ignore_errors=True)
    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    writer = Writer(tmp, version=8, storage_plugin=plugin)
    if storage == 'mcap':
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with AnyReader([src]) as reader, writer:
        connmap, convmap = create_connections_converters(reader.connections, None, reader, writer)
        last = None
        steps_back = 0
        messages = file_order(reader)
        for _, conn, time, data in messages:
            if last is not None and time <= last:
                steps_back += time < last
                time = last + 1
            writer.write(connmap[(conn.id, conn.owner)], time, convmap[conn.msgtype](data))
            last = time
    shutil.rmtree(dst, ignore_errors=True)
    tmp.rename(dst)
    print(f'{src.name} -> {dst} ({storage}): {len(messages)} messages in the file\'s order, '
          f'{steps_back} record times moved forward to keep them increasing')


if __name__ == '__main__':
    main()
