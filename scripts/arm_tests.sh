#!/usr/bin/env bash
# slamkit on ARM: cross-builds for aarch64-unknown-linux-gnu (Debian's cross gcc as the linker)
# and runs the unit tests of the crates with hand-vectorised kernels and their portable
# fallbacks (core, vision, map, lidar) under qemu-aarch64, as a Raspberry Pi class board would
# run them: no AVX2 there, so the portable paths are the ones tested. Installs what it needs
# (rust-std for the target, gcc-aarch64-linux-gnu, qemu-user); `.ci/run` runs it.
#
#     scripts/arm_tests.sh
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

# The unit tests of the crates with SIMD kernels and their portable fallbacks, under emulation
# (the whole CLI is not cross-built in CI: it would double this step's time).
# The particle filter's scenario tests and ICP-SLAM's laps on mapped ground (seconds natively,
# minutes emulated, no kernel of their own) run on x86-64 only.
cargo test --release --quiet --target "$target" \
    -p slamkit-core -p slamkit-vision -p slamkit-map -p slamkit-lidar --lib -- --skip rbpf::tests:: \
    --skip icp_slam::tests::laps_on_mapped_ground
