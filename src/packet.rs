//! Ray packets: up to [`LANES`] rays that share one direction and start at different origins,
//! traced through the [`Bvh`] together. The CPU bake casts the same sample direction from 16
//! Morton-adjacent vertices at a time; their rays are parallel and close, so they visit nearly
//! the same nodes, and everything that depends only on the direction is worked out once:
//!
//! - the near and far slab planes of every box (picked by the sign of each direction component);
//! - the Woop–Benthin–Wald permutation and shear constants, and each triangle vertex's
//!   coordinates permuted into the shear frame, once per triangle and packet.
//!
//! Per lane remain the slab distances, the translation of the vertices to the lane's origin and
//! the shear, the edge functions and the hit distance: `[f32; LANES]` arrays walked by plain loops, which
//! LLVM turns into SIMD (one AVX-512 register, two AVX2 or four NEON/SSE registers per array).
//! The one step LLVM does not vectorize well from plain loops, turning 16 lane comparisons into a
//! 16-bit mask, is a per-instruction-set primitive ([`Isa`]). [`occluded`] picks, at run time,
//! a copy of the traversal compiled for the widest vector unit of the machine (`mod dispatch`).
//!
//! Answers equal [`Bvh::occluded`] lane for lane, bit for bit: every lane does the single ray's
//! arithmetic in the single ray's order. (Shearing each vertex once per packet, relative to an
//! anchor point, and subtracting a sheared origin per lane would save a third of the triangle
//! test's lane work and stays watertight, but it moves the rounding: on the built-in scene's
//! ground plane 0.33% of the rays, grazing their own plane, came out blocked.)

use glam::Vec3;

use crate::bvh::{Bvh, BvhNode, BvhTriangle, STACK_SIZE};
use crate::ray::{Ray, SLAB_WIDENING};

/// Rays per packet: one AVX-512 register of f32.
pub const LANES: usize = 16;

/// One f32 per lane.
pub type Lanes = [f32; LANES];

/// One bit per lane, bit i for lane i.
pub type LaneMask = u32;

/// Every lane of a full packet.
pub const ALL_LANES: LaneMask = (1 << LANES) - 1;

/// Mask of the lanes for which `pred` holds, lane by lane: for code outside the hot loop (LLVM
/// compiles it to scalar compares; the traversal uses [`Isa`] instead).
#[inline(always)]
pub fn lane_mask(pred: impl Fn(usize) -> bool) -> LaneMask {
    let mut mask = 0;
    for lane in 0..LANES {
        mask |= (pred(lane) as LaneMask) << lane;
    }
    mask
}

/// The origins of a packet, which stay the same for every direction cast from them.
#[derive(Clone, Debug)]
#[repr(C, align(64))]
pub struct PacketOrigins {
    /// Origins by axis: `origin[axis][lane]`, as given (the slab test uses them as they are).
    pub origin: [Lanes; 3],
    /// Lanes that carry an origin.
    pub filled: LaneMask,
}

impl PacketOrigins {
    /// Packs up to [`LANES`] origins; lanes beyond `origins.len()` are empty.
    pub fn new(origins: &[Vec3]) -> Self {
        assert!(
            origins.len() <= LANES,
            "a packet holds at most {LANES} rays"
        );
        // Empty lanes repeat the first origin so that they compute harmless finite numbers.
        let first = origins.first().copied().unwrap_or(Vec3::ZERO);
        let lane_origin = |lane: usize| origins.get(lane).copied().unwrap_or(first);
        let origin = [0, 1, 2].map(|axis| std::array::from_fn(|lane| lane_origin(lane)[axis]));
        PacketOrigins {
            origin,
            filled: ALL_LANES >> (LANES - origins.len()),
        }
    }
}

/// A packet of rays along one direction: the per-direction constants of the box and triangle
/// tests, and per lane the origin in the triangle test's sheared frame.
#[derive(Clone, Debug)]
#[repr(C, align(64))]
pub struct RayPacket<'a> {
    /// Origins in the triangle test's permuted axes: `[o[kx], o[ky], o[kz]]` per lane.
    permuted_origin: [Lanes; 3],
    origins: &'a PacketOrigins,
    /// The shared ray: direction, reciprocal, permutation and shear (its origin is unused).
    ray: Ray,
    /// Per axis, where in a node's eight words (`min.xyz, left_or_first, max.xyz, count`) the
    /// plane lies through which the rays enter a box (`max` for a negative direction)...
    near_word: [usize; 3],
    /// ...and the plane through which they leave it.
    far_word: [usize; 3],
    /// Lanes that take part; the others never report a hit.
    pub active: LaneMask,
}

impl<'a> RayPacket<'a> {
    /// Rays from every lane of `origins` in `active` along `direction`.
    pub fn new(origins: &'a PacketOrigins, direction: Vec3, active: LaneMask) -> Self {
        let ray = Ray::new(Vec3::ZERO, direction);
        let o = &origins.origin;
        let permuted_origin = [o[ray.axis_x], o[ray.axis_y], o[ray.axis_z]];
        let enters_at_max = [0, 1, 2].map(|axis| ray.inv_direction[axis] < 0.0);
        let plane = |axis: usize, at_max: bool| axis + 4 * at_max as usize;
        RayPacket {
            permuted_origin,
            origins,
            ray,
            near_word: [0, 1, 2].map(|axis| plane(axis, enters_at_max[axis])),
            far_word: [0, 1, 2].map(|axis| plane(axis, !enters_at_max[axis])),
            active: active & origins.filled,
        }
    }

    /// The single ray of one lane, as [`Bvh::occluded`] would trace it.
    pub fn lane_ray(&self, lane: usize) -> Ray {
        let o = &self.origins.origin;
        Ray::new(
            Vec3::new(o[0][lane], o[1][lane], o[2][lane]),
            self.ray.direction,
        )
    }
}

/// Slab test of every lane against one node's box: the lanes that meet it within `[0, t_max]`.
///
/// The same arithmetic as `ray::intersect_box`, lane by lane: `(bound - origin) * inv_dir`.
/// Which of `min`/`max` gives the entry distance follows from the sign of `inv_dir` alone
/// (both products are rounded monotonically), so the per-lane min/max of the single-ray test
/// is not needed and the answers are the same bit for bit.
#[inline(always)]
fn box_lanes<I: Isa>(packet: &RayPacket, node: &BvhNode, t_max: f32) -> LaneMask {
    let inv = packet.ray.inv_direction;
    // Both planes are picked by index, without branches.
    let words: &[f32; 8] = bytemuck::cast_ref(node);
    let near_plane = packet.near_word.map(|i| words[i]);
    let far_plane = packet.far_word.map(|i| words[i]);
    let o = &packet.origins.origin;
    let mut near = [0.0f32; LANES];
    let mut far = [0.0f32; LANES];
    for lane in 0..LANES {
        let nx = (near_plane[0] - o[0][lane]) * inv.x;
        let ny = (near_plane[1] - o[1][lane]) * inv.y;
        let nz = (near_plane[2] - o[2][lane]) * inv.z;
        let fx = (far_plane[0] - o[0][lane]) * inv.x;
        let fy = (far_plane[1] - o[1][lane]) * inv.y;
        let fz = (far_plane[2] - o[2][lane]) * inv.z;
        near[lane] = max(max(nx, ny), max(nz, 0.0));
        far[lane] = min(min(min(fx, fy), fz) * SLAB_WIDENING, t_max);
    }
    I::le_mask(&near, &far)
}

/// `f32::max` without its NaN rules, so that it is one vector instruction (no NaN reaches it:
/// finite coordinates and finite reciprocals give finite or infinite products).
#[inline(always)]
fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// `f32::min` without its NaN rules; see [`max`].
#[inline(always)]
fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// A triangle vertex with its axes permuted into the triangle test's frame, once per packet.
#[inline(always)]
fn permute_vertex(packet: &RayPacket, v: [f32; 3]) -> [f32; 3] {
    let ray = &packet.ray;
    [v[ray.axis_x], v[ray.axis_y], v[ray.axis_z]]
}

/// Watertight triangle test (Woop, Benthin, Wald 2013) of the lanes in `lanes`: those that hit
/// the triangle on `(0, t_max)`, both faces counting, edge functions of zero counting as inside.
/// Each lane computes exactly what `ray::intersect_triangle` computes for its ray.
#[inline(always)]
fn triangle_lanes<I: Isa>(
    packet: &RayPacket,
    tri: &BvhTriangle,
    lanes: LaneMask,
    t_max: f32,
) -> LaneMask {
    // (Three calls rather than `array::map`, whose closure LLVM leaves out of line.)
    let a = permute_vertex(packet, tri.v0);
    let b = permute_vertex(packet, tri.v1);
    let c = permute_vertex(packet, tri.v2);
    let (sx, sy, sz) = (packet.ray.shear.x, packet.ray.shear.y, packet.ray.shear.z);
    let o = &packet.permuted_origin;
    // Translated to the lane's origin, then sheared: the single ray's order of operations.
    let shear = |v: &[f32; 3], lane: usize| {
        let (x, y, z) = (v[0] - o[0][lane], v[1] - o[1][lane], v[2] - o[2][lane]);
        (x - sx * z, y - sy * z, z)
    };
    // Edge functions of all lanes; a lane is outside when they have mixed signs.
    let mut lowest = [0.0f32; LANES];
    let mut highest = [0.0f32; LANES];
    for lane in 0..LANES {
        let (ax, ay, _) = shear(&a, lane);
        let (bx, by, _) = shear(&b, lane);
        let (cx, cy, _) = shear(&c, lane);
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        lowest[lane] = min(min(u, v), w);
        highest[lane] = max(max(u, v), w);
    }
    const ZERO: Lanes = [0.0; LANES];
    let outside = I::lt_mask(&lowest, &ZERO) & I::lt_mask(&ZERO, &highest);
    let mut inside = lanes & !outside;
    // Most triangles are missed by every lane; the few lanes inside finish one by one.
    let mut hits = 0;
    while inside != 0 {
        let lane = inside.trailing_zeros() as usize;
        inside &= inside - 1;
        let (ax, ay, az) = shear(&a, lane);
        let (bx, by, bz) = shear(&b, lane);
        let (cx, cy, cz) = shear(&c, lane);
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let det = u + v + w;
        if det == 0.0 {
            continue;
        }
        let t = (u * (sz * az) + v * (sz * bz) + w * (sz * cz)) / det;
        if t > 0.0 && t < t_max {
            hits |= 1 << lane;
        }
    }
    hits
}

/// Which lanes of `packet` are blocked on `(0, t_max)`: for every active lane the answer of
/// [`Bvh::occluded`] for that lane's ray (up to the edge-grazing rays described at the top).
/// Inactive lanes are never reported.
pub fn occluded(bvh: &Bvh, packet: &RayPacket, t_max: f32) -> LaneMask {
    dispatch::occluded(bvh, packet, t_max)
}

/// The traversal. A stack entry carries the lanes that met the node's box, so every lane
/// visits exactly the nodes its single ray would visit (only the order differs); a node is
/// entered while any of its lanes is still unblocked, and the walk ends once all are blocked.
///
/// Children are taken in stored order. On the dragon about 70% of the rays are unblocked and
/// must visit every box on their way whatever the order; near-first orders (by the children's
/// centres along the direction, by the majority of lanes' entry distances, by the first lane's)
/// each cost more than they saved, 5–15% in CPU time.
#[inline(always)]
fn occluded_lanes<I: Isa>(bvh: &Bvh, packet: &RayPacket, t_max: f32) -> LaneMask {
    let Some(root) = bvh.nodes.first() else {
        return 0;
    };
    // Lanes not yet blocked.
    let mut open = packet.active & box_lanes::<I>(packet, root, t_max);
    if open == 0 {
        return 0;
    }
    let mut blocked = 0;
    let mut stack = [(0u32, 0 as LaneMask); STACK_SIZE];
    let mut stack_len = 0;
    let mut node = root;
    // Lanes that met the current node's box and are not blocked.
    let mut lanes = open;
    loop {
        if node.is_leaf() {
            let first = node.left_or_first as usize;
            for tri in &bvh.triangles[first..first + node.triangle_count as usize] {
                let hits = triangle_lanes::<I>(packet, tri, lanes, t_max);
                if hits != 0 {
                    blocked |= hits;
                    open &= !hits;
                    lanes &= !hits;
                    if open == 0 {
                        return blocked;
                    }
                    if lanes == 0 {
                        break;
                    }
                }
            }
        } else {
            let first = node.left_or_first;
            let left = &bvh.nodes[first as usize];
            let right = &bvh.nodes[first as usize + 1];
            let in_left = lanes & box_lanes::<I>(packet, left, t_max);
            let in_right = lanes & box_lanes::<I>(packet, right, t_max);
            match (in_left != 0, in_right != 0) {
                (true, true) => {
                    stack[stack_len] = (first + 1, in_right);
                    stack_len += 1;
                    node = left;
                    lanes = in_left;
                    continue;
                }
                (true, false) => {
                    node = left;
                    lanes = in_left;
                    continue;
                }
                (false, true) => {
                    node = right;
                    lanes = in_right;
                    continue;
                }
                (false, false) => {}
            }
        }
        // Next stacked node that still has an unblocked lane.
        loop {
            if stack_len == 0 {
                return blocked;
            }
            stack_len -= 1;
            let (index, stacked_lanes) = stack[stack_len];
            lanes = stacked_lanes & open;
            if lanes != 0 {
                node = &bvh.nodes[index as usize];
                break;
            }
        }
    }
}

/// Lane comparisons that give a [`LaneMask`], one implementation per instruction set: the
/// plain loop of [`lane_mask`] is compiled by LLVM into scalar compares and bit shuffles, while
/// every vector unit has a compare-to-mask instruction (sequence).
trait Isa {
    /// Lanes with `a < b`.
    fn lt_mask(a: &Lanes, b: &Lanes) -> LaneMask;
    /// Lanes with `a <= b`.
    fn le_mask(a: &Lanes, b: &Lanes) -> LaneMask;
}

/// Any target: the plain loop.
#[cfg_attr(all(target_arch = "x86_64", not(test)), allow(dead_code))]
struct Portable;

impl Isa for Portable {
    #[inline(always)]
    fn lt_mask(a: &Lanes, b: &Lanes) -> LaneMask {
        lane_mask(|l| a[l] < b[l])
    }
    #[inline(always)]
    fn le_mask(a: &Lanes, b: &Lanes) -> LaneMask {
        lane_mask(|l| a[l] <= b[l])
    }
}

/// Run-time choice of the traversal's machine code. The source is one function; on x86-64 it is
/// compiled three times: for AVX-512 (a packet array is one register), for AVX2 + FMA, and for
/// the SSE2 that every x86-64 has. Other targets get the portable copy (on aarch64 LLVM
/// vectorizes its arithmetic with NEON, the baseline there; only the masks stay scalar). Rust
/// never contracts `a * b + c` into a fused multiply-add on its own, so all copies compute the
/// same bits.
///
/// Plain `#[target_feature]` functions and `std::arch` compares rather than a crate
/// (`multiversion`, `pulp`): three thin wrappers, six compare functions and one cached feature
/// test need no dependency, and the compares are the only place where a crate would help.
mod dispatch {
    use super::*;

    /// The signature every copy shares.
    pub type Traversal = fn(&Bvh, &RayPacket, f32) -> LaneMask;

    #[cfg(target_arch = "x86_64")]
    pub fn occluded(bvh: &Bvh, packet: &RayPacket, t_max: f32) -> LaneMask {
        use std::sync::OnceLock;
        static CHOSEN: OnceLock<Traversal> = OnceLock::new();
        let chosen = CHOSEN.get_or_init(|| {
            if std::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has the features the function is compiled for.
                |b, p, t| unsafe { avx512(b, p, t) }
            } else if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
            {
                // SAFETY: as above.
                |b, p, t| unsafe { avx2(b, p, t) }
            } else {
                occluded_lanes::<x86::Sse2>
            }
        });
        chosen(bvh, packet, t_max)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma,bmi1,bmi2,popcnt")]
    unsafe fn avx512(bvh: &Bvh, packet: &RayPacket, t_max: f32) -> LaneMask {
        occluded_lanes::<x86::Avx512>(bvh, packet, t_max)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,popcnt")]
    unsafe fn avx2(bvh: &Bvh, packet: &RayPacket, t_max: f32) -> LaneMask {
        occluded_lanes::<x86::Avx2>(bvh, packet, t_max)
    }

    #[cfg(not(target_arch = "x86_64"))]
    pub fn occluded(bvh: &Bvh, packet: &RayPacket, t_max: f32) -> LaneMask {
        occluded_lanes::<Portable>(bvh, packet, t_max)
    }

    /// Every copy of the traversal this machine can run, for tests that compare them.
    #[cfg(test)]
    pub fn all_available() -> Vec<(&'static str, Traversal)> {
        let mut copies: Vec<(&'static str, Traversal)> =
            vec![("portable", occluded_lanes::<Portable>)];
        #[cfg(target_arch = "x86_64")]
        {
            copies.push(("sse2", occluded_lanes::<x86::Sse2>));
            if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
                // SAFETY: detected.
                copies.push(("avx2", |b, p, t| unsafe { avx2(b, p, t) }));
            }
            if std::is_x86_feature_detected!("avx512f") {
                // SAFETY: detected.
                copies.push(("avx512", |b, p, t| unsafe { avx512(b, p, t) }));
            }
        }
        copies
    }
}

/// The x86-64 compares. They are `#[inline(always)]` without `#[target_feature]` of their own:
/// they are only ever inlined into the `dispatch` function compiled for their features, where
/// the `std::arch` intrinsics inline too.
#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{Isa, LaneMask, Lanes};
    use std::arch::x86_64::*;

    pub struct Avx512;
    pub struct Avx2;
    pub struct Sse2;

    impl Isa for Avx512 {
        #[inline(always)]
        fn lt_mask(a: &Lanes, b: &Lanes) -> LaneMask {
            // SAFETY: reads 16 f32 from 16-element arrays; only called where AVX-512F is on.
            unsafe {
                _mm512_cmp_ps_mask::<_CMP_LT_OQ>(
                    _mm512_loadu_ps(a.as_ptr()),
                    _mm512_loadu_ps(b.as_ptr()),
                ) as LaneMask
            }
        }
        #[inline(always)]
        fn le_mask(a: &Lanes, b: &Lanes) -> LaneMask {
            // SAFETY: as above.
            unsafe {
                _mm512_cmp_ps_mask::<_CMP_LE_OQ>(
                    _mm512_loadu_ps(a.as_ptr()),
                    _mm512_loadu_ps(b.as_ptr()),
                ) as LaneMask
            }
        }
    }

    /// Two 8-lane compares and their sign masks.
    #[inline(always)]
    fn avx2_mask<const OP: i32>(a: &Lanes, b: &Lanes) -> LaneMask {
        // SAFETY: reads two halves of 8 f32 from 16-element arrays; only called where AVX is on.
        unsafe {
            let half = |i: usize| {
                let m = _mm256_cmp_ps::<OP>(
                    _mm256_loadu_ps(a.as_ptr().add(i)),
                    _mm256_loadu_ps(b.as_ptr().add(i)),
                );
                _mm256_movemask_ps(m) as LaneMask
            };
            half(0) | (half(8) << 8)
        }
    }

    impl Isa for Avx2 {
        #[inline(always)]
        fn lt_mask(a: &Lanes, b: &Lanes) -> LaneMask {
            avx2_mask::<_CMP_LT_OQ>(a, b)
        }
        #[inline(always)]
        fn le_mask(a: &Lanes, b: &Lanes) -> LaneMask {
            avx2_mask::<_CMP_LE_OQ>(a, b)
        }
    }

    /// Four 4-lane compares and their sign masks (SSE2 is part of every x86-64).
    #[inline(always)]
    fn sse2_mask(a: &Lanes, b: &Lanes, cmp: impl Fn(__m128, __m128) -> __m128) -> LaneMask {
        let mut mask = 0;
        for quarter in 0..4 {
            // SAFETY: reads 4 f32 inside 16-element arrays; SSE2 is always present on x86-64.
            let bits = unsafe {
                let (x, y) = (
                    _mm_loadu_ps(a.as_ptr().add(4 * quarter)),
                    _mm_loadu_ps(b.as_ptr().add(4 * quarter)),
                );
                _mm_movemask_ps(cmp(x, y))
            };
            mask |= (bits as LaneMask) << (4 * quarter);
        }
        mask
    }

    impl Isa for Sse2 {
        #[inline(always)]
        fn lt_mask(a: &Lanes, b: &Lanes) -> LaneMask {
            sse2_mask(a, b, |x, y| unsafe { _mm_cmplt_ps(x, y) })
        }
        #[inline(always)]
        fn le_mask(a: &Lanes, b: &Lanes) -> LaneMask {
            sse2_mask(a, b, |x, y| unsafe { _mm_cmple_ps(x, y) })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::BakeInputs;
    use crate::ray::RAY_T_MAX;
    use crate::sampling::Pcg32;
    use crate::scene::{self, builtin, prepare::prepare};

    fn random_direction(rng: &mut Pcg32) -> Vec3 {
        loop {
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            if (0.01..=1.0).contains(&v.length_squared()) {
                return v.normalize();
            }
        }
    }

    /// Every copy of the traversal against single rays, on packets of `width` consecutive
    /// (Morton-adjacent) vertices and random directions, lanes above the horizon active.
    /// Returns (lanes compared, lanes that differ, lanes blocked).
    fn compare_with_single_rays(inputs: &BakeInputs, width: usize, packets: usize) -> [usize; 3] {
        let mut rng = Pcg32::new(7);
        let copies = dispatch::all_available();
        let mut counts = [0; 3];
        for _ in 0..packets {
            let count = inputs.origins.len();
            let start = (rng.next_u32() as usize) % (count - width + 1);
            let origins = PacketOrigins::new(&inputs.origins[start..start + width]);
            let direction = random_direction(&mut rng);
            let normals = &inputs.normals[start..start + width];
            let above = lane_mask(|l| l < width && normals[l].dot(direction) > 0.0);
            let packet = RayPacket::new(&origins, direction, above);
            let expected = lane_mask(|l| {
                above & (1 << l) != 0 && inputs.bvh.occluded(&packet.lane_ray(l), RAY_T_MAX)
            });
            let answers: Vec<LaneMask> = copies
                .iter()
                .map(|(_, f)| f(&inputs.bvh, &packet, RAY_T_MAX))
                .collect();
            for ((name, _), &got) in copies.iter().zip(&answers) {
                assert_eq!(got, answers[0], "{name} differs from the portable copy");
                assert_eq!(got & !above, 0, "{name}: an inactive lane reported a hit");
            }
            counts[0] += above.count_ones() as usize;
            counts[1] += (answers[0] ^ expected).count_ones() as usize;
            counts[2] += expected.count_ones() as usize;
        }
        counts
    }

    #[test]
    fn packets_agree_with_single_rays_on_the_dragon() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/dragon_vrip_res3.ply.gz");
        let (mesh, _) = prepare(scene::load(&path).unwrap()).unwrap();
        let inputs = BakeInputs::new(&mesh, 1, 1, 1);
        let [lanes, differ, blocked] = compare_with_single_rays(&inputs, LANES, 20_000);
        println!(
            "dragon: {lanes} lanes, {blocked} blocked, {differ} differ from single rays \
             ({:.5}% identical)",
            100.0 * (lanes - differ) as f64 / lanes as f64
        );
        assert!(
            blocked > lanes / 10,
            "too few blocked rays to test anything"
        );
        assert_eq!(differ, 0);
    }

    #[test]
    fn packets_agree_with_single_rays_on_the_bunny_and_partial_packets() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bunny.obj");
        let (mesh, _) = prepare(scene::load(&path).unwrap()).unwrap();
        let inputs = BakeInputs::new(&mesh, 1, 1, 1);
        for width in [1, 5, LANES - 1, LANES] {
            let [lanes, differ, blocked] = compare_with_single_rays(&inputs, width, 4_000);
            println!("bunny, {width} lanes: {lanes} lanes, {blocked} blocked, {differ} differ");
            assert!(blocked > 0);
            assert_eq!(differ, 0, "{width}-lane packets");
        }
    }

    #[test]
    fn inactive_and_empty_lanes_never_report() {
        // Inside a closed box every ray is blocked: exactly the active lanes must come back.
        let (mesh, _) =
            prepare(builtin::closed_box(Vec3::splat(-1.0), Vec3::splat(1.0), 4)).unwrap();
        let bvh = crate::bvh::Bvh::build(&mesh.positions, &mesh.triangles);
        let points: Vec<Vec3> = (0..LANES)
            .map(|i| Vec3::new(i as f32 / LANES as f32 - 0.5, 0.1, -0.2))
            .collect();
        let mut rng = Pcg32::new(3);
        for width in [1, 7, LANES] {
            let origins = PacketOrigins::new(&points[..width]);
            for _ in 0..50 {
                let direction = random_direction(&mut rng);
                for active in [0, 0b1010_0110_0101_1001, ALL_LANES] {
                    let packet = RayPacket::new(&origins, direction, active);
                    let expected = active & origins.filled;
                    assert_eq!(packet.active, expected);
                    for (name, f) in dispatch::all_available() {
                        assert_eq!(f(&bvh, &packet, RAY_T_MAX), expected, "{name}");
                    }
                }
            }
        }
    }

    #[test]
    fn empty_scene_blocks_nothing() {
        let bvh = crate::bvh::Bvh::build(&[], &[]);
        let origins = PacketOrigins::new(&[Vec3::ZERO; 3]);
        let packet = RayPacket::new(&origins, Vec3::X, ALL_LANES);
        assert_eq!(occluded(&bvh, &packet, RAY_T_MAX), 0);
    }
}
