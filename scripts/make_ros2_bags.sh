#!/usr/bin/env bash
# Converts the Freiburg benchmark's ROS 1 bags ($SLAMKIT_DATA/lidar2d/{intel,aces}/
# *.clf.orig.bag) into ROS 2 bags with an independent tool, PyPI `rosbags` (pinned below):
# scripts/ros1_to_ros2_bag.py runs rosbags' own conversion (message definitions, ROS 1 to CDR)
# and writes each bag as MCAP with zstd-compressed chunks (rosbag2's default MCAP profile) and
# as SQLite .db3, in the order the ROS 1 bag stores the messages (the order they were
# received) with increasing record times, as a rosbag2 recorder writes them. slamkit's
# `ros2_bags` tests (crates/cli/tests/cli/ros2_bags.rs) read them. Also the first 60 frames of
# 7-Scenes RedKitchen as RGB-D camera bags (MCAP and .db3) with a reference folder, by
# scripts/rgbd_to_ros2_bags.py (rosbags, Pillow to decode the images), and a simulated
# camera's run (`slamkit sim`, built here) as an MCAP bag, for the `vo_bags` tests
# (crates/cli/tests/cli/vo_bags.rs). Nothing here is committed.
#
# Usage: scripts/make_ros2_bags.sh [OUT_DIR]      (default: target/ros2-bags)
# Needs python3 with venv; installs rosbags into OUT_DIR/venv (and stops there with VENV_ONLY=1).
# Bags already converted are kept.
set -euo pipefail
cd "$(dirname "$0")/.."

ROSBAGS_VERSION=0.11.9
PILLOW_VERSION=13.0.0
out="${1:-target/ros2-bags}"
data="${SLAMKIT_DATA:-}"
if [ -z "$data" ]; then
    echo "make_ros2_bags: SLAMKIT_DATA is not set; nothing to convert" >&2
    exit 0
fi
mkdir -p "$out"
venv="$out/venv"
if [ ! -x "$venv/bin/rosbags-convert" ] ||
    ! "$venv/bin/python" -c "import importlib.metadata as m, sys; sys.exit(m.version('rosbags') != '$ROSBAGS_VERSION' or m.version('pillow') != '$PILLOW_VERSION')"; then
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check "rosbags==$ROSBAGS_VERSION" "pillow==$PILLOW_VERSION"
fi
# VENV_ONLY=1: only the virtualenv (`.ci/run` installs it while the builds run).
if [ "${VENV_ONLY:-}" = 1 ]; then
    exit 0
fi

for name in intel aces; do
    src="$data/lidar2d/$name/$name.clf.orig.bag"
    if [ ! -f "$src" ]; then
        echo "make_ros2_bags: $src missing" >&2
        exit 1
    fi
    for storage in mcap db3; do
        if [ ! -f "$out/${name}_$storage/metadata.yaml" ]; then
            "$venv/bin/python" scripts/ros1_to_ros2_bag.py "$src" "$out/${name}_$storage" \
                "$([ "$storage" = mcap ] && echo mcap || echo sqlite3)"
        fi
    done
done
rgbd="$data/rgbd/7scenes_redkitchen_frames_0000-0599"
if [ ! -f "$out/redkitchen_db3/metadata.yaml" ]; then
    if [ ! -d "$rgbd" ]; then
        echo "make_ros2_bags: $rgbd missing" >&2
        exit 1
    fi
    rm -rf "$out"/redkitchen_{ref,mcap,db3}
    "$venv/bin/python" scripts/rgbd_to_ros2_bags.py "$rgbd" "$out" 60
fi
# A simulated camera as a bag (vo_bags tests): `slamkit sim` drives the office's ground robot
# 23 s (a straight, a quarter turn in place, a straight) with its RGB-D camera at 10 Hz; its
# TUM folder is the reference for the MCAP bag written from it.
sim="$out/sim_office"
if [ ! -f "$sim/mcap/metadata.yaml" ]; then
    rm -rf "$sim"
    mkdir -p "$sim"
    printf '[rgbd]\nrate_hz = 10.0\n' >"$sim/camera.toml"
    cargo build --release --quiet -p slamkit
    target/release/slamkit sim --world office --robot diff-drive --sensors rgbd --duration 23 \
        --seed 1 --config "$sim/camera.toml" --out "$sim/folder" >/dev/null
    "$venv/bin/python" scripts/rgbd_to_ros2_bags.py --sim "$sim/folder" "$sim/mcap"
fi
echo "make_ros2_bags: ROS 2 bags in $out (rosbags $ROSBAGS_VERSION)"
