#!/usr/bin/env bash
# Side-by-side benchmark of 2D lidar SLAM: slamkit's ICP-SLAM and MRPT's icp-slam (Debian package
# mrpt-apps, run through ../shared/tools/mrpt/run-mrpt.sh) on the Freiburg benchmark logs, both
# scored with `slamkit eval relations`; wall time, CPU time (user + sys) and peak memory from
# /usr/bin/time; the last column is the 1-minute load average before and after the log's runs
# (the machine is shared: compare ratios from one run, not times across runs).
# METHOD=rbpf compares the particle filters instead (both with 10 particles, MRPT's ICP-based
# rbpf-slam config); LOGS="aces mit-csail" runs only those logs.
# SLAMKIT_BIN=path runs that slamkit binary instead of building one (e.g. an older build, to
# compare before and after a change against MRPT).
# usage: [METHOD=icp|rbpf] [LOGS="intel aces mit-csail"] [SLAMKIT_BIN=...] scripts/bench_lidar.sh [OUTDIR]
#        (needs SLAMKIT_DATA; installs mrpt-apps if missing)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
data=${SLAMKIT_DATA:?set SLAMKIT_DATA to the data folder}
mrpt_tools=${MRPT_TOOLS:-$root/../shared/tools/mrpt}
method=${METHOD:-icp}
logs=${LOGS:-intel aces mit-csail}
case $method in
  icp) slamkit_flags=(--method icp) ;;
  rbpf) slamkit_flags=(--method rbpf --particles 10) ;;
  *) echo "METHOD must be icp or rbpf" >&2; exit 2 ;;
esac
out=${1:-$root/out/bench-lidar-$method}
mkdir -p "$out"

if ! command -v icp-slam >/dev/null; then
  (apt-get update -qq && apt-get install -y -qq mrpt-apps time) >/dev/null
fi
python3 -c 'import numpy' 2>/dev/null || pip install -q numpy
if [[ -n ${SLAMKIT_BIN:-} ]]; then
  slamkit=$SLAMKIT_BIN
else
  cargo build --release -q -p slamkit --manifest-path "$root/Cargo.toml"
  slamkit=${CARGO_TARGET_DIR:-$root/target}/release/slamkit
fi

# name | log | relations | MRPT converter flags (from tools/mrpt/README.md)
runs=(
  "intel|lidar2d/intel/intel.fromrosbag.clf.gz|lidar2d/intel/intel.relations|--odom file-order --max-range 81.0 --aperture-deg 179 --sensor-yaw-deg -0.5"
  "aces|lidar2d/aces/aces.fromrosbag.clf.gz|lidar2d/aces/aces.relations|--odom interp --max-range 49.95 --aperture-deg 179 --sensor-yaw-deg -0.5"
  "mit-csail|lidar2d/mit-csail/mit-csail.clf|lidar2d/mit-csail/mit-csail.relations|--max-range 81.0"
)

# "t x y theta" -> TUM
to_tum() { awk '{printf "%s %s %s 0 0 0 %.12f %.12f\n", $1, $2, $3, sin($4/2), cos($4/2)}' "$1" > "$2"; }
score() { "$slamkit" eval relations --relations "$1" --est "$2" --json; }
field() { python3 -c "import json,sys; d=json.loads(sys.argv[1]); print(f\"{d['trans_mean']:.4f} ± {d['trans_std']:.4f} m\")" "$1"; }
timing() { python3 - "$1" <<'PY'
import re, sys
t = open(sys.argv[1]).read()
wall = re.search(r"Elapsed \(wall clock\) time.*: (?:(\d+):)?(\d+):([\d.]+)", t)
h, m, s = wall.groups()
secs = int(h or 0) * 3600 + int(m) * 60 + float(s)
mib = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", t).group(1)) / 1024
cpu = sum(float(re.search(rf"{k} time \(seconds\): ([\d.]+)", t).group(1)) for k in ("User", "System"))
print(f"{secs:.1f} s|{cpu:.1f} s|{mib:.0f} MiB")
PY
}

echo "| log | slamkit $method | wall | CPU | peak | MRPT $method-slam | wall | CPU | peak | wall ratio | CPU ratio | load |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
load() { cut -d' ' -f1 /proc/loadavg; }
for run in "${runs[@]}"; do
  IFS='|' read -r name log rel flags <<<"$run"
  [[ " $logs " == *" $name "* ]] || continue
  d=$out/$name
  load_before=$(load)
  /usr/bin/time -v -o "$d.slamkit.time" "$slamkit" lidar "$data/$log" "${slamkit_flags[@]}" \
    --relations "$data/$rel" --out "$d/slamkit" >/dev/null 2>&1
  s_err=$(field "$(score "$data/$rel" "$d/slamkit/trajectory.tum")")
  IFS='|' read -r s_wall s_cpu s_mem <<<"$(timing "$d.slamkit.time")"
  # shellcheck disable=SC2086
  "$mrpt_tools/run-mrpt.sh" "$method" "$data/$log" "$d/mrpt" $flags >/dev/null 2>&1
  to_tum "$d/mrpt/trajectory.txt" "$d/mrpt/trajectory.tum"
  m_err=$(field "$(score "$data/$rel" "$d/mrpt/trajectory.tum")")
  IFS='|' read -r m_wall m_cpu m_mem <<<"$(timing "$d/mrpt/time.txt")"
  ratio=$(python3 -c "print(f'{${s_wall% s}/${m_wall% s}:.2f}')")
  cpu_ratio=$(python3 -c "print(f'{${s_cpu% s}/${m_cpu% s}:.2f}')")
  echo "| $name | $s_err | $s_wall | $s_cpu | $s_mem | $m_err | $m_wall | $m_cpu | $m_mem | $ratio | $cpu_ratio | $load_before–$(load) |"
done
