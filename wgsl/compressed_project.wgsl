// Projection: one invocation per (cluster, component),
// coordinates[c * m + k] = sum over the cluster's members of bases * (irradiance - means).

@group(0) @binding(1) var<storage, read> members: array<u32>;
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
@group(0) @binding(3) var<storage, read> means: array<f32>;
@group(0) @binding(4) var<storage, read> bases: array<f32>;
@group(0) @binding(5) var<storage, read> irradiance: array<f32>;
@group(0) @binding(6) var<storage, read_write> coordinates: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let m = params.components;
    let index = id.x;
    if (index >= params.clusters * m) {
        return;
    }
    let c = index / m;
    let k = index % m;
    let start = offsets[c];
    let size = offsets[c + 1u] - start;
    let begin = min(params.entry_begin, size);
    let end = min(begin + params.entry_limit, size);
    let row = start * m + k * size;
    var total = 0.0;
    for (var i = begin; i < end; i += 1u) {
        total += bases[row + i] * (irradiance[members[start + i]] - means[start + i]);
    }
    if (params.accumulate != 0u) {
        total += coordinates[index];
    }
    coordinates[index] = total;
}
