// Shared include: what the horizon and visibility passes know of a vertex's samples: the
// record of a ray's closest hit, the tangent frame a cosine-weighted set is turned into, and the
// horizon test. Rounded as the CPU rounds (`rounded`, `divide_rounded`: wgsl/bvh.wgsl), so both
// passes list and cast exactly the CPU's rays.

// 12 bytes; Rust twin: bake::bounce::Hit.
struct Hit {
    triangle: u32,
    u: f32,
    v: f32,
}

// Rust twin: sampling::tangent_frame (Duff et al. 2017), step for step.
fn tangent_frame(n: vec3<f32>) -> mat3x3<f32> {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = divide_rounded(-1.0, sign + n.z);
    let b = n.x * n.y * a;
    let tangent = vec3<f32>(1.0 + rounded(sign * n.x * n.x * a), sign * b, -sign * n.x);
    let bitangent = vec3<f32>(b, sign + rounded(n.y * n.y * a), -n.y);
    return mat3x3<f32>(tangent, bitangent, n);
}

// Rust twin: sampling::VertexDirections::world.
fn to_world(frame: mat3x3<f32>, d: vec3<f32>) -> vec3<f32> {
    return rounded3(frame[0] * d.x) + rounded3(frame[1] * d.y) + rounded3(frame[2] * d.z);
}

// Rust twin: bake::cpu::trace_visibility (its horizon test, `normal.dot(direction) > 0`, with
// glam's dot: x, then y, then z).
fn above_horizon(n: vec3<f32>, d: vec3<f32>) -> bool {
    return rounded(n.x * d.x) + rounded(n.y * d.y) + rounded(n.z * d.z) > 0.0;
}
