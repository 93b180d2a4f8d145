#!/usr/bin/env python3
"""Checks that crates/workspace-hack pins every shared dependency's features.

Cargo compiles a dependency once per feature set. The README's test command resolves
features over the whole workspace with dev-dependencies; `cargo run -- demo`, `cargo build -p
slamkit` (the ROS 2 and Python scripts) and maturin's build of slamkit-py resolve them over
fewer packages. Any dependency whose features differ between those and the test build is
compiled twice, with everything above it; this script names each such dependency and the
features to add to crates/workspace-hack/Cargo.toml.

It reads Cargo's unit graph, the exact list of what each command would compile. That output is
unstable (`-Z unstable-options`), so RUSTC_BOOTSTRAP=1 is set for these read-only queries;
nothing is built.
"""
import json
import os
import subprocess
import sys

ENV = dict(os.environ, RUSTC_BOOTSTRAP="1")
REFERENCE = ["test", "--workspace", "--release", "--no-run"]
OTHERS = {
    # `cargo run` in this virtual workspace resolves over every member, then builds the one binary.
    "cargo run --release -- demo": ["build", "--release", "--bins"],
    "cargo build --release -p slamkit": ["build", "--release", "-p", "slamkit"],
    "maturin build --release (slamkit-py)": ["build", "--release", "-p", "slamkit-py", "--lib"],
    "cargo bench --workspace --no-run": ["bench", "--workspace", "--no-run"],
}


def units(args):
    """(package@version, target, mode, opt-level) -> the feature sets cargo would compile."""
    out = subprocess.run(
        ["cargo", *args, "--unit-graph", "-Z", "unstable-options"],
        env=ENV, capture_output=True, text=True, check=True,
    ).stdout
    found = {}
    for unit in json.loads(out)["units"]:
        key = (
            unit["pkg_id"].split("#")[-1],
            unit["target"]["name"],
            unit["mode"],
            unit["profile"]["opt_level"],
        )
        found.setdefault(key, set()).add(tuple(sorted(unit["features"])))
    return found


def main():
    reference = units(REFERENCE)
    drift = 0
    for name, args in OTHERS.items():
        for key, feature_sets in sorted(units(args).items()):
            if key not in reference:
                continue  # compiled only by this command (pyo3 for the wheel): nothing shared
            for features in sorted(feature_sets - reference[key]):
                package, target, mode, opt = key
                wanted = " | ".join(",".join(f) for f in sorted(reference[key]))
                print(f"{name}: {package} ({target}, {mode}, opt-level {opt}) "
                      f"gets [{','.join(features)}], the test build [{wanted}]")
                drift += 1
    if drift:
        print(f"{drift} dependencies would be compiled twice: add the test build's features "
              "to crates/workspace-hack/Cargo.toml", file=sys.stderr)
        return 1
    print("workspace-hack: every command compiles the shared dependencies with the test build's features")
    return 0


if __name__ == "__main__":
    sys.exit(main())
