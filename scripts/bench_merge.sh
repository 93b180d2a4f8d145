#!/usr/bin/env bash
# Many robots, one map (issue 22), offline: each Freiburg log cut into three consecutive parts,
# each part mapped on its own from the origin and saved (`--save-map`), the three maps merged
# (`slamkit map merge`), and the merged trajectory (all parts' scans in the merged frame,
# merged/trajectory.tum) scored with the log's relations beside each part alone and the
# uninterrupted run. Prints one row per log; the merge's wall time is report.json's
# `wall_seconds` (loading the maps, merging, writing the outputs).
# usage: [LOGS="intel aces mit-csail"] [SLAMKIT_BIN=...] scripts/bench_merge.sh [OUTDIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
data=${SLAMKIT_DATA:?set SLAMKIT_DATA to the data folder}
logs=${LOGS:-intel aces mit-csail}
out=${1:-$root/out/bench-merge}
mkdir -p "$out"
if [[ -n ${SLAMKIT_BIN:-} ]]; then
  slamkit=$SLAMKIT_BIN
else
  cargo build --release -q -p slamkit --manifest-path "$root/Cargo.toml"
  slamkit=${CARGO_TARGET_DIR:-$root/target}/release/slamkit
fi

declare -A file=([intel]=intel/intel.fromrosbag.clf.gz [aces]=aces/aces.fromrosbag.clf.gz
                 [mit-csail]=mit-csail/mit-csail.clf)
for name in $logs; do
  log=$data/lidar2d/${file[$name]}
  rel=$data/lidar2d/$name/$name.relations
  o=$out/$name
  mkdir -p "$o"
  # three parts of equal scan counts; each keeps the header and the last odometry line before
  # its first scan, so that scan has odometry
  python3 - "$log" "$o" <<'PY'
import gzip, sys
log, out = sys.argv[1], sys.argv[2]
lines = (gzip.open if log.endswith('.gz') else open)(log, 'rt').read().splitlines(True)
scan = [i for i, l in enumerate(lines)
        if l.split()[:1] and l.split()[0] in ('FLASER', 'RAWLASER1', 'ROBOTLASER1')]
third = len(scan) // 3
cuts = [0, scan[third], scan[2 * third], len(lines)]
head = [l for l in lines if l.startswith('#')]
for k in range(3):
    odom = [l for l in lines[:cuts[k]] if l.startswith('ODOM')][-1:]
    body = [l for l in lines[cuts[k]:cuts[k + 1]] if not l.startswith('#')]
    open(f'{out}/{k + 1}.clf', 'w').writelines(head + odom + body)
PY
  "$slamkit" lidar "$log" --relations "$rel" --out "$o/full" >/dev/null
  for k in 1 2 3; do
    "$slamkit" lidar "$o/$k.clf" --relations "$rel" --save-map "$o/${name}_$k.skmap" --out "$o/part$k" >/dev/null
  done
  "$slamkit" map merge "$o/${name}_1.skmap" "$o/${name}_2.skmap" "$o/${name}_3.skmap" --out "$o/merged"
  "$slamkit" eval relations --relations "$rel" --est "$o/merged/trajectory.tum" --json > "$o/merged.json"
  python3 - "$o" "$name" <<'PY'
import json, sys
o, name = sys.argv[1], sys.argv[2]
def err(path): return json.load(open(path))['metrics']['relations']['trans_mean']
full = err(f'{o}/full/report.json')
parts = [err(f'{o}/part{k}/report.json') for k in (1, 2, 3)]
merged = json.load(open(f'{o}/merged.json'))['trans_mean']
rep = json.load(open(f'{o}/merged/report.json'))
print(f"| {name} | {' / '.join(f'{p:.4f}' for p in parts)} m | {merged:.4f} m "
      f"({merged / full:.2f}×) | {full:.4f} m | {rep['closures_found']} / {rep['closures_accepted']} "
      f"| {', '.join(rep['unmerged']) or 'none'} | {rep['wall_seconds']:.1f} s |")
PY
done
