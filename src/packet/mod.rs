//! Ray packets: [`LANES`] rays traced through the [`Bvh`] together, of two kinds.
//!
//! - [`RayPacket`] (`parallel.rs`): one direction from 16 origins, for direction sets shared by
//!   all vertices.
//! - [`FanPacket`] (`fan.rs`): one origin, 16 directions, for sets that each vertex turns into
//!   its own tangent frame.
//!
//! Per-lane work is done on `[f32; LANES]` arrays walked by plain loops, which LLVM turns into
//! SIMD (one AVX-512 register, two AVX2 or four NEON/SSE registers per array). The one step
//! LLVM does not vectorize well from plain loops, turning 16 lane comparisons into a 16-bit
//! mask, is a per-instruction-set primitive (`Isa`). The traversal is one function for both
//! kinds; [`occluded`] and [`occluded_fan`] run, chosen at run time, a copy of it compiled for
//! the widest vector unit of the machine (`mod dispatch`).
//!
//! Answers equal [`Bvh::occluded`] lane for lane, bit for bit: every lane does the single ray's
//! arithmetic in the single ray's order.

mod fan;
mod parallel;

pub use fan::FanPacket;
pub use parallel::{PacketOrigins, RayPacket};

use crate::bvh::{Bvh, BvhNode, BvhTriangle, STACK_SIZE};

/// Rays per packet: one AVX-512 register of f32.
pub const LANES: usize = 16;

/// One f32 per lane.
pub type Lanes = [f32; LANES];

/// One bit per lane, bit i for lane i.
pub type LaneMask = u32;

/// Every lane of a full packet.
pub const ALL_LANES: LaneMask = (1 << LANES) - 1;

/// Mask of the lanes for which `pred` holds, lane by lane: for code outside the hot loop (LLVM
/// compiles it to scalar compares; the traversal uses `Isa` instead).
#[inline(always)]
pub fn lane_mask(pred: impl Fn(usize) -> bool) -> LaneMask {
    let mut mask = 0;
    for lane in 0..LANES {
        mask |= (pred(lane) as LaneMask) << lane;
    }
    mask
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

/// The lane work of the watertight triangle test (`ray::intersect_triangle`), shared by both
/// packet kinds, which differ only in how a vertex reaches a lane's sheared frame:
/// `shear(v, lane)` is vertex `v` translated to the lane's origin, permuted and sheared, as
/// `(x, y, z)` with `z` not yet scaled; `z_scale(lane)` is the lane's `1 / d_z`. Edge
/// functions are computed for all lanes at once; the few lanes inside (most triangles are
/// missed by every lane) finish one by one. Returns the lanes of `lanes` that hit on
/// `(0, t_max)`.
#[inline(always)]
fn sheared_triangle_lanes<I: Isa>(
    [a, b, c]: [&[f32; 3]; 3],
    shear: impl Fn(&[f32; 3], usize) -> (f32, f32, f32),
    z_scale: impl Fn(usize) -> f32,
    lanes: LaneMask,
    t_max: f32,
) -> LaneMask {
    let edge_functions = |lane: usize| {
        let (ax, ay, _) = shear(a, lane);
        let (bx, by, _) = shear(b, lane);
        let (cx, cy, _) = shear(c, lane);
        (cx * by - cy * bx, ax * cy - ay * cx, bx * ay - by * ax)
    };
    // A lane is outside when its edge functions have mixed signs.
    let mut lowest = [0.0f32; LANES];
    let mut highest = [0.0f32; LANES];
    for lane in 0..LANES {
        let (u, v, w) = edge_functions(lane);
        lowest[lane] = min(min(u, v), w);
        highest[lane] = max(max(u, v), w);
    }
    const ZERO: Lanes = [0.0; LANES];
    let outside = I::lt_mask(&lowest, &ZERO) & I::lt_mask(&ZERO, &highest);
    let mut inside = lanes & !outside;
    let mut hits = 0;
    while inside != 0 {
        let lane = inside.trailing_zeros() as usize;
        inside &= inside - 1;
        let (u, v, w) = edge_functions(lane);
        let det = u + v + w;
        if det == 0.0 {
            continue;
        }
        let s = z_scale(lane);
        let (az, bz, cz) = (shear(a, lane).2, shear(b, lane).2, shear(c, lane).2);
        let t = (u * (s * az) + v * (s * bz) + w * (s * cz)) / det;
        if t > 0.0 && t < t_max {
            hits |= 1 << lane;
        }
    }
    hits
}

/// What the traversal needs of a packet kind: its active lanes, and its box and triangle tests.
trait Packet {
    /// Lanes that take part; the others never report a hit.
    fn active(&self) -> LaneMask;
    /// Lanes that meet the node's box within `[0, t_max]`, as `ray::intersect_box` decides.
    fn box_lanes<I: Isa>(&self, node: &BvhNode, t_max: f32) -> LaneMask;
    /// Lanes among `lanes` that hit the triangle on `(0, t_max)`, as
    /// `ray::intersect_triangle` decides (both faces count, zero edge functions are inside).
    fn triangle_lanes<I: Isa>(&self, tri: &BvhTriangle, lanes: LaneMask, t_max: f32) -> LaneMask;
    /// Whether to enter `right` before `left` when lanes meet both.
    fn right_first(&self, _left: &BvhNode, _right: &BvhNode) -> bool {
        false
    }
}

/// Which lanes of `packet` are blocked on `(0, t_max)`: for every active lane the answer of
/// [`Bvh::occluded`] for that lane's ray. Inactive lanes are never reported.
pub fn occluded(bvh: &Bvh, packet: &RayPacket, t_max: f32) -> LaneMask {
    dispatch::occluded(bvh, packet, t_max)
}

/// [`occluded`] for a packet of rays from one origin.
pub fn occluded_fan(bvh: &Bvh, packet: &FanPacket, t_max: f32) -> LaneMask {
    dispatch::occluded(bvh, packet, t_max)
}

/// The traversal. A stack entry carries the lanes that met the node's box, so every lane
/// visits exactly the nodes its single ray would visit (only the order differs); a node is
/// entered while any of its lanes is still unblocked, and the walk ends once all are blocked.
///
/// Children are taken in the order the packet kind asks for ([`Packet::right_first`]). Parallel
/// packets take them in stored order: on the dragon about 70% of the rays are unblocked and
/// must visit every box on their way whatever the order, and near-first orders (by the
/// children's centres along the direction, by the majority of lanes' entry distances, by the
/// first lane's) each cost more than they saved, 5–15% in CPU time. Fans enter the child whose
/// centre is nearer their origin first: 9% faster on the dragon, where a vertex's blockers are
/// mostly its neighbours, and 7% slower on the open built-in scene (docs/performance.md).
#[inline(always)]
fn occluded_lanes<P: Packet, I: Isa>(bvh: &Bvh, packet: &P, t_max: f32) -> LaneMask {
    let Some(root) = bvh.nodes.first() else {
        return 0;
    };
    // Lanes not yet blocked.
    let mut open = packet.active() & packet.box_lanes::<I>(root, t_max);
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
                let hits = packet.triangle_lanes::<I>(tri, lanes, t_max);
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
            let in_left = lanes & packet.box_lanes::<I>(left, t_max);
            let in_right = lanes & packet.box_lanes::<I>(right, t_max);
            match (in_left != 0, in_right != 0) {
                (true, true) => {
                    if packet.right_first(left, right) {
                        stack[stack_len] = (first, in_left);
                        node = right;
                        lanes = in_right;
                    } else {
                        stack[stack_len] = (first + 1, in_right);
                        node = left;
                        lanes = in_left;
                    }
                    stack_len += 1;
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
#[cfg_attr(
    all(any(target_arch = "x86_64", target_arch = "aarch64"), not(test)),
    allow(dead_code)
)]
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
/// the SSE2 that every x86-64 has. On aarch64 NEON is the baseline, so there is one copy, with
/// NEON compares (checked under qemu-aarch64: the packet tests pass there). Other targets get
/// the portable copy. Rust never contracts `a * b + c` into a fused multiply-add on its own, so
/// all copies compute the same bits.
///
/// Plain `#[target_feature]` functions and `std::arch` compares rather than a crate
/// (`multiversion`, `pulp`): two thin wrappers, eight compare functions and one cached feature
/// test need no dependency, and the compares are the only place where a crate would help.
mod dispatch {
    use super::*;

    /// The signature every copy shares.
    #[cfg(test)]
    pub type Traversal<P> = fn(&Bvh, &P, f32) -> LaneMask;

    /// The widest vector unit of this machine, found once.
    #[cfg(target_arch = "x86_64")]
    #[derive(Clone, Copy)]
    enum Level {
        Avx512,
        Avx2,
        Sse2,
    }

    #[cfg(target_arch = "x86_64")]
    fn level() -> Level {
        use std::sync::OnceLock;
        static LEVEL: OnceLock<Level> = OnceLock::new();
        *LEVEL.get_or_init(|| {
            if std::is_x86_feature_detected!("avx512f") {
                Level::Avx512
            } else if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
            {
                Level::Avx2
            } else {
                Level::Sse2
            }
        })
    }

    #[cfg(target_arch = "x86_64")]
    pub fn occluded<P: Packet>(bvh: &Bvh, packet: &P, t_max: f32) -> LaneMask {
        match level() {
            // SAFETY: the CPU has the features the function is compiled for.
            Level::Avx512 => unsafe { avx512(bvh, packet, t_max) },
            // SAFETY: as above.
            Level::Avx2 => unsafe { avx2(bvh, packet, t_max) },
            Level::Sse2 => occluded_lanes::<P, x86::Sse2>(bvh, packet, t_max),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma,bmi1,bmi2,popcnt")]
    unsafe fn avx512<P: Packet>(bvh: &Bvh, packet: &P, t_max: f32) -> LaneMask {
        occluded_lanes::<P, x86::Avx512>(bvh, packet, t_max)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,popcnt")]
    unsafe fn avx2<P: Packet>(bvh: &Bvh, packet: &P, t_max: f32) -> LaneMask {
        occluded_lanes::<P, x86::Avx2>(bvh, packet, t_max)
    }

    #[cfg(target_arch = "aarch64")]
    pub fn occluded<P: Packet>(bvh: &Bvh, packet: &P, t_max: f32) -> LaneMask {
        occluded_lanes::<P, arm::Neon>(bvh, packet, t_max)
    }

    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    pub fn occluded<P: Packet>(bvh: &Bvh, packet: &P, t_max: f32) -> LaneMask {
        occluded_lanes::<P, Portable>(bvh, packet, t_max)
    }

    /// Every copy of the traversal this machine can run, for tests that compare them.
    #[cfg(test)]
    pub fn all_available<P: Packet>() -> Vec<(&'static str, Traversal<P>)> {
        let mut copies: Vec<(&'static str, Traversal<P>)> =
            vec![("portable", occluded_lanes::<P, Portable>)];
        #[cfg(target_arch = "x86_64")]
        {
            copies.push(("sse2", occluded_lanes::<P, x86::Sse2>));
            if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
                // SAFETY: detected.
                copies.push(("avx2", |b, p, t| unsafe { avx2(b, p, t) }));
            }
            if std::is_x86_feature_detected!("avx512f") {
                // SAFETY: detected.
                copies.push(("avx512", |b, p, t| unsafe { avx512(b, p, t) }));
            }
        }
        #[cfg(target_arch = "aarch64")]
        copies.push(("neon", occluded_lanes::<P, arm::Neon>));
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

/// The aarch64 compares: NEON is part of every aarch64, so no run-time test is needed.
#[cfg(target_arch = "aarch64")]
mod arm {
    use super::{Isa, LaneMask, Lanes};
    use std::arch::aarch64::*;

    pub struct Neon;

    /// Four 4-lane compares; each lane's all-ones result keeps its own bit of `1, 2, 4, 8`, and
    /// one horizontal add gathers them.
    #[inline(always)]
    fn neon_mask(
        a: &Lanes,
        b: &Lanes,
        cmp: impl Fn(float32x4_t, float32x4_t) -> uint32x4_t,
    ) -> LaneMask {
        const BITS: [u32; 4] = [1, 2, 4, 8];
        let mut mask = 0;
        for quarter in 0..4 {
            // SAFETY: reads 4 values inside 16-element arrays and a 4-element constant; NEON is
            // always present on aarch64.
            let bits = unsafe {
                let lanes = cmp(
                    vld1q_f32(a.as_ptr().add(4 * quarter)),
                    vld1q_f32(b.as_ptr().add(4 * quarter)),
                );
                vaddvq_u32(vandq_u32(lanes, vld1q_u32(BITS.as_ptr())))
            };
            mask |= (bits as LaneMask) << (4 * quarter);
        }
        mask
    }

    impl Isa for Neon {
        #[inline(always)]
        fn lt_mask(a: &Lanes, b: &Lanes) -> LaneMask {
            neon_mask(a, b, |x, y| unsafe { vcltq_f32(x, y) })
        }
        #[inline(always)]
        fn le_mask(a: &Lanes, b: &Lanes) -> LaneMask {
            neon_mask(a, b, |x, y| unsafe { vcleq_f32(x, y) })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::BakeInputs;
    use crate::ray::{Ray, RAY_T_MAX};
    use crate::sampling::Pcg32;
    use crate::scene::{self, builtin, prepare::prepare};
    use glam::Vec3;

    fn random_direction(rng: &mut Pcg32) -> Vec3 {
        loop {
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            if (0.01..=1.0).contains(&v.length_squared()) {
                return v.normalize();
            }
        }
    }

    /// Runs every copy of the traversal on `packet`: they must agree with each other and never
    /// report an inactive lane. Returns (lanes compared, lanes that differ from `expected`,
    /// lanes blocked).
    fn check_copies<P: Packet>(
        copies: &[(&'static str, dispatch::Traversal<P>)],
        bvh: &Bvh,
        packet: &P,
        above: LaneMask,
        expected: LaneMask,
    ) -> [usize; 3] {
        let answers: Vec<LaneMask> = copies
            .iter()
            .map(|(_, f)| f(bvh, packet, RAY_T_MAX))
            .collect();
        for ((name, _), &got) in copies.iter().zip(&answers) {
            assert_eq!(got, answers[0], "{name} differs from the portable copy");
            assert_eq!(got & !above, 0, "{name}: an inactive lane reported a hit");
        }
        [above, answers[0] ^ expected, expected].map(|m| m.count_ones() as usize)
    }

    /// Every copy of the traversal against single rays, on packets of `width` consecutive
    /// (Morton-adjacent) vertices and random directions, lanes above the horizon active.
    /// Returns (lanes compared, lanes that differ, lanes blocked).
    fn compare_with_single_rays(inputs: &BakeInputs, width: usize, packets: usize) -> [usize; 3] {
        let mut rng = Pcg32::new(7);
        let mut counts = [0; 3];
        for _ in 0..packets {
            // (Per packet: a copy's type names the packet's borrow of its origins.)
            let copies = dispatch::all_available();
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
            let checked = check_copies(&copies, &inputs.bvh, &packet, above, expected);
            counts.iter_mut().zip(checked).for_each(|(c, n)| *c += n);
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

    /// Every copy of the fan traversal against single rays: packets of `width` consecutive
    /// samples of a cosine set, turned into the tangent frame of a random vertex, lanes above
    /// the horizon active. Returns (lanes compared, lanes that differ, lanes blocked).
    fn compare_fans_with_single_rays(
        inputs: &BakeInputs,
        width: usize,
        packets: usize,
    ) -> [usize; 3] {
        let mut rng = Pcg32::new(11);
        let set = crate::sampling::cosine_hemisphere(1024, 3);
        let copies = dispatch::all_available();
        let mut counts = [0; 3];
        for _ in 0..packets {
            let vertex = (rng.next_u32() as usize) % inputs.origins.len();
            let normal = inputs.normals[vertex];
            let start = (rng.next_u32() as usize) % (set.len() - width + 1);
            let to_world = crate::sampling::VertexDirections::new(set.frame, normal);
            let directions: Vec<Vec3> = set.directions[start..start + width]
                .iter()
                .map(|&d| to_world.world(d))
                .collect();
            let above = lane_mask(|l| l < width && normal.dot(directions[l]) > 0.0);
            let packet = FanPacket::new(inputs.origins[vertex], &directions, above);
            let expected = lane_mask(|l| {
                above & (1 << l) != 0
                    && inputs
                        .bvh
                        .occluded(&Ray::new(inputs.origins[vertex], directions[l]), RAY_T_MAX)
            });
            let checked = check_copies(&copies, &inputs.bvh, &packet, above, expected);
            counts.iter_mut().zip(checked).for_each(|(c, n)| *c += n);
        }
        counts
    }

    #[test]
    fn fans_agree_with_single_rays_on_the_dragon_and_bunny() {
        for (name, widths) in [
            ("dragon_vrip_res3.ply.gz", &[LANES][..]),
            ("bunny.obj", &[1, 5, LANES - 1, LANES][..]),
        ] {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("tests/data")
                .join(name);
            let (mesh, _) = prepare(scene::load(&path).unwrap()).unwrap();
            let inputs = BakeInputs::new(&mesh, 1, 1, 1);
            for &width in widths {
                let [lanes, differ, blocked] =
                    compare_fans_with_single_rays(&inputs, width, 10_000);
                println!(
                    "{name}, {width} lanes: {lanes} lanes, {blocked} blocked, {differ} differ"
                );
                assert!(
                    blocked > lanes / 20,
                    "too few blocked rays to test anything"
                );
                assert_eq!(differ, 0, "{name}, {width}-lane fans");
            }
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
        // The same for fans from one point inside.
        for width in [1, 7, LANES] {
            let directions: Vec<Vec3> = (0..width).map(|_| random_direction(&mut rng)).collect();
            for active in [0, 0b1010_0110_0101_1001, ALL_LANES] {
                let packet = FanPacket::new(points[3], &directions, active);
                let expected = active & (ALL_LANES >> (LANES - width));
                assert_eq!(packet.active, expected);
                for (name, f) in dispatch::all_available() {
                    assert_eq!(f(&bvh, &packet, RAY_T_MAX), expected, "{name} fan");
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
        let fan = FanPacket::new(Vec3::ZERO, &[Vec3::X, Vec3::Y], ALL_LANES);
        assert_eq!(occluded_fan(&bvh, &fan, RAY_T_MAX), 0);
    }
}
