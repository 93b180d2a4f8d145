#!/usr/bin/env bash
# slamkit on ARM: cross-builds for aarch64-unknown-linux-gnu (Debian's cross gcc as the linker)
# and runs unit tests under qemu-aarch64, as a Raspberry Pi class board would run them: no AVX2
# there, so the portable paths of the hand-vectorised kernels are the ones tested. By default
# the crates `.ci/run` checks: vision (every kernel with an AVX2 copy and its portable
# fallback), core and map (the geometry and grids under them). Name others to add them (lidar
# is portable Rust with no kernel of its own: its unit tests took 69 s emulated, and its
# test build as much again, so CI leaves it to x86-64). Installs what it needs (rust-std for
# the target, gcc-aarch64-linux-gnu, qemu-user).
#
#     scripts/arm_tests.sh [CRATE ...]          e.g. scripts/arm_tests.sh core vision map lidar
set -euo pipefail
cd "$(dirname "$0")/.."

target=aarch64-unknown-linux-gnu
rustup target add "$target" >/dev/null
if ! command -v aarch64-linux-gnu-gcc >/dev/null || ! command -v qemu-aarch64 >/dev/null; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
        gcc-aarch64-linux-gnu libc6-dev-arm64-cross qemu-user >/dev/null
fi

export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="qemu-aarch64 -L /usr/aarch64-linux-gnu"

# The unit tests of the named crates under emulation (the whole CLI is not cross-built in CI:
# it would double this step's time). With lidar, the particle filter's scenario tests and
# ICP-SLAM's laps on mapped ground (seconds natively, minutes emulated) are left to x86-64.
packages=()
for crate in "${@:-core vision map}"; do
    for c in $crate; do packages+=(-p "slamkit-$c"); done
done
cargo test --profile arm-test --quiet --target "$target" "${packages[@]}" --lib -- \
    --skip rbpf::tests:: --skip icp_slam::tests::laps_on_mapped_ground
