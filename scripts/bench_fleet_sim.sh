#!/usr/bin/env bash
# `slamkit fleet sim` benchmark (issue 22): for each seed, a loss-free run and a run with 30 %
# of every robot's publications dropped, the last robot off the network for 60 simulated
# seconds, robot 0 killed and restarted and the merger killed and restarted mid-run; then one
# line per run (merged error, closures, bytes, latencies) and, per seed, the largest distance
# between the two runs' merged poses (every pose of every robot in the merged frame).
#   WORLD=office ROBOTS=3 SEEDS="1 2 3 4 5" scripts/bench_fleet_sim.sh
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${SLAMKIT:-${CARGO_TARGET_DIR:-target}/release/slamkit}
OUT=${OUT:-/tmp/slamkit_fleet_sim_bench}
WORLD=${WORLD:-office}
ROBOTS=${ROBOTS:-3}
SEEDS=${SEEDS:-1 2 3 4 5}
for seed in $SEEDS; do
  base="$OUT/$WORLD-$ROBOTS-$seed"
  "$BIN" fleet sim --world "$WORLD" --robots "$ROBOTS" --seed "$seed" --out "$base-clean"
  "$BIN" fleet sim --world "$WORLD" --robots "$ROBOTS" --seed "$seed" \
    --loss 0.3 --disconnect 60 --restart --out "$base-lossy"
done
python3 - "$OUT" "$WORLD" "$ROBOTS" $SEEDS <<'PY'
import json, math, os, sys
out, world, robots, seeds = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
def tum(path):
    rows = [l.split() for l in open(path) if l.strip() and not l.startswith('#')]
    return {round(float(r[0]), 6): (float(r[1]), float(r[2])) for r in rows}
print("| seed | run | merged mean / max error (m) | inter-robot closures accepted / rejected / wrong accepted "
      "| update B per log s per robot (LaserScan B/s) | merged-map B received per robot "
      "| receipt→merged published ms median / p95 | wall s |")
print("|---|---|---|---|---|---|---|---|")
for seed in seeds:
    runs = {}
    for run in ("clean", "lossy"):
        d = os.path.join(out, f"{world}-{robots}-{seed}-{run}")
        r = json.load(open(os.path.join(d, "report.json")))
        runs[run] = d
        m = r["metrics"]
        ups = [x["update_bytes_per_log_second"] for x in r["robots"]]
        raw = [x["laser_scan_bytes_per_log_second"] for x in r["robots"]]
        got = [x["merged_map_received"]["map_bytes"] for x in r["robots"]]
        lat = m["receipt_to_merged_ms"] or {}
        print(f"| {seed} | {run} | {m['merged_mean_position_error_m']:.3f} / {m['merged_max_position_error_m']:.3f} "
              f"| {m['inter_robot_closures_accepted']} / {m['inter_robot_closures_rejected']} / "
              f"{m['inter_robot_closures_accepted_wrong']} | {sum(ups)/len(ups):.0f} ({sum(raw)/len(raw):.0f}) "
              f"| {sum(got)/len(got):.0f} | {lat.get('median_ms', float('nan')):.0f} / {lat.get('p95_ms', float('nan')):.0f} "
              f"| {r['wall_seconds']:.1f} |")
    worst, poses = 0.0, 0
    for k in range(robots):
        name = f"trajectory_robot_{k}.tum"
        present = [os.path.exists(os.path.join(runs[r], "merger", name)) for r in runs]
        assert present[0] == present[1], f"seed {seed} robot {k}: merged in one run only"
        if not present[0]:
            continue
        a = tum(os.path.join(runs["clean"], "merger", name))
        b = tum(os.path.join(runs["lossy"], "merger", name))
        assert a.keys() == b.keys(), f"seed {seed} robot {k}: different poses"
        for t in a:
            worst = max(worst, math.dist(a[t], b[t]))
        poses += len(a)
    print(f"| {seed} | lossy vs clean | largest distance {worst*100:.4f} cm over {poses} merged poses | | | | | |")
PY
