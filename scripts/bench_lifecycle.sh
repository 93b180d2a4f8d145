#!/usr/bin/env bash
# The map lifecycle on the Freiburg benchmark logs, timed: map each log and save the map
# (`--save-map`), localise the same log in the saved map with no initial pose (`--localize`),
# map the first half and continue the saved half-map with the second (`--continue`). Prints one
# row per log: relations error of each (the continued map's whole trajectory,
# trajectory_map.tum), the session time each run reports (report.json `session_seconds`: map
# load, global search and every scan; the log's parsing is left out as it is the same for all),
# the map's size and `slamkit map info`'s load time. Runs ROUNDS rounds (default 3) and prints
# medians: the machine is shared, compare ratios. Beside the session's speed-up, the ratio of the
# two whole processes' CPU time (user + sys, /usr/bin/time): contention on a loaded machine
# slows wall times unevenly, CPU time much less; parsing and writing are in both processes, so
# it understates the session's ratio.
# usage: [ROUNDS=3] [LOGS="intel aces mit-csail"] [SLAMKIT_BIN=...] scripts/bench_lifecycle.sh [OUTDIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
data=${SLAMKIT_DATA:?set SLAMKIT_DATA to the data folder}
rounds=${ROUNDS:-3}
logs=${LOGS:-intel aces mit-csail}
out=${1:-$root/out/bench-lifecycle}
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
  # the log's two halves, split at the middle scan (the second keeps the last odometry line
  # before it, so its first scan has odometry)
  python3 - "$log" "$o" <<'PY'
import gzip, sys
log, out = sys.argv[1], sys.argv[2]
lines = (gzip.open if log.endswith('.gz') else open)(log, 'rt').read().splitlines(True)
scan = [i for i, l in enumerate(lines)
        if l.split()[:1] and l.split()[0] in ('FLASER', 'RAWLASER1', 'ROBOTLASER1')]
cut = scan[len(scan) // 2]
head = [l for l in lines[:cut] if l.startswith('#')]
odom = [l for l in lines[:cut] if l.startswith('ODOM')][-1:]
open(out + '/first.clf', 'w').writelines(lines[:cut])
open(out + '/second.clf', 'w').writelines(head + odom + lines[cut:])
PY
  for r in $(seq 1 "$rounds"); do
    /usr/bin/time -f "%U %S" -o "$o/map-$r.cpu" \
      "$slamkit" lidar "$log" --relations "$rel" --save-map "$o/map.skmap" --out "$o/map-$r" >/dev/null
    /usr/bin/time -f "%U %S" -o "$o/loc-$r.cpu" \
      "$slamkit" lidar "$log" --relations "$rel" --localize "$o/map.skmap" --out "$o/loc-$r" >/dev/null
    "$slamkit" lidar "$o/first.clf" --relations "$rel" --save-map "$o/first.skmap" --out "$o/first-$r" >/dev/null
    "$slamkit" lidar "$o/second.clf" --relations "$rel" --continue "$o/first.skmap" --out "$o/cont-$r" >/dev/null
    "$slamkit" eval relations --relations "$rel" --est "$o/cont-$r/trajectory_map.tum" --json > "$o/cont-$r/whole.json"
    "$slamkit" map info "$o/map.skmap" --json > "$o/info-$r.json"
  done
  python3 - "$o" "$rounds" "$name" <<'PY'
import json, statistics, sys
o, rounds, name = sys.argv[1], int(sys.argv[2]), sys.argv[3]
def rep(kind, r): return json.load(open(f'{o}/{kind}-{r}/report.json'))
med = statistics.median
rs = range(1, rounds + 1)
m = [rep('map', r) for r in rs]; l = [rep('loc', r) for r in rs]
whole = json.load(open(f'{o}/cont-1/whole.json'))
info = [json.load(open(f'{o}/info-{r}.json')) for r in rs]
t_map = med(x['session_seconds'] for x in m); t_loc = med(x['session_seconds'] for x in l)
def cpu(kind, r): return sum(float(v) for v in open(f'{o}/{kind}-{r}.cpu').read().split()[-2:])
c_map = med(cpu('map', r) for r in rs); c_loc = med(cpu('loc', r) for r in rs)
e_map = m[0]['metrics']['relations']; e_loc = l[0]['metrics']['relations']
print(f"| {name} | {e_map['trans_mean']:.4f} m, {e_map['rot_mean_deg']:.3f}° | {t_map:.2f} s "
      f"| {e_loc['trans_mean']:.4f} m, {e_loc['rot_mean_deg']:.3f}° "
      f"({e_loc['trans_mean'] / e_map['trans_mean']:.2f}×) | {t_loc:.2f} s ({t_map / t_loc:.1f}× faster; "
      f"CPU {c_map:.1f} / {c_loc:.1f} s, {c_map / c_loc:.1f}×) "
      f"| scan {l[0]['session']['first_fix_scan']} "
      f"| {whole['trans_mean']:.4f} m, {whole['rot_mean_deg']:.3f}° ({whole['trans_mean'] / e_map['trans_mean']:.2f}×) "
      f"| {info[0]['file_bytes'] / 1e6:.2f} MB | {med(i['load_seconds'] for i in info) * 1e3:.0f} ms |")
PY
done
