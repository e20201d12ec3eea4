// Shared include: the flattened BVH, rays, the watertight triangle test and any-hit traversal.
// Mirrors src/ray.rs and src/bvh.rs function for function. The constants STACK_SIZE,
// WORKGROUP_SIZE, SLAB_WIDENING and MIN_DIRECTION_COMPONENT are generated from their Rust
// definitions (src/shaders.rs) and prepended to every kernel.

// 32 bytes; Rust twin: bvh::BvhNode.
struct BvhNode {
    min: vec3<f32>,
    left_or_first: u32,
    max: vec3<f32>,
    triangle_count: u32,
}

// 48 bytes; Rust twin: bvh::BvhTriangle.
struct BvhTriangle {
    v0: vec3<f32>,
    source_index: u32,
    v1: vec3<f32>,
    pad1: u32,
    v2: vec3<f32>,
    pad2: u32,
}

struct Ray {
    origin: vec3<f32>,
    direction: vec3<f32>,
    inv_direction: vec3<f32>,
    // Permuted axes of the watertight test: z is the dominant direction component.
    axis_x: u32,
    axis_y: u32,
    axis_z: u32,
    shear: vec3<f32>,
}

fn safe_component(d: f32) -> f32 {
    return select(d, select(MIN_DIRECTION_COMPONENT, -MIN_DIRECTION_COMPONENT, d < 0.0), abs(d) < MIN_DIRECTION_COMPONENT);
}

fn make_ray(origin: vec3<f32>, direction: vec3<f32>) -> Ray {
    var ray: Ray;
    ray.origin = origin;
    ray.direction = direction;
    ray.inv_direction = vec3<f32>(1.0) / vec3<f32>(safe_component(direction.x), safe_component(direction.y), safe_component(direction.z));
    let a = abs(direction);
    var kz = 2u;
    if (a.x > a.y) {
        if (a.x > a.z) { kz = 0u; }
    } else if (a.y > a.z) {
        kz = 1u;
    }
    var kx = (kz + 1u) % 3u;
    var ky = (kx + 1u) % 3u;
    if (direction[kz] < 0.0) {
        let t = kx;
        kx = ky;
        ky = t;
    }
    ray.axis_x = kx;
    ray.axis_y = ky;
    ray.axis_z = kz;
    let dz = direction[kz];
    ray.shear = vec3<f32>(direction[kx] / dz, direction[ky] / dz, 1.0 / dz);
    return ray;
}

// Slab test: true if the ray meets the box within [t_min, t_max].
fn hits_box(ray: Ray, box_min: vec3<f32>, box_max: vec3<f32>, t_min: f32, t_max: f32) -> bool {
    let t0 = (box_min - ray.origin) * ray.inv_direction;
    let t1 = (box_max - ray.origin) * ray.inv_direction;
    let near_v = min(t0, t1);
    let far_v = max(t0, t1);
    let near = max(max(max(near_v.x, near_v.y), near_v.z), t_min);
    let far = min(min(min(far_v.x, far_v.y), far_v.z) * SLAB_WIDENING, t_max);
    return near <= far;
}

// A hit on a triangle: distance (negative on a miss) and barycentrics of v1 and v2.
struct TriangleHit {
    t: f32,
    u: f32,
    v: f32,
}

// Watertight ray-triangle test (Woop, Benthin, Wald 2013); Rust twin: ray::intersect_triangle.
fn intersect_triangle(ray: Ray, v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, t_min: f32, t_max: f32) -> TriangleHit {
    let miss = TriangleHit(-1.0, 0.0, 0.0);
    let kx = ray.axis_x;
    let ky = ray.axis_y;
    let kz = ray.axis_z;
    let a = v0 - ray.origin;
    let b = v1 - ray.origin;
    let c = v2 - ray.origin;
    let ax = a[kx] - ray.shear.x * a[kz];
    let ay = a[ky] - ray.shear.y * a[kz];
    let bx = b[kx] - ray.shear.x * b[kz];
    let by = b[ky] - ray.shear.y * b[kz];
    let cx = c[kx] - ray.shear.x * c[kz];
    let cy = c[ky] - ray.shear.y * c[kz];
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) {
        return miss;
    }
    let det = u + v + w;
    if (det == 0.0) {
        return miss;
    }
    let az = ray.shear.z * a[kz];
    let bz = ray.shear.z * b[kz];
    let cz = ray.shear.z * c[kz];
    let t = (u * az + v * bz + w * cz) / det;
    if (!(t > t_min && t < t_max)) {
        return miss;
    }
    return TriangleHit(t, v / det, w / det);
}

// Result of a traversal: whether and where the ray hit, and whether the step budget ran out.
struct Trace {
    hit: bool,
    exhausted: bool,
    // Scene index of the closest triangle hit so far and the barycentrics of its v1 and v2.
    triangle: u32,
    u: f32,
    v: f32,
}

// Closest-hit (any_hit false) or any-hit (any_hit true) traversal of `nodes`/`triangles`
// (declared by the kernel that includes this file); Rust twin: Bvh::traverse.
// Every loop iteration counts against `max_steps`: llvmpipe silently ends any invocation's loops
// after 65,535 iterations in total, so a traversal that could come near that reports itself
// as exhausted instead of returning a wrong answer.
fn trace(ray: Ray, t_max_in: f32, max_steps: u32, any_hit: bool) -> Trace {
    var result = Trace(false, false, NO_HIT, 0.0, 0.0);
    var t_max = t_max_in;
    if (!hits_box(ray, nodes[0].min, nodes[0].max, 0.0, t_max)) {
        return result;
    }
    var stack: array<u32, STACK_SIZE>;
    var stack_len = 0u;
    var node_index = 0u;
    var steps = 0u;
    loop {
        steps += 1u;
        if (steps > max_steps) {
            result.exhausted = true;
            return result;
        }
        let node = nodes[node_index];
        var descend = false;
        if (node.triangle_count > 0u) {
            steps += node.triangle_count;
            for (var i = node.left_or_first; i < node.left_or_first + node.triangle_count; i += 1u) {
                let tri = triangles[i];
                let hit = intersect_triangle(ray, tri.v0, tri.v1, tri.v2, 0.0, t_max);
                if (hit.t >= 0.0) {
                    result.hit = true;
                    result.triangle = tri.source_index;
                    result.u = hit.u;
                    result.v = hit.v;
                    if (any_hit) {
                        return result;
                    }
                    t_max = hit.t;
                }
            }
        } else {
            let left = nodes[node.left_or_first];
            let right = nodes[node.left_or_first + 1u];
            let t0l = (left.min - ray.origin) * ray.inv_direction;
            let t1l = (left.max - ray.origin) * ray.inv_direction;
            let t0r = (right.min - ray.origin) * ray.inv_direction;
            let t1r = (right.max - ray.origin) * ray.inv_direction;
            let near_l = box_near(t0l, t1l);
            let near_r = box_near(t0r, t1r);
            let hit_l = near_l <= box_far(t0l, t1l, t_max);
            let hit_r = near_r <= box_far(t0r, t1r, t_max);
            if (hit_l && hit_r) {
                // Visit the nearer child first, keep the other.
                let near_first = near_l <= near_r;
                stack[stack_len] = select(node.left_or_first, node.left_or_first + 1u, near_first);
                stack_len += 1u;
                node_index = select(node.left_or_first + 1u, node.left_or_first, near_first);
                descend = true;
            } else if (hit_l) {
                node_index = node.left_or_first;
                descend = true;
            } else if (hit_r) {
                node_index = node.left_or_first + 1u;
                descend = true;
            }
        }
        if (!descend) {
            if (stack_len == 0u) {
                return result;
            }
            stack_len -= 1u;
            node_index = stack[stack_len];
        }
    }
    return result;
}

fn box_near(t0: vec3<f32>, t1: vec3<f32>) -> f32 {
    let n = min(t0, t1);
    return max(max(max(n.x, n.y), n.z), 0.0);
}

fn box_far(t0: vec3<f32>, t1: vec3<f32>, t_max: f32) -> f32 {
    let f = max(t0, t1);
    return min(min(min(f.x, f.y), f.z) * SLAB_WIDENING, t_max);
}
