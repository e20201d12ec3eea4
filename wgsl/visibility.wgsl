// Visibility pass: one invocation per (vertex, sample) of a chunk; sets the bit of every ray
// that is above the vertex's horizon and unblocked, and, for interreflection, records where a
// blocked ray hits. Rust twins: bake::cpu::trace_visibility, bake::bounce::hits_and_visibility.
// Dispatch: x over the slots of the vertices' sample lists (WORKGROUP_SIZE per group), y over
// vertices: a workgroup casts consecutive above-horizon sample directions from one vertex. Measured on lavapipe against
// workgroups of 64 Morton-adjacent vertices sharing one direction: 0.72x the CPU time
// (docs/performance.md).

struct VisibilityParams {
    vertex_offset: u32,
    vertex_count: u32,
    sample_offset: u32,
    sample_count: u32,
    words_per_vertex: u32,
    max_steps: u32,
    // 1: trace rays; 0: every sample above the horizon is visible (unshadowed transfer).
    shadowed: u32,
    // 1: find the closest hit of each ray and write it to `hits` (interreflection).
    record_hits: u32,
    // The grid of the node boxes: world = grid_origin + q * grid_step.
    grid_origin: vec3<f32>,
    grid_step: f32,
    // FRAMES_*: world directions, each vertex's tangent frame (cosine-weighted sampling), or
    // that frame turned by the vertex's own angle.
    frames: u32,
    // Vertex v turns by receiver_turn(turn_seed, turn_first + v).
    turn_seed: u32,
    turn_first: u32,
    pad0: u32,
}

@group(0) @binding(0) var<uniform> params: VisibilityParams;
@group(0) @binding(1) var<storage, read> nodes: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> origins: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> directions: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> visible_bits: array<atomic<u32>>;
// [0]: rays whose traversal ran out of steps (must stay 0).
@group(0) @binding(7) var<storage, read_write> exhausted_rays: array<atomic<u32>>;
// [local_vertex * sample_count + local_sample]; written only when record_hits is 1: here for
// the listed samples, by the horizon pass (NO_HIT) for the others.
@group(0) @binding(8) var<storage, read_write> hits: array<Hit>;
// [local_vertex * sample_count + slot]: the vertex's samples above its horizon (chunk-local
// indices, in the order of the set's fan runs), then NO_SAMPLE.
@group(0) @binding(9) var<storage, read> sample_lists: array<u32>;


@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    read_unseen_zero();
    let slot = id.x;
    let local_vertex = id.y;
    if (local_vertex >= params.vertex_count || slot >= params.sample_count) {
        return;
    }
    // Only the samples above the vertex's horizon are listed (by the horizon pass, with the
    // CPU's test), packed to the front of the vertex's row: whole SIMD groups trace rays.
    let local_sample = sample_lists[local_vertex * params.sample_count + slot];
    if (local_sample == NO_SAMPLE) {
        return;
    }
    let vertex = params.vertex_offset + local_vertex;
    let normal = normals[vertex].xyz;
    var direction = directions[params.sample_offset + local_sample].xyz;
    if (params.frames != 0u) {
        let frame = receiver_frame(normal, params.frames, params.turn_seed, params.turn_first + vertex);
        direction = to_world(frame, direction);
    }
    var visible = true;
    if (params.shadowed != 0u) {
        let closest = params.record_hits != 0u;
        let grid = BoxGrid(params.grid_origin, params.grid_step);
        let found = trace(make_ray(origins[vertex].xyz, direction), RAY_T_MAX, params.max_steps, !closest, grid);
        if (found.exhausted) {
            atomicAdd(&exhausted_rays[0], 1u);
            return;
        }
        visible = !found.hit;
        if (closest) {
            hits[local_vertex * params.sample_count + local_sample] = Hit(found.triangle, found.u, found.v);
        }
    }
    if (visible) {
        let word = local_vertex * params.words_per_vertex + local_sample / 32u;
        atomicOr(&visible_bits[word], 1u << (local_sample % 32u));
    }
}
