// Shared include: the flattened BVH, rays, the watertight triangle test and any-hit traversal.
// Mirrors src/ray.rs and src/bvh/ function for function. The constants (STACK_SIZE,
// SLAB_WIDENING, MIN_DIRECTION_COMPONENT, NO_HIT, LEAF_FLAG, ...) are generated from their Rust
// definitions (src/shaders.rs) and prepended to every kernel. Traversal reads nothing of the
// including kernel but the `nodes` and `triangles` arrays; everything else is an argument.

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

// The arithmetic below must round as the CPU's does, step for step, or the GPU's visibility
// differs from the CPU reference on the rays that graze an edge, and the watertight test's
// shared edges (whose two edge functions are exact negatives only when every product is
// rounded) let rays through. Vulkan allows two liberties that an NVIDIA H200 takes and llvmpipe
// does not: fusing `a * b + c` into one fma, rounded once (SPIR-V's NoContraction would forbid
// it, but naga does not emit it), and a division up to 2.5 ulps off. On the H200, 470 of the
// built-in scene's 3.3 M rays differed before these two functions (docs/performance.md).

// `p` as computed, rounded: its bits pass through an OR with a word the compiler cannot know
// is zero (the pad word of the first triangle's last vec4, `pad2` of bvh::BvhTriangle, 0 in
// every tree), so a product wrapped in it cannot be fused into the sum it feeds.
fn rounded(p: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(p) | unseen_zero);
}

fn rounded3(p: vec3<f32>) -> vec3<f32> {
    return bitcast<vec3<f32>>(bitcast<vec3<u32>>(p) | vec3<u32>(unseen_zero));
}

// The zero `rounded` ORs with, read from memory once per invocation rather than once per
// product: every kernel that rounds calls `read_unseen_zero()` first (a test checks), since a
// private variable never written is a zero the compiler sees.
var<private> unseen_zero: u32;

fn read_unseen_zero() {
    unseen_zero = triangles[2u].w;
}

// Set by the host (bake::gpu::Division) where the adapter's own `/` was seen to round as IEEE
// 754 does, as llvmpipe's does: `divide_rounded` is then `/`. Forced on lavapipe, the emulation
// took 1.4x the time of a bake before it (docs/performance.md).
override DIVISION_IS_IEEE: bool = false;

// One step of the significands' long division: 8 more quotient bits. `q_r` is (quotient so
// far, remainder), the remainder below `d` < 2^24, so that it shifted by 8 still fits 32 bits.
// The digit is estimated by a float division (off by at most one: the exact digit is below 256
// and the estimate within 2^-14 of it) and corrected with the exact integer remainder: x86 has
// no vector integer division, so llvmpipe would divide lane by lane.
fn quotient_step(q_r: vec2<u32>, d: u32) -> vec2<u32> {
    let shifted = q_r.y << 8u;
    // Through i32: both values are below 2^24, and x86 converts signed integers in one
    // instruction where an unsigned conversion takes a sequence.
    var digit = u32(i32(f32(i32(q_r.y)) * 256.0 / f32(i32(d))));
    var product = digit * d;
    let over = product > shifted;
    digit = select(digit, digit - 1u, over);
    product = select(product, product - d, over);
    var remainder = shifted - product;
    let under = remainder >= d;
    digit = select(digit, digit + 1u, under);
    remainder = select(remainder, remainder - d, under);
    return vec2<u32>((q_r.x << 8u) | digit, remainder);
}

// `a / b` rounded to nearest, ties to even, as IEEE 754 (and the CPU) divides: the significands
// divided as integers to 24 bits past the leading one, plus a rounding bit and whether anything
// remains. Zero, subnormal, infinite or NaN operands, and quotients outside the normal range,
// take the hardware's `/`: the callers divide by direction components no smaller than
// MIN_DIRECTION_COMPONENT and by edge-function sums, and their quotients of zero are exact
// either way. Written without loops: llvmpipe's loop cap counts every iteration.
fn divide_rounded(a: f32, b: f32) -> f32 {
    if (DIVISION_IS_IEEE) {
        return a / b;
    }
    // Branch-free (both answers computed, one selected): llvmpipe runs every branch anyway,
    // and a branch costs it a mask per lane.
    let bits_a = bitcast<u32>(a);
    let bits_b = bitcast<u32>(b);
    let exponent_a = (bits_a >> 23u) & 0xffu;
    let exponent_b = (bits_b >> 23u) & 0xffu;
    let ordinary = exponent_a != 0u && exponent_a != 255u && exponent_b != 0u && exponent_b != 255u;
    let n_unshifted = (bits_a & 0x7fffffu) | 0x800000u;
    let d = (bits_b & 0x7fffffu) | 0x800000u;
    let below = n_unshifted < d;
    let n = select(n_unshifted, n_unshifted << 1u, below);
    var exponent = i32(exponent_a) - i32(exponent_b) + 127 - select(0, 1, below);
    // n / d is in [1, 2): the leading quotient bit is 1, the remainder n - d.
    let q_r = quotient_step(quotient_step(quotient_step(vec2<u32>(1u, n - d), d), d), d);
    // q_r.x: the leading one, 23 significand bits and the rounding bit.
    let truncated = q_r.x >> 1u;
    let round_up = (q_r.x & 1u) == 1u && (q_r.y != 0u || (truncated & 1u) == 1u);
    var significand = truncated + select(0u, 1u, round_up);
    let carried = significand == 0x1000000u;
    significand = select(significand, 0x800000u, carried);
    exponent += select(0, 1, carried);
    let sign = (bits_a ^ bits_b) & 0x80000000u;
    let rounded_quotient = bitcast<f32>(sign | (u32(max(exponent, 0)) << 23u) | (significand & 0x7fffffu));
    return select(a / b, rounded_quotient, ordinary && exponent > 0 && exponent < 255);
}

fn safe_component(d: f32) -> f32 {
    return select(d, select(MIN_DIRECTION_COMPONENT, -MIN_DIRECTION_COMPONENT, d < 0.0), abs(d) < MIN_DIRECTION_COMPONENT);
}

fn make_ray(origin: vec3<f32>, direction: vec3<f32>) -> Ray {
    var ray: Ray;
    ray.origin = origin;
    ray.direction = direction;
    ray.inv_direction = vec3<f32>(divide_rounded(1.0, safe_component(direction.x)), divide_rounded(1.0, safe_component(direction.y)), divide_rounded(1.0, safe_component(direction.z)));
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
    // 1 / dz is inv_direction[kz] (|dz| >= 1/sqrt(3), never replaced by safe_component).
    ray.shear = vec3<f32>(divide_rounded(direction[kx], dz), divide_rounded(direction[ky], dz), ray.inv_direction[kz]);
    return ray;
}

// A hit on a triangle: distance (negative on a miss), and the edge functions of v1 and v2 and
// their sum, whose quotients are the barycentrics of v1 and v2 (divided by the traversal, once
// for its closest hit rather than once for every candidate).
struct TriangleHit {
    t: f32,
    v: f32,
    w: f32,
    det: f32,
}

// Watertight ray-triangle test (Woop, Benthin, Wald 2013); Rust twin: ray::intersect_triangle.
// `exact_t`: t rounded as the CPU rounds it, for a traversal that compares distances. Without
// it the hardware's division serves: an any-hit traversal on (0, RAY_T_MAX) reads only t's
// sign and finiteness, which any division keeps (and llvmpipe runs both sides of a branch, so
// a division saved here is saved on every triangle test).
fn intersect_triangle(ray: Ray, v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, t_min: f32, t_max: f32, exact_t: bool) -> TriangleHit {
    let miss = TriangleHit(-1.0, 0.0, 0.0, 1.0);
    let kx = ray.axis_x;
    let ky = ray.axis_y;
    let kz = ray.axis_z;
    let a = v0 - ray.origin;
    let b = v1 - ray.origin;
    let c = v2 - ray.origin;
    let ax = a[kx] - rounded(ray.shear.x * a[kz]);
    let ay = a[ky] - rounded(ray.shear.y * a[kz]);
    let bx = b[kx] - rounded(ray.shear.x * b[kz]);
    let by = b[ky] - rounded(ray.shear.y * b[kz]);
    let cx = c[kx] - rounded(ray.shear.x * c[kz]);
    let cy = c[ky] - rounded(ray.shear.y * c[kz]);
    let u = rounded(cx * by) - rounded(cy * bx);
    let v = rounded(ax * cy) - rounded(ay * cx);
    let w = rounded(bx * ay) - rounded(by * ax);
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
    let distance_times_det = rounded(u * az) + rounded(v * bz) + rounded(w * cz);
    var t: f32;
    if (exact_t) {
        t = divide_rounded(distance_times_det, det);
    } else {
        t = distance_times_det / det;
    }
    if (!(t > t_min && t < t_max)) {
        return miss;
    }
    return TriangleHit(t, v, w, det);
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

// The BVH as the visibility kernel reads it (built from bvh::Bvh by bvh::gpu::GpuBvh), both
// arrays as vec4<u32> so that every read is a 16-byte load.
// `nodes`: 64 bytes (four vec4) per node of the four-wide tree, Rust twin bvh::gpu::GpuNode:
//   [i].xyz  child i's box, [i].w  child i's reference.
// A box is (min.x, min.y), (min.z, max.x), (max.y, max.z) as pairs of u16 (low half first) on a
// grid of 2^16 steps per axis, rounded outwards, so it holds at least what the exact box holds.
// A reference is an interior child's index in `nodes`, LEAF_FLAG | the index of a leaf's first
// triangle, or EMPTY_CHILD for an unused slot.
// `triangles`: 48 bytes (three vec4) per triangle in leaf order, Rust twin bvh::BvhTriangle:
//   [0] = (v0, source_index), [1] = (v1, flags), [2] = (v2, 0), vertices as f32 bits;
//   flags is LAST_IN_LEAF on the last triangle of a leaf.

// The grid of the node boxes: world = origin + q * step (Rust: bvh::gpu::GpuBvh's grid_origin
// and grid_step, passed by the kernel that traces).
struct BoxGrid {
    origin: vec3<f32>,
    step: f32,
}

// A grid coordinate back to world space: exact, since the grid step is a power of two and
// the grid is small enough that origin + q * step needs no rounding (bvh::gpu::GpuBvh::new).
fn grid_point(q: vec3<f32>, grid: BoxGrid) -> vec3<f32> {
    return grid.origin + q * grid.step;
}

fn box_min(q: vec3<u32>, grid: BoxGrid) -> vec3<f32> {
    return grid_point(vec3<f32>(f32(q.x & 0xffffu), f32(q.x >> 16u), f32(q.y & 0xffffu)), grid);
}

fn box_max(q: vec3<u32>, grid: BoxGrid) -> vec3<f32> {
    return grid_point(vec3<f32>(f32(q.y >> 16u), f32(q.z & 0xffffu), f32(q.z >> 16u)), grid);
}

// Closest-hit (any_hit false) or any-hit (any_hit true, on (0, t_max_in) with t_max_in
// RAY_T_MAX: see intersect_triangle's `exact_t`) traversal of `nodes`/`triangles`, whose boxes
// lie on `grid` (declared by the kernel that includes this file). Rust twin: Bvh::traverse,
// whose answers it gives on the binary tree this one was collapsed from (with exact instead of
// grid-rounded boxes): every triangle the CPU tests is tested here, and of triangles at one
// distance the closest-hit query keeps the first in the scene (`replaces`), as every CPU
// traversal does, whatever order the four-wide steps make it meet them in.
// Every loop iteration counts against `max_steps`: llvmpipe silently ends any invocation's loops
// after 65,535 iterations in total, so a traversal that could come near that reports itself
// as exhausted instead of returning a wrong answer.
//
// Written for llvmpipe, where an invocation is one lane of an 8-wide SIMD group: both sides
// of every branch run (masked) in every loop iteration, and a storage-buffer load is a loop
// over the lanes with a bounds check per lane and per component. So an interior step reads
// one 64-byte node (four vec4 loads) that holds four children's boxes and references, orders
// them without branches, and a leaf's triangles are read as three vec4 each.
fn trace(ray: Ray, t_max_in: f32, max_steps: u32, any_hit: bool, grid: BoxGrid) -> Trace {
    var result = Trace(false, false, NO_HIT, 0.0, 0.0);
    // The closest hit so far, its barycentrics divided out when the traversal ends; its
    // triangle's index in the scene, which settles ties (`replaces`), is `result.triangle`.
    var closest = TriangleHit(t_max_in, 0.0, 0.0, 1.0);
    // Where the ray ends for the triangle tests, just past the closest hit once there is one,
    // and for the box tests, a little farther (`reach`).
    var t_max = t_max_in;
    var box_t_max = t_max_in;
    var stack: array<u32, WIDE_STACK_SIZE>;
    var stack_len = 0u;
    // The root's children are tested by the first step.
    var node = 0u;
    var steps = 0u;
    loop {
        steps += 1u;
        if (steps > max_steps) {
            result.exhausted = true;
            return result;
        }
        var descend = false;
        if ((node & LEAF_FLAG) != 0u) {
            // A leaf's triangles are consecutive; the last one has LAST_IN_LEAF in `flags`.
            var i = node & ~LEAF_FLAG;
            loop {
                steps += 1u;
                if (steps > max_steps) {
                    result.exhausted = true;
                    return result;
                }
                let w0 = triangles[3u * i];
                let w1 = triangles[3u * i + 1u];
                let w2 = triangles[3u * i + 2u];
                let hit = intersect_triangle(ray, bitcast<vec3<f32>>(w0.xyz), bitcast<vec3<f32>>(w1.xyz), bitcast<vec3<f32>>(w2.xyz), 0.0, t_max, !any_hit);
                if (hit.t >= 0.0 && (any_hit || replaces(hit.t, w0.w, closest.t, result.triangle))) {
                    result.hit = true;
                    result.triangle = w0.w;
                    closest = hit;
                    if (any_hit) {
                        return result;
                    }
                    t_max = past(hit.t);
                    box_t_max = reach(hit.t);
                }
                if (w1.w != 0u) {
                    break;
                }
                i += 1u;
            }
        } else {
            // The children met, nearest first; a missed or empty child sorts last.
            let c0 = nodes[4u * node];
            let c1 = nodes[4u * node + 1u];
            let c2 = nodes[4u * node + 2u];
            let c3 = nodes[4u * node + 3u];
            var near = vec4<u32>(child_key(c0, ray, grid, box_t_max), child_key(c1, ray, grid, box_t_max), child_key(c2, ray, grid, box_t_max), child_key(c3, ray, grid, box_t_max));
            var child = vec4<u32>(c0.w, c1.w, c2.w, c3.w);
            // A sorting network of five compare-exchanges: (0 1) (2 3) (0 2) (1 3) (1 2).
            let swap_01 = near.y < near.x;
            let swap_23 = near.w < near.z;
            near = vec4<u32>(select(near.xy, near.yx, swap_01), select(near.zw, near.wz, swap_23));
            child = vec4<u32>(select(child.xy, child.yx, swap_01), select(child.zw, child.wz, swap_23));
            let swap_02 = near.z < near.x;
            let swap_13 = near.w < near.y;
            near = select(near, near.zwxy, vec4<bool>(swap_02, swap_13, swap_02, swap_13));
            child = select(child, child.zwxy, vec4<bool>(swap_02, swap_13, swap_02, swap_13));
            let swap_12 = near.z < near.y;
            near = vec4<u32>(near.x, select(near.yz, near.zy, swap_12), near.w);
            child = vec4<u32>(child.x, select(child.yz, child.zy, swap_12), child.w);
            // The nearest is next; the others wait, the farthest deepest. Each is written
            // before it is known to be kept (a later write overwrites one that is not), so
            // the stack has a slot beyond the deepest it holds.
            let met = near != vec4<u32>(MISSED);
            stack[stack_len] = child.w;
            stack_len += select(0u, 1u, met.w);
            stack[stack_len] = child.z;
            stack_len += select(0u, 1u, met.z);
            stack[stack_len] = child.y;
            stack_len += select(0u, 1u, met.y);
            node = child.x;
            descend = met.x;
        }
        if (!descend) {
            if (stack_len == 0u) {
                if (result.hit) {
                    result.u = divide_rounded(closest.v, closest.det);
                    result.v = divide_rounded(closest.w, closest.det);
                }
                return result;
            }
            stack_len -= 1u;
            node = stack[stack_len];
        }
    }
    return result;
}

// The next f32 after a positive finite t; Rust twin: ray::past.
fn past(t: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(t) + 1u);
}

// The far end of the box tests once a closest hit at t is known; Rust twin: ray::reach.
fn reach(t: f32) -> f32 {
    return t * TIE_REACH;
}

// Whether a hit at t on the triangle at `index` in the scene replaces the closest so far:
// nearer, or as near and first in the scene; Rust twin: ray::replaces.
fn replaces(t: f32, index: u32, best_t: f32, best_index: u32) -> bool {
    return t < best_t || (t == best_t && index < best_index);
}

// Where the ray enters a child's box (`c`: the box, the reference), as the bits of the
// distance, or MISSED where it does not reach the box before `t_max` or the slot is empty.
// The distance is not negative, so its bits order as it does and MISSED sorts after every box
// met. Rust twin: ray::intersect_box.
fn child_key(c: vec4<u32>, ray: Ray, grid: BoxGrid, t_max: f32) -> u32 {
    let t0 = (box_min(c.xyz, grid) - ray.origin) * ray.inv_direction;
    let t1 = (box_max(c.xyz, grid) - ray.origin) * ray.inv_direction;
    let near = box_near(t0, t1);
    return select(MISSED, bitcast<u32>(near), near <= box_far(t0, t1, t_max) && c.w != EMPTY_CHILD);
}

const MISSED: u32 = 0xffffffffu;

fn box_near(t0: vec3<f32>, t1: vec3<f32>) -> f32 {
    let n = min(t0, t1);
    return max(max(max(n.x, n.y), n.z), 0.0);
}

fn box_far(t0: vec3<f32>, t1: vec3<f32>, t_max: f32) -> f32 {
    let f = max(t0, t1);
    return min(min(min(f.x, f.y), f.z) * SLAB_WIDENING, t_max);
}
