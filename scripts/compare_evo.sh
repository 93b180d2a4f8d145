#!/usr/bin/env bash
# Compares `slamkit eval` with evo (github.com/MichaelGrupp/evo) on the trajectory pairs of
# $SLAMKIT_DATA/trajectories/evo_test_data: ATE (se3, sim3, none) and RPE (frames, metres).
# Prints a side-by-side table and exits non-zero if any statistic differs by more than 1e-6
# (or any pair count differs).
#
#   SLAMKIT_DATA=/path/to/data scripts/compare_evo.sh
#
# evo is installed into .venv-evo (gitignored) at the repository root.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
: "${SLAMKIT_DATA:?set SLAMKIT_DATA to the data folder (see README.md)}"
venv="${EVO_VENV:-$root/.venv-evo}"
evo_version="1.38.*"

if [ ! -x "$venv/bin/evo_ape" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet "evo==$evo_version"
fi

cargo build --quiet --release -p slamkit --manifest-path "$root/Cargo.toml"
slamkit="${CARGO_TARGET_DIR:-$root/target}/release/slamkit"

exec "$venv/bin/python" "$root/scripts/compare_evo.py" \
    --data "$SLAMKIT_DATA/trajectories/evo_test_data" \
    --slamkit "$slamkit" \
    --evo-bin "$venv/bin"
