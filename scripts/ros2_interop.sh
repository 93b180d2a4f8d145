#!/usr/bin/env bash
# The Cyclone DDS interoperability test of `slamkit ros2 lidar` (scripts/ros2_interop.py):
# PyPI cyclonedds (pinned below, its wheel carries the Cyclone C library) plays the Intel log's
# first scans into the node and checks what comes back.
#
# It runs in a network namespace of its own holding only `lo` (multicast on, 224.0.0.0/4
# routed to it), so both DDS stacks keep ROS 2's default multicast discovery and no packet can
# leave the machine. Needs root (or user namespaces) for `unshare --net`.
#
# Usage: scripts/ros2_interop.sh [OUT_DIR] [SCANS] [RATE]
#        (defaults: target/ros2-interop, 3000 scans, 5x real time)
# Exit 77 (skipped) without $SLAMKIT_DATA or when no network namespace can be made.
set -euo pipefail
cd "$(dirname "$0")/.."

CYCLONEDDS_VERSION=11.0.1
ROSBAGS_VERSION=0.11.9
out="${1:-target/ros2-interop}"
scans="${2:-3000}"
rate="${3:-5}"
bag="${SLAMKIT_DATA:-}/lidar2d/intel/intel.clf.orig.bag"
if [ -z "${SLAMKIT_DATA:-}" ] || [ ! -f "$bag" ]; then
    echo "ros2_interop: skipped (no \$SLAMKIT_DATA/lidar2d/intel/intel.clf.orig.bag)" >&2
    exit 77
fi
if ! unshare --net true 2>/dev/null; then
    echo "ros2_interop: skipped (cannot make a network namespace: unshare --net needs root)" >&2
    exit 77
fi
mkdir -p "$out"
venv="$out/venv"
if ! "$venv/bin/python" -c "import importlib.metadata as m, sys; sys.exit(m.version('cyclonedds') != '$CYCLONEDDS_VERSION' or m.version('rosbags') != '$ROSBAGS_VERSION')" 2>/dev/null; then
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check \
        "cyclonedds==$CYCLONEDDS_VERSION" "rosbags==$ROSBAGS_VERSION"
fi
# VENV_ONLY=1: only the virtualenv (`.ci/run` installs it while the builds run).
if [ "${VENV_ONLY:-}" = 1 ]; then
    exit 0
fi
cargo build --release --quiet -p slamkit
slamkit="${CARGO_TARGET_DIR:-target}/release/slamkit"

# Cyclone on lo only, multicast allowed there (it leaves loopback multicast off by default).
export CYCLONEDDS_URI='<CycloneDDS><Domain><General><Interfaces><NetworkInterface name="lo" multicast="true"/></Interfaces></General></Domain></CycloneDDS>'
exec unshare --net bash -c '
    set -e
    ip link set lo up
    ip link set lo multicast on
    ip route add 224.0.0.0/4 dev lo
    exec "$0" scripts/ros2_interop.py --slamkit "$1" --bag "$2" --scans "$3" --rate "$4" --out "$5"
' "$venv/bin/python" "$slamkit" "$bag" "$scans" "$rate" "$out"
