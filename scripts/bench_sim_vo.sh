#!/usr/bin/env bash
# RGB-D visual odometry on simulated 60 s office sequences, one per seed (issue #5's bound:
# ATE RMSE <= 0.02 m): the setup of crates/cli/tests/cli/vo_sim.rs (ground robot at 0.25 m/s, camera
# at 15 Hz) for several seeds; prints render time per frame and ATE RMSE per seed.
# usage: scripts/bench_sim_vo.sh [SEED ...]      (default seeds 1 2 3 4 5)
# VO=FILE passes a `slamkit vo --config` file (e.g. `[motion]\nweight_by_noise = false`).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${OUT:-$root/out/bench-sim-vo}
seeds=("${@:-1 2 3 4 5}")
vo_config=()
if [ -n "${VO:-}" ]; then vo_config=(--config "$VO"); fi
mkdir -p "$out"
cargo build --release -q -p slamkit --manifest-path "$root/Cargo.toml"
slamkit=${CARGO_TARGET_DIR:-$root/target}/release/slamkit
printf '[rgbd]\nrate_hz = 15.0\n[diff_drive]\nspeed_mps = 0.25\n' > "$out/sim.toml"
echo "| seed | render ms/frame (median) | VO ms/frame (median) | ATE RMSE (m) | failed frames |"
echo "|---|---|---|---|---|"
for seed in ${seeds[@]}; do
  "$slamkit" sim --world office --robot diff-drive --sensors rgbd --duration 60 --seed "$seed" \
    --config "$out/sim.toml" --out "$out/sim-$seed" >/dev/null
  "$slamkit" vo "$out/sim-$seed/tum_rgbd_fr1" "${vo_config[@]}" --out "$out/vo-$seed" >/dev/null
  python3 - "$out/sim-$seed/report.json" "$out/vo-$seed/report.json" "$seed" <<'PY'
import json, sys
sim, vo = (json.load(open(p)) for p in sys.argv[1:3])
render = sim["timings_ms"]["render_rgbd"]["median_ms"]
stages = vo.get("timings_ms", {})
frame = stages.get("frame", stages.get("total", {})).get("median_ms", float("nan"))
print(f"| {sys.argv[3]} | {render:.1f} | {frame:.1f} | {vo['metrics']['ate']['rmse']:.4f} | {vo['frames']['failed']} |")
PY
done
python3 - "$out" ${seeds[@]} <<'PY'
import json, statistics, sys
ate = [json.load(open(f"{sys.argv[1]}/vo-{s}/report.json"))["metrics"]["ate"]["rmse"] for s in sys.argv[2:]]
print(f"ATE RMSE median {statistics.median(ate):.4f} m, max {max(ate):.4f} m over {len(ate)} seeds")
PY
