#!/usr/bin/env bash
# The hardware-GPU benchmark: one prepared script for a machine with a real GPU (Vulkan), meant
# to finish in under 5 minutes there. Builds in release, lists the adapters, times the direct
# pass on the CPU and GPU backends side by side (`prt-gpu bench`), bakes on the GPU the
# dragon and the largest mesh in the repository, printing rays/s per backend and the adapter,
# compresses the dragon (CPCA) with the clustering on the CPU and on the GPU, and bakes probes
# around it on each (the 'probes:' line's seconds).
# Record its output in docs/performance.md ("On a hardware GPU").
#
#   ci/device-bench.sh [OUT_DIR] [MESH...]
#
# OUT_DIR defaults to target/device-bench (the log goes there too); MESHes are benched after the
# repository's two. A machine with no Rust toolchain or no network (the usual GPU box) takes a
# binary built elsewhere for the same architecture: PRT_GPU_BIN=path/to/prt-gpu skips the build.
# PRT_GPU_BASELINE_BIN=path/to/an-older-prt-gpu first benches the dragon on the GPU with both
# binaries in turn, twice, so that a change is measured side by side on the same card (e.g.
# e382ecc, the last binary whose GPU walked the binary tree, against the four-wide one).
set -uo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/device-bench}
shift $(( $# > 0 ? 1 : 0 ))
mkdir -p "$out"
exec > >(tee "$out/device-bench.log") 2>&1

say() { printf '\n== %s\n' "$*"; }
started=$(date +%s)

say "machine"
uname -srm
nproc
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader

say "Vulkan"
# wgpu reaches the GPU through the Vulkan loader (libvulkan.so.1) and the driver's ICD file.
if ! ldconfig -p 2>/dev/null | grep -q 'libvulkan\.so\.1'; then
    if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null; then
        echo "the Vulkan loader is missing: installing libvulkan1"
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends libvulkan1 >/dev/null \
            || echo "MISSING: could not install libvulkan1 (the Vulkan loader); wgpu will see no Vulkan adapter"
    else
        echo "MISSING: the Vulkan loader libvulkan.so.1 (Debian/Ubuntu: apt-get install libvulkan1)"
    fi
fi
icds=$(ls /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json 2>/dev/null || true)
echo "ICD files: ${icds:-none}"
if command -v nvidia-smi >/dev/null && ! grep -qil nvidia $icds /dev/null 2>/dev/null; then
    echo "MISSING: an NVIDIA GPU is present but no nvidia_icd.json: the driver's Vulkan part is not"
    echo "  installed beside it (install the driver's Vulkan ICD, e.g. libnvidia-gl-<version>, or"
    echo "  point VK_ICD_FILENAMES at the driver's nvidia_icd.json)"
    for candidate in /usr/share/vulkan/icd.d/nvidia_icd.json /etc/vulkan/icd.d/nvidia_icd.json \
        /usr/lib/x86_64-linux-gnu/nvidia/nvidia_icd.json \
        /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json; do
        # The loader reads VK_DRIVER_FILES since 1.3.234 and VK_ICD_FILENAMES before it.
        [ -e "$candidate" ] && export VK_DRIVER_FILES=$candidate VK_ICD_FILENAMES=$candidate \
            && echo "  using $candidate"
    done
fi

if [ -n "${PRT_GPU_BIN:-}" ]; then
    bin=$PRT_GPU_BIN
    say "prebuilt binary $bin"
    "$bin" --version || { echo "FAILED: $bin does not run here"; exit 1; }
else
    say "build (release)"
    cargo build --release --locked --quiet || { echo "FAILED: cargo build --release"; exit 1; }
    bin=target/release/prt-gpu
fi

say "adapters"
$bin devices
if ! $bin devices 2>/dev/null | grep -qiE 'discrete|integrated'; then
    echo "NOTE: no hardware adapter: the GPU figures below are a software adapter's, not a GPU's"
fi

dragon=tests/data/dragon_vrip_res3.ply.gz
if [ -n "${PRT_GPU_BASELINE_BIN:-}" ]; then
    for round in 1 2; do
        for side in "$PRT_GPU_BASELINE_BIN" "$bin"; do
            say "side by side, round $round: $side bench $dragon (shadowed, then interreflected)"
            "$side" bench "$dragon" --device gpu --repeats 3 | grep -E '^gpu'
            "$side" bench "$dragon" --device gpu --repeats 3 --mode interreflected | grep -E '^gpu'
        done
    done
fi
largest=$(ls -S tests/data/*.obj tests/data/*.ply.gz tests/data/gltf/*.glb 2>/dev/null | head -1)
for mesh in "$dragon" "$largest" "$@"; do
    say "bench $mesh (CPU and GPU side by side, 1024 samples, shadowed; shadow and diffuse ray sets)"
    $bin bench "$mesh" --device gpu --repeats 3 --ray-sets
    say "bench $mesh (interreflected)"
    $bin bench "$mesh" --device gpu --repeats 3 --mode interreflected
    say "GPU bake of $mesh (interreflected, 3 bounces)"
    $bin bake "$mesh" --device gpu --mode interreflected -o "$out/$(basename "$mesh").prt.glb"
done

for device in cpu gpu; do
    say "CPCA of $dragon, clustering on the $device (lean, 384x8, f16; the 'compressed:' line)"
    $bin bake "$dragon" --device $device --storage lean --compress 384x8 --precision f16 \
        -o "$out/dragon.$device.cpca.glb" 2>&1 | grep -E 'compressed|baked'
done

for device in cpu gpu; do
    say "probes around $dragon on the $device (interreflected, a grid 0.01 apart; the 'probes:' line)"
    $bin bake "$dragon" --device $device --mode interreflected --probes 0.01 \
        -o "$out/dragon.$device.probes.glb" 2>&1 | grep -E '^probes|baked'
done

say "done in $(( $(date +%s) - started )) s"
