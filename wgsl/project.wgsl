// Projection pass: one invocation per (vertex, coefficient) of a chunk; sums
// cos(n, w_s) y_k(w_s) over the samples whose visibility bit is set (or over the blocked ones,
// or without the cosine: see ESTIMATOR_*). Rust twin: bake::cpu::project_visibility. Sums run per 32-sample word and are then added, which keeps
// the f32 rounding error near (32 + samples/32) ulps instead of growing with the sample count.

struct ProjectParams {
    vertex_offset: u32,
    vertex_count: u32,
    sample_offset: u32,
    sample_count: u32,
    words_per_vertex: u32,
    coeff_count: u32,
    // 1: add to what `transfer` holds (later sample chunks); 0: overwrite.
    accumulate: u32,
    estimator: u32,
}

// Flags of `estimator`; Rust twin: bake::gpu::kernels::estimator_flags. Without flags: sum over
// visible samples of the cosine times y_k.
// ESTIMATOR_BLOCKED: sum over samples above the horizon that are blocked
// (sampling::Estimator::Blocked). ESTIMATOR_TANGENT: directions in the tangent frame with cosine
// density, no cosine factor. Both are generated from src/shaders.rs.

@group(0) @binding(0) var<uniform> params: ProjectParams;
@group(0) @binding(1) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> directions: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> sh_table: array<f32>;
@group(0) @binding(4) var<storage, read> visible_bits: array<u32>;
@group(0) @binding(5) var<storage, read_write> transfer: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let index = id.x;
    if (index >= params.vertex_count * params.coeff_count) {
        return;
    }
    let local_vertex = index / params.coeff_count;
    let k = index % params.coeff_count;
    let normal = normals[params.vertex_offset + local_vertex].xyz;
    let sums_blocked = (params.estimator & ESTIMATOR_BLOCKED) != 0u;
    let tangent = (params.estimator & ESTIMATOR_TANGENT) != 0u;
    var total = 0.0;
    for (var word = 0u; word < params.words_per_vertex; word += 1u) {
        let bits = visible_bits[local_vertex * params.words_per_vertex + word];
        let bits_in_word = min(32u, params.sample_count - min(params.sample_count, word * 32u));
        let in_word = select(0u, 0xffffffffu >> (32u - bits_in_word), bits_in_word > 0u);
        // Candidate samples in ascending order: llvmpipe pays for every storage read, so only
        // candidates read their direction and SH value.
        var rest = select(bits, ~bits & in_word, sums_blocked);
        var partial = 0.0;
        while (rest != 0u) {
            let bit = firstTrailingBit(rest);
            rest &= rest - 1u;
            let sample = params.sample_offset + word * 32u + bit;
            let direction = directions[sample].xyz;
            let cosine = select(dot(normal, direction), direction.z, tangent);
            // A clear bit below the horizon was never cast: it is not blocked.
            if (sums_blocked && cosine <= 0.0) {
                continue;
            }
            let weight = select(cosine, 1.0, tangent);
            partial += weight * sh_table[sample * params.coeff_count + k];
        }
        total += partial;
    }
    if (params.accumulate != 0u) {
        total += transfer[index];
    }
    transfer[index] = total;
}
