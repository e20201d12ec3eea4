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

// Rust twin: sampling::pcg_hash.
fn pcg_hash(input: u32) -> u32 {
    let state = input * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// Rust twin: sampling::receiver_turn, step for step: (cos a, sin a) of a = 2 atan t, with no
// trigonometry, so that both give the same bits.
fn receiver_turn(seed: u32, receiver: u32) -> vec2<f32> {
    let bits = pcg_hash(receiver ^ seed);
    let t = f32(bits >> 8u) * (2.0 / 16777216.0) - 1.0;
    let t2 = rounded(t * t);
    let turn = vec2<f32>(divide_rounded(1.0 - t2, 1.0 + t2), divide_rounded(2.0 * t, 1.0 + t2));
    return select(turn, -turn, (bits & 1u) == 1u);
}

// Rust twin: sampling::turned_frame.
fn turned_frame(frame: mat3x3<f32>, turn: vec2<f32>) -> mat3x3<f32> {
    let tangent = rounded3(frame[0] * turn.x) + rounded3(frame[1] * turn.y);
    let bitangent = rounded3(frame[1] * turn.x) - rounded3(frame[0] * turn.y);
    return mat3x3<f32>(tangent, bitangent, frame[2]);
}

// The frame a receiver casts a tangent set in (`frames` is FRAMES_TANGENT or FRAMES_TURNED).
// Rust twin: bake::inputs::DirectInputs::directions_of.
fn receiver_frame(n: vec3<f32>, frames: u32, turn_seed: u32, receiver: u32) -> mat3x3<f32> {
    let frame = tangent_frame(n);
    if (frames == FRAMES_TURNED) {
        return turned_frame(frame, receiver_turn(turn_seed, receiver));
    }
    return frame;
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
