#!/usr/bin/env bash
# Runs the whole test suite on a fresh machine: installs what the tests need, then cargo test.
# The GPU tests run on lavapipe (Mesa's Vulkan on the CPU) where no GPU exists.
set -euo pipefail
cd "$(dirname "$0")/.."

need_packages=()
# libllvm19: Dr.Jit's LLVM backend, so the Mitsuba oracle (tests/oracle_*.rs) runs vectorised.
for package in mesa-vulkan-drivers libvulkan1 libllvm19; do
    dpkg -s "$package" >/dev/null 2>&1 || need_packages+=("$package")
done
# Headless Chromium shows the web viewer and, with X_ITE, the X3D export (tests/viewer.rs).
command -v chromium >/dev/null || need_packages+=(chromium)
# node and npm run the Khronos glTF-Validator (below).
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
    need_packages+=(nodejs npm)
fi
# Slurm and munge run the sharded bake's array jobs (tests/slurm.rs) on a one-node cluster.
for tool in sbatch:slurm-wlm munged:munge; do
    command -v "${tool%%:*}" >/dev/null || need_packages+=("${tool#*:}")
done
if [ ${#need_packages[@]} -gt 0 ]; then
    if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null; then
        echo "ci/test.sh: installing ${need_packages[*]}"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq
        apt-get install -y -qq --no-install-recommends "${need_packages[@]}" >/dev/null
    else
        echo "ci/test.sh: missing ${need_packages[*]} (install them, or GPU, glTF-Validator and browser tests will skip)" >&2
    fi
fi

# The Python reader test (glb::PYTHON_READER) needs numpy.
if ! python3 -c "import numpy" >/dev/null 2>&1; then
    python3 -m pip install --quiet --disable-pip-version-check numpy || echo "ci/test.sh: numpy not installed" >&2
fi
# The lightmap test (tests/lightmap_exr.rs) reads our OpenEXR files with the reference library's
# Python binding. Debian's python refuses pip installs outside a virtual environment (PEP 668),
# hence the second try.
if ! python3 -c "import OpenEXR" >/dev/null 2>&1; then
    python3 -m pip install --quiet --disable-pip-version-check OpenEXR \
        || python3 -m pip install --quiet --disable-pip-version-check --break-system-packages OpenEXR \
        || echo "ci/test.sh: OpenEXR (Python) not installed" >&2
fi

# The Kubernetes manifest test (tests/shards.rs) parses k8s/sharded-bake.yaml with PyYAML.
if ! python3 -c "import yaml" >/dev/null 2>&1; then
    python3 -m pip install --quiet --disable-pip-version-check pyyaml \
        || python3 -m pip install --quiet --disable-pip-version-check --break-system-packages pyyaml \
        || echo "ci/test.sh: PyYAML not installed" >&2
fi

# The independent oracle of the accuracy tests (tests/oracle_*.rs, src/testing/oracle.rs):
# Mitsuba 3's path tracer, pinned with its Dr.Jit.
if ! python3 -c "import mitsuba, drjit; assert mitsuba.__version__ == '3.9.1'" >/dev/null 2>&1; then
    python3 -m pip install --quiet --disable-pip-version-check mitsuba==3.9.1 drjit==1.5.0 \
        || python3 -m pip install --quiet --disable-pip-version-check --break-system-packages \
            mitsuba==3.9.1 drjit==1.5.0 \
        || echo "ci/test.sh: Mitsuba (Python) not installed" >&2
fi
if [ -z "${DRJIT_LIBLLVM_PATH:-}" ] && [ -e /usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 ]; then
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
fi

# A one-node Slurm cluster for tests/slurm.rs (root only: it starts munged, slurmctld, slurmd).
if [ "$(id -u)" -eq 0 ] && command -v slurmctld >/dev/null; then
    ci/slurm/start-cluster.sh || echo "ci/test.sh: the Slurm cluster did not start" >&2
fi

# npm packages the tests run, each at the version pinned in its package-lock.json; installed
# again only when the lock file changed since.
install_pinned() { # DIR WHAT
    local installed_lock="$1/node_modules/.installed-package-lock.json"
    if command -v npm >/dev/null && ! cmp -s "$1/package-lock.json" "$installed_lock"; then
        echo "ci/test.sh: installing $2 (npm ci --prefix $1)"
        if npm ci --prefix "$1" --no-audit --no-fund --loglevel=error >/dev/null; then
            cp "$1/package-lock.json" "$installed_lock"
        else
            echo "ci/test.sh: $2 is not installed" >&2
        fi
    fi
}
# The Khronos glTF-Validator, which every written file must pass (src/gltf_validator.rs).
install_pinned ci/gltf-validator "the glTF-Validator"
# X_ITE, the X3D browser the X3D export is loaded in (tests/viewer.rs).
install_pinned ci/x3d "X_ITE"
# three.js, the engine relit lightmaps are loaded in (tests/lightmaps.rs).
install_pinned ci/three "three.js"

# Mesa's drivers complain on stderr without a runtime directory (headless machines).
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
cargo test --locked "$@"
