// Relighting probes for one frame: one invocation per (probe, row) of the probes from
// `first_probe` on, relit[(p * rows + i) * 3 + rgb] = row i of channel min(rgb, channels - 1)
// of probe p's matrix times the light's coefficients of colour rgb. Rust twin:
// probes::ProbeSet::relight (GPU side: probes::gpu::GpuProbes). Each loop runs over one row's
// coefficients (at most 1,024), far below llvmpipe's iteration cap.

struct ProbeRelightParams {
    probes: u32,
    rows: u32,
    coeffs: u32,
    channels: u32,
    first_probe: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: ProbeRelightParams;
// [probe][channel][row][k]
@group(0) @binding(1) var<storage, read> matrices: array<f32>;
// [k][rgb]
@group(0) @binding(2) var<storage, read> light: array<f32>;
// [probe][row][rgb]
@group(0) @binding(3) var<storage, read_write> relit: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let index = params.first_probe * params.rows + id.x;
    if (index >= params.probes * params.rows) {
        return;
    }
    let p = index / params.rows;
    let i = index % params.rows;
    let per_probe = params.channels * params.rows * params.coeffs;
    for (var rgb = 0u; rgb < 3u; rgb += 1u) {
        let c = min(rgb, params.channels - 1u);
        let row = p * per_probe + (c * params.rows + i) * params.coeffs;
        var total = 0.0;
        for (var k = 0u; k < params.coeffs; k += 1u) {
            total += matrices[row + k] * light[k * 3u + rgb];
        }
        relit[index * 3u + rgb] = total;
    }
}
