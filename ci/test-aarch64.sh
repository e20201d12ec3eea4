#!/usr/bin/env bash
# Cross-builds for aarch64 and runs the CPU packet tests there under qemu-aarch64: the NEON copy
# of the ray-packet traversal against single rays, and every copy against the portable one.
# Not part of ci/test.sh (it compiles every dependency a second time, several minutes on two
# cores); run it after changing src/packet/.
set -euo pipefail
cd "$(dirname "$0")/.."

need_packages=()
for package in qemu-user gcc-aarch64-linux-gnu libc6-dev-arm64-cross; do
    dpkg -s "$package" >/dev/null 2>&1 || need_packages+=("$package")
done
if [ ${#need_packages[@]} -gt 0 ]; then
    echo "ci/test-aarch64.sh: installing ${need_packages[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${need_packages[@]}" >/dev/null
fi
rustup target add aarch64-unknown-linux-gnu

export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="qemu-aarch64 -L /usr/aarch64-linux-gnu"
cargo test --locked --release --target aarch64-unknown-linux-gnu --lib -- packet bake::cpu "$@"
