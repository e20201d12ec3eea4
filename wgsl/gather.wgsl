// Bounce pass: one invocation per (row, channel, coefficient) of a chunk of rows of the gather
// matrix; `next = albedo * sum_j weight_j * previous[j]`. Rust twin: bake::bounce::apply_cpu.
// Rows longer than `entry_limit` are done in several passes (`entry_begin` advances and
// `accumulate` adds), keeping every invocation's loop far below llvmpipe's iteration cap.

struct GatherParams {
    // First matrix row of this chunk; row_offsets are rebased to the chunk's entry arrays.
    row_offset: u32,
    row_count: u32,
    coeff_count: u32,
    entry_begin: u32,
    entry_limit: u32,
    accumulate: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: GatherParams;
@group(0) @binding(1) var<storage, read> row_offsets: array<u32>;
@group(0) @binding(2) var<storage, read> columns: array<u32>;
@group(0) @binding(3) var<storage, read> weights: array<f32>;
@group(0) @binding(4) var<storage, read> albedo: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> previous: array<f32>;
@group(0) @binding(6) var<storage, read_write> next: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let per_row = 3u * params.coeff_count;
    let index = id.x;
    if (index >= params.row_count * per_row) {
        return;
    }
    let local_row = index / per_row;
    let channel = (index % per_row) / params.coeff_count;
    let k = index % params.coeff_count;
    let row_end = row_offsets[local_row + 1u];
    let begin = min(row_offsets[local_row] + params.entry_begin, row_end);
    let end = min(begin + params.entry_limit, row_end);
    var total = 0.0;
    for (var e = begin; e < end; e += 1u) {
        total += weights[e] * previous[columns[e] * per_row + channel * params.coeff_count + k];
    }
    let row = params.row_offset + local_row;
    let out = row * per_row + channel * params.coeff_count + k;
    var value = albedo[row][channel] * total;
    if (params.accumulate != 0u) {
        value += next[out];
    }
    next[out] = value;
}
