#!/usr/bin/env bash
# Builds slamkit's Python wheel (crates/py, abi3: one wheel for CPython >= 3.9), installs it
# into a fresh virtualenv with the test tools, and runs the Python tests (crates/py/tests) and
# the example. `.ci/run` runs this; run it by hand the same way:
#
#     SLAMKIT_DATA=../shared/data scripts/python_tests.sh
#
# Versions are pinned so a run today and a run next month test the same thing.
set -euo pipefail
cd "$(dirname "$0")/.."

venv=target/py-venv
wheels=target/wheels
python="${PYTHON:-python3}"

tools=(maturin==1.16.0 pytest==9.2.0 numpy==2.4.6 evo==1.38.1 mcap==1.6.0)

# The virtualenv with the test tools: made fresh unless it already holds exactly these
# versions and no slamkit (VENV_ONLY=1 makes only it: `.ci/run` installs it while the builds
# run, so pip's downloads wait on the network beside them).
if ! "$venv/bin/python" - "${tools[@]}" 2>/dev/null <<'PY'
import importlib.metadata as m, sys
pins = dict(t.split("==") for t in sys.argv[1:])
try:
    m.version("slamkit")
    sys.exit(1)
except m.PackageNotFoundError:
    pass
sys.exit(any(m.version(name) != version for name, version in pins.items()))
PY
then
    rm -rf "$venv"
    "$python" -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check "${tools[@]}"
fi
if [ "${VENV_ONLY:-}" = 1 ]; then
    exit 0
fi
rm -rf "$wheels"

# The release profile, as the CLI the tests compare with is built.
"$venv/bin/maturin" build --quiet --release --manifest-path crates/py/Cargo.toml --out "$wheels"
"$venv/bin/pip" install --quiet --disable-pip-version-check --no-index "$wheels"/slamkit-*.whl

# From the repository's root, so `import slamkit` finds the installed wheel, not a folder.
"$venv/bin/python" -c "import slamkit; print('slamkit', slamkit.__version__, 'from', slamkit.__file__)"
cargo build --release --quiet -p slamkit
SLAMKIT_BIN="$PWD/target/release/slamkit" "$venv/bin/python" -m pytest -q crates/py/tests
