// CPCA assignment: one invocation per vertex of a chunk finds, among clusters
// [cluster_begin, cluster_end), the one whose affine subspace is nearest, residual
// |x - mean|^2 - sum_j (b_j . (x - mean))^2 (the directions b_j orthonormal), and keeps it if it
// beats the best of earlier passes (ties: the lower index, as passes run in cluster order).
// Rust twin: compress::cluster::Model::residual and best_cluster (in f64 there, f32 here).
// The host sizes a pass so that one invocation's loops stay far below llvmpipe's iteration cap
// (compress::gpu::clusters_per_pass).

struct AssignParams {
    vertex_count: u32,
    dimension: u32,
    components: u32,
    cluster_begin: u32,
    cluster_end: u32,
    accumulate: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: AssignParams;
@group(0) @binding(1) var<storage, read> points: array<f32>;
@group(0) @binding(2) var<storage, read> means: array<f32>;
@group(0) @binding(3) var<storage, read> bases: array<f32>;
@group(0) @binding(4) var<storage, read_write> best_cluster: array<u32>;
@group(0) @binding(5) var<storage, read_write> best_residual: array<f32>;

const NO_RESIDUAL: f32 = 3.40282347e38;

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let v = id.x;
    if (v >= params.vertex_count) {
        return;
    }
    let n = params.dimension;
    let m = params.components;
    let x = v * n;
    var best = params.cluster_begin;
    var best_r = NO_RESIDUAL;
    if (params.accumulate != 0u) {
        best = best_cluster[v];
        best_r = best_residual[v];
    }
    for (var c = params.cluster_begin; c < params.cluster_end; c += 1u) {
        let mean = c * n;
        var distance = 0.0;
        for (var d = 0u; d < n; d += 1u) {
            let e = points[x + d] - means[mean + d];
            distance += e * e;
        }
        var captured = 0.0;
        for (var j = 0u; j < m; j += 1u) {
            let b = (c * m + j) * n;
            var w = 0.0;
            for (var d = 0u; d < n; d += 1u) {
                w += bases[b + d] * (points[x + d] - means[mean + d]);
            }
            captured += w * w;
        }
        let r = max(distance - captured, 0.0);
        if (r < best_r) {
            best_r = r;
            best = c;
        }
    }
    best_cluster[v] = best;
    best_residual[v] = best_r;
}
