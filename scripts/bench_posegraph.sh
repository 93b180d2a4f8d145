#!/usr/bin/env bash
# Side-by-side benchmark of the SE(3) pose-graph optimiser: slamkit's `vo::pose_graph`
# (Levenberg–Marquardt, sparse block elimination; the `posegraph` example of slamkit-vo) and
# GTSAM's Levenberg–Marquardt (PyPI gtsam, scripts/posegraph_gtsam.py) on the same g2o file, the
# same cost (½ Σ eᵀΩe with the SE(3) log-map error) and the same gauge (first vertex held).
# Both run in this one invocation on the same machine: time is the wall time of the
# optimisation, median of REPEATS (3), file reading excluded.
# usage: [REPEATS=3] scripts/bench_posegraph.sh [FILE.g2o]
#        (default $SLAMKIT_DATA/posegraph/parking-garage.g2o; creates a venv with gtsam in
#        out/venv-gtsam on first use)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
file=${1:-${SLAMKIT_DATA:?set SLAMKIT_DATA or pass a file}/posegraph/parking-garage.g2o}
repeats=${REPEATS:-3}
venv=$root/out/venv-gtsam
if [[ ! -x $venv/bin/python ]] || ! "$venv/bin/python" -c 'import gtsam' 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q gtsam==4.3.0 numpy
fi
cargo build --release -q -p slamkit-vo --example posegraph --manifest-path "$root/Cargo.toml"
target=${CARGO_TARGET_DIR:-$root/target}
slamkit_json=$("$target/release/examples/posegraph" "$file" "$repeats")
gtsam_json=$("$venv/bin/python" "$root/scripts/posegraph_gtsam.py" "$file" "$repeats")
python3 - "$slamkit_json" "$gtsam_json" <<'PY'
import json, sys
s, g = json.loads(sys.argv[1]), json.loads(sys.argv[2])
print(f"{'':12} {'initial cost':>14} {'final cost':>14} {'iterations':>10} {'median s':>9}  times s")
for r in (s, g):
    print(f"{r['optimiser']:12} {r['initial_cost']:14.6f} {r['final_cost']:14.9f} "
          f"{r['iterations']:10d} {r['median_s']:9.3f}  {r['times_s']}")
rel = abs(s['final_cost'] - g['final_cost']) / g['final_cost']
print(f"final cost relative difference {rel:.2e}; time slamkit / gtsam {s['median_s'] / g['median_s']:.2f}")
PY
