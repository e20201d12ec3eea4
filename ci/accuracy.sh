#!/usr/bin/env bash
# Regenerates docs/accuracy.md: every capability against the path tracer (Mitsuba 3), as the
# oracle tests measure it. Needs what ci/test.sh installs (Mitsuba, libLLVM 19).
set -euo pipefail
cd "$(dirname "$0")/.."
export DRJIT_LIBLLVM_PATH="${DRJIT_LIBLLVM_PATH:-/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1}"
# `ci/accuracy.sh LOG` takes the rows from a log of those tests run with --nocapture instead
# of running them again.
if [ $# -ge 1 ]; then
    log="$1"
else
    log=$(mktemp)
    trap 'rm -f "$log"' EXIT
    cargo test --release --locked --test oracle_distant --test oracle_local --test oracle_probes -- --nocapture \
        --test-threads 1 >"$log" 2>&1 || { tail -40 "$log" >&2; exit 1; }
fi
{
    cat <<'HEAD'
# Accuracy against an independent path tracer

Every figure is the RMS of prt-gpu's exit radiance minus Mitsuba 3's (path tracing the same
prepared scene: positions, the baker's shading normals, per-vertex albedo), over the RMS of
Mitsuba's, at the points named; beside it the oracle's own noise on that RMS (its standard
errors, combined as an RMS). Distant light is a band-limited sky of 3 bands (exact in a bake of
4 bands); local lights are point and spot lights of the intensities given. Vertices compared:
those whose normal is within 10 degrees of every face around them and that touch no other part
(`oracle::measurable_vertices`). The notes give the bake's own noise (two seeds), what lies
beyond both noises (`sqrt(error^2 - oracle^2 - bake^2)`), and for interpolated representations
their measured floor: for local lights the difference the vertex representation of the bounced
light makes (the bake's gather rays with the direct light exact at each hit point), for
least-squares vertices and lightmap texels the difference from the baker at the points
themselves. Probes: irradiance at free points for random normals against Mitsuba's (cosine-distributed
paths from the point). The tests (`tests/oracle_distant.rs`, `tests/oracle_local.rs`,
`tests/oracle_probes.rs`) assert the bounds;
this table is their printed figures, made by `ci/accuracy.sh`.

| what | error | oracle noise | notes |
|---|---:|---:|---|
HEAD
    grep '^accuracy-row |' "$log" | sed 's/^accuracy-row //'
    echo
    echo "Made by \`ci/accuracy.sh\` on $(date -u +%Y-%m-%d) ($(grep -m1 -o 'llvm_ad_rgb [0-9.]*\|scalar_rgb [0-9.]*' "$log" || echo Mitsuba))."
} >docs/accuracy.md
echo "wrote docs/accuracy.md ($(grep -c '^accuracy-row |' "$log") rows)"
