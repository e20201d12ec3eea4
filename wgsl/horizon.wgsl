// Horizon pass: for each vertex of a chunk, lists the chunk's samples above its horizon
// (chunk-local indices, in the order of the set's fan runs), then NO_SAMPLE to the end of its
// row: the list the visibility pass walks, so that its SIMD groups trace rays rather than idle
// below the horizon, and trace neighbouring directions side by side.
// It also counts the listed samples (the rays a shadowed pass casts), sizes the visibility
// pass's indirect dispatch to the longest list, and, for a closest-hit pass, writes NO_HIT to
// the hits of the samples it leaves out, so that the host reads a row's hits without its list.
// Rust twin: bake::cpu::trace_visibility (its horizon test); the tests hold the lists to the
// host's, built as bake::gpu::horizon's tests build them.
// Dispatch: one workgroup per vertex (y), WORKGROUP_SIZE samples at a time: each invocation
// tests one sample, and a prefix sum over the workgroup places the ones above the horizon.

struct HorizonParams {
    vertex_offset: u32,
    vertex_count: u32,
    sample_offset: u32,
    sample_count: u32,
    // FRAMES_*: world directions, each vertex's tangent frame (cosine-weighted sampling), or
    // that frame turned by the vertex's own angle.
    frames: u32,
    // 1: the visibility pass records hits; write NO_HIT for the samples left out.
    record_hits: u32,
    // Vertex v turns by receiver_turn(turn_seed, turn_first + v).
    turn_seed: u32,
    turn_first: u32,
}

@group(0) @binding(0) var<uniform> params: HorizonParams;
// Read for its pad word only (`rounded`, wgsl/bvh.wgsl).
@group(0) @binding(1) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> directions: array<vec4<f32>>;
// [local_vertex * sample_count + slot].
@group(0) @binding(4) var<storage, read_write> sample_lists: array<u32>;
// (low, high) words of the samples listed in this run, summed over its chunks.
@group(0) @binding(5) var<storage, read_write> listed: array<atomic<u32>, 2>;
// The visibility pass's workgroup counts (x, y, z); the host sets (0, vertices, 1) per chunk.
@group(0) @binding(6) var<storage, read_write> visibility_groups: array<atomic<u32>, 3>;
// As the visibility pass's `hits`.
@group(0) @binding(7) var<storage, read_write> hits: array<Hit>;
// Per sample chunk, its samples (chunk-local indices) in the order of the set's fan runs
// (`SampleSet::fan_runs`), at [sample_offset + position]; built by
// bake::gpu::horizon::listing_order.
@group(0) @binding(8) var<storage, read> listing_order: array<u32>;
// Declared for wgsl/bvh.wgsl's traversal, which this pass does not call (so it is not bound).
@group(0) @binding(9) var<storage, read> nodes: array<vec4<u32>>;

// Inclusive prefix sums of the workgroup's flags, one per invocation.
var<workgroup> prefix: array<u32, WORKGROUP_SIZE>;

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(local_invocation_index) lane: u32, @builtin(workgroup_id) group: vec3<u32>) {
    read_unseen_zero();
    // One workgroup per vertex: every branch on it is uniform, this return included.
    let local_vertex = group.y;
    if (local_vertex >= params.vertex_count) {
        return;
    }
    let vertex = params.vertex_offset + local_vertex;
    let normal = normals[vertex].xyz;
    let frame = receiver_frame(normal, params.frames, params.turn_seed, params.turn_first + vertex);
    let row = local_vertex * params.sample_count;
    var count = 0u;
    for (var first = 0u; first < params.sample_count; first += WORKGROUP_SIZE) {
        let position = first + lane;
        var sample = 0u;
        var above = false;
        if (position < params.sample_count) {
            sample = listing_order[params.sample_offset + position];
            var direction = directions[params.sample_offset + sample].xyz;
            if (params.frames != 0u) {
                direction = to_world(frame, direction);
            }
            above = above_horizon(normal, direction);
            if (!above && params.record_hits != 0u) {
                hits[row + sample] = Hit(NO_HIT, 0.0, 0.0);
            }
        }
        // Hillis–Steele scan: after step k each entry sums the 2^k flags ending at it.
        prefix[lane] = u32(above);
        workgroupBarrier();
        for (var step = 1u; step < WORKGROUP_SIZE; step <<= 1u) {
            var before = 0u;
            if (lane >= step) {
                before = prefix[lane - step];
            }
            workgroupBarrier();
            prefix[lane] += before;
            workgroupBarrier();
        }
        if (above) {
            sample_lists[row + count + prefix[lane] - 1u] = sample;
        }
        count += prefix[WORKGROUP_SIZE - 1u];
        // Every invocation has read the sums before the next tile overwrites them.
        workgroupBarrier();
    }
    for (var slot = count + lane; slot < params.sample_count; slot += WORKGROUP_SIZE) {
        sample_lists[row + slot] = NO_SAMPLE;
    }
    if (lane == 0u) {
        let low = atomicAdd(&listed[0], count);
        if (low + count < low) {
            atomicAdd(&listed[1], 1u);
        }
        atomicMax(&visibility_groups[0], (count + WORKGROUP_SIZE - 1u) / WORKGROUP_SIZE);
    }
}
