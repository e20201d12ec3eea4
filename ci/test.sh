#!/usr/bin/env bash
# Runs the whole test suite on a fresh machine: installs what the tests need, then cargo test.
# The GPU tests run on lavapipe (Mesa's Vulkan on the CPU) where no GPU exists.
set -euo pipefail
cd "$(dirname "$0")/.."

need_packages=()
for package in mesa-vulkan-drivers libvulkan1; do
    dpkg -s "$package" >/dev/null 2>&1 || need_packages+=("$package")
done
if [ ${#need_packages[@]} -gt 0 ]; then
    if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null; then
        echo "ci/test.sh: installing ${need_packages[*]}"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq
        apt-get install -y -qq --no-install-recommends "${need_packages[@]}" >/dev/null
    else
        echo "ci/test.sh: missing ${need_packages[*]} (install them, or GPU tests will skip)" >&2
    fi
fi

# The Python reader test (glb::PYTHON_READER) needs numpy.
if ! python3 -c "import numpy" >/dev/null 2>&1; then
    python3 -m pip install --quiet --disable-pip-version-check numpy || echo "ci/test.sh: numpy not installed" >&2
fi

# Mesa's drivers complain on stderr without a runtime directory (headless machines).
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
cargo test --locked "$@"
