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

pub use dispatch::{on_widest_unit, Kernel};
pub use fan::FanPacket;
pub use parallel::{PacketOrigins, RayPacket};

use crate::bvh::{Bvh, BvhNode, BvhTriangle, PointPath, STACK_SIZE};
use crate::ray::{past, reach, replaces, NO_HIT};

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

/// The far end of each lane's ray: one distance for every lane (any-hit queries), or a
/// lane's own (closest-hit queries, each lane's nearest hit so far).
pub trait LaneLimit: Copy {
    fn at(self, lane: usize) -> f32;
}

impl LaneLimit for f32 {
    #[inline(always)]
    fn at(self, _lane: usize) -> f32 {
        self
    }
}

impl LaneLimit for &Lanes {
    #[inline(always)]
    fn at(self, lane: usize) -> f32 {
        self[lane]
    }
}

/// The lane work of the watertight triangle test (`ray::intersect_triangle`), shared by both
/// packet kinds, which differ only in how a vertex reaches a lane's sheared frame:
/// `shear(v, lane)` is vertex `v` translated to the lane's origin, permuted and sheared, as
/// `(x, y, z)` with `z` not yet scaled; `z_scale(lane)` is the lane's `1 / d_z`. Edge
/// functions are computed for all lanes at once, and where any lane of `lanes` is inside (most
/// triangles are missed by every lane), every lane's distance too: one vector division costs
/// less than finishing the lanes inside one by one, whose count no branch predicts. Returns
/// the lanes of `lanes` that hit on `(0, t_max)`, their hits written to `hits_out` (the other
/// lanes' entries there are meaningless).
#[inline(always)]
fn sheared_triangle_lanes<I: Isa>(
    [a, b, c]: [&[f32; 3]; 3],
    shear: impl Fn(&[f32; 3], usize) -> (f32, f32, f32),
    z_scale: impl Fn(usize) -> f32,
    lanes: LaneMask,
    t_max: impl LaneLimit,
    hits_out: &mut LaneHits,
) -> LaneMask {
    let LaneHits { t, v, w, det } = hits_out;
    let mut u = [0.0f32; LANES];
    // A lane is outside when its edge functions have mixed signs.
    let mut lowest = [0.0f32; LANES];
    let mut highest = [0.0f32; LANES];
    for lane in 0..LANES {
        let (ax, ay, _) = shear(a, lane);
        let (bx, by, _) = shear(b, lane);
        let (cx, cy, _) = shear(c, lane);
        u[lane] = cx * by - cy * bx;
        v[lane] = ax * cy - ay * cx;
        w[lane] = bx * ay - by * ax;
        lowest[lane] = min(min(u[lane], v[lane]), w[lane]);
        highest[lane] = max(max(u[lane], v[lane]), w[lane]);
    }
    const ZERO: Lanes = [0.0; LANES];
    let outside = I::lt_mask(&lowest, &ZERO) & I::lt_mask(&ZERO, &highest);
    let inside = lanes & !outside;
    if inside == 0 {
        return 0;
    }
    let mut limit = [0.0f32; LANES];
    for lane in 0..LANES {
        det[lane] = u[lane] + v[lane] + w[lane];
        let s = z_scale(lane);
        let (az, bz, cz) = (shear(a, lane).2, shear(b, lane).2, shear(c, lane).2);
        t[lane] = (u[lane] * (s * az) + v[lane] * (s * bz) + w[lane] * (s * cz)) / det[lane];
        limit[lane] = t_max.at(lane);
    }
    // A zero determinant (edge-on) is no hit; its distance is not a number or infinite.
    let nonzero = I::lt_mask(det, &ZERO) | I::lt_mask(&ZERO, det);
    inside & nonzero & I::lt_mask(&ZERO, t) & I::lt_mask(t, &limit)
}

/// What the traversal needs of a packet kind: its active lanes, and its box and triangle tests.
trait Packet {
    /// Lanes that take part; the others never report a hit.
    fn active(&self) -> LaneMask;
    /// Lanes that meet the node's box within `[0, t_max]`, as `ray::intersect_box` decides.
    fn box_lanes<I: Isa>(&self, node: &BvhNode, t_max: impl LaneLimit) -> LaneMask;
    /// Lanes among `lanes` that hit the triangle on `(0, t_max)`, as
    /// `ray::intersect_triangle` decides (both faces count, zero edge functions are inside),
    /// with their hits in `hits`.
    fn triangle_lanes<I: Isa>(
        &self,
        tri: &BvhTriangle,
        lanes: LaneMask,
        t_max: impl LaneLimit,
        hits: &mut LaneHits,
    ) -> LaneMask;
    /// Whether to enter `right` before `left` when lanes meet both.
    fn right_first(&self, _left: &BvhNode, _right: &BvhNode) -> bool {
        false
    }
}

/// What a traversal asks and keeps: the far end of each lane's ray, and what a triangle hit
/// does to it.
trait Query {
    type Limit<'a>: LaneLimit
    where
        Self: 'a;
    fn limit(&self) -> Self::Limit<'_>;
    /// The far end of each lane's box tests.
    fn box_limit(&self) -> Self::Limit<'_>;
    /// Keeps the hits of `lanes` on triangle `index` of `Bvh::triangles`, `source` in the
    /// scene, as `hits` holds them; returns the lanes that are done.
    fn record(&mut self, lanes: LaneMask, index: u32, source: u32, hits: &LaneHits) -> LaneMask;
}

/// Any hit on `(0, t_max)` blocks a lane, which is then done.
struct Blocked {
    t_max: f32,
    blocked: LaneMask,
}

impl Query for Blocked {
    type Limit<'a> = f32;
    #[inline(always)]
    fn limit(&self) -> f32 {
        self.t_max
    }
    #[inline(always)]
    fn box_limit(&self) -> f32 {
        self.t_max
    }
    #[inline(always)]
    fn record(&mut self, lanes: LaneMask, _index: u32, _source: u32, _hits: &LaneHits) -> LaneMask {
        self.blocked |= lanes;
        lanes
    }
}

/// Each lane's nearest hit so far; a hit shortens the lane's ray to just past it, and no lane
/// is done before the walk ends.
pub struct ClosestHits {
    /// Distance of each lane's nearest hit, `t_max` where it has none.
    pub t: Lanes,
    /// Index in `Bvh::triangles` (leaf order) of the triangle hit, or `NO_HIT`.
    pub triangle: [u32; LANES],
    /// Index in the scene of the triangle hit, or `NO_HIT`: what settles ties.
    source: [u32; LANES],
    /// The nearest hit's edge functions of corners 1 and 2 and their sum (`LaneHits`).
    edges: [[f32; 3]; LANES],
    /// Where each lane's ray ends: `ray::past` its nearest hit, `t_max` before one.
    limit: Lanes,
    /// Where each lane's box tests end: `ray::reach` its nearest hit, `t_max` before one.
    box_limit: Lanes,
}

/// Each lane's hit on the triangle last tested: its distance and, as
/// `ray::intersect_triangle` computes them, the edge functions of corners 1 and 2 and their
/// sum, whose quotients are the hit's barycentrics.
#[derive(Clone, Copy, Debug, Default)]
pub struct LaneHits {
    t: Lanes,
    v: Lanes,
    w: Lanes,
    det: Lanes,
}

impl ClosestHits {
    /// The barycentrics of corners 1 and 2 at `lane`'s nearest hit, as
    /// `ray::intersect_triangle` divides them; `None` where the lane hit nothing.
    pub fn barycentrics(&self, lane: usize) -> Option<(f32, f32)> {
        let [v, w, det] = self.edges[lane];
        (self.triangle[lane] != NO_HIT).then(|| (v / det, w / det))
    }

    fn new(t_max: f32) -> Self {
        ClosestHits {
            t: [t_max; LANES],
            triangle: [NO_HIT; LANES],
            source: [NO_HIT; LANES],
            edges: [[0.0; 3]; LANES],
            limit: [t_max; LANES],
            box_limit: [t_max; LANES],
        }
    }
}

impl Query for ClosestHits {
    type Limit<'a> = &'a Lanes;
    #[inline(always)]
    fn limit(&self) -> &Lanes {
        &self.limit
    }
    #[inline(always)]
    fn box_limit(&self) -> &Lanes {
        &self.box_limit
    }
    #[inline(always)]
    fn record(
        &mut self,
        mut lanes: LaneMask,
        index: u32,
        source: u32,
        hits: &LaneHits,
    ) -> LaneMask {
        while lanes != 0 {
            let lane = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            let t = hits.t[lane];
            if replaces(t, source, self.t[lane], self.source[lane]) {
                self.t[lane] = t;
                self.triangle[lane] = index;
                self.source[lane] = source;
                self.edges[lane] = [hits.v[lane], hits.w[lane], hits.det[lane]];
                self.limit[lane] = past(t);
                self.box_limit[lane] = reach(t);
            }
        }
        0
    }
}

/// Which lanes of `packet` are blocked on `(0, t_max)`: for every active lane the answer of
/// [`Bvh::occluded`] for that lane's ray. Inactive lanes are never reported.
pub fn occluded(bvh: &Bvh, packet: &RayPacket, t_max: f32) -> LaneMask {
    let mut query = Blocked { t_max, blocked: 0 };
    dispatch::traverse(bvh, packet, &PointPath::NONE, &mut query);
    query.blocked
}

/// [`occluded`] for a packet of rays from one origin, whose walk starts down `path`
/// (`bvh.path_to(origin)`, or [`PointPath::NONE`] to start at the root).
pub fn occluded_fan(bvh: &Bvh, packet: &FanPacket, path: &PointPath, t_max: f32) -> LaneMask {
    debug_assert!(path.leads_to(packet.origin()), "a path to another point");
    let mut query = Blocked { t_max, blocked: 0 };
    dispatch::traverse(bvh, packet, path, &mut query);
    query.blocked
}

/// The nearest hit on `(0, t_max)` of each active lane of a packet of rays from one origin:
/// what [`Bvh::closest_hit`] finds for that lane's ray, its distance bit for bit, and of
/// triangles at that distance the same one (`ray::replaces`).
pub fn closest_fan(bvh: &Bvh, packet: &FanPacket, path: &PointPath, t_max: f32) -> ClosestHits {
    debug_assert!(path.leads_to(packet.origin()), "a path to another point");
    let mut query = ClosestHits::new(t_max);
    dispatch::traverse(bvh, packet, path, &mut query);
    query
}

/// The traversal. A stack entry carries the lanes that met the node's box, so every lane
/// visits exactly the nodes its single ray would visit (only the order differs); a node is
/// entered while any of its lanes is still open, and the walk ends once none is (an any-hit
/// query closes a lane at its first hit, a closest-hit query only shortens its ray).
///
/// Children are taken in the order the packet kind asks for ([`Packet::right_first`]). Parallel
/// packets take them in stored order: on the dragon about 70% of the rays are unblocked and
/// must visit every box on their way whatever the order, and near-first orders (by the
/// children's centres along the direction, by the majority of lanes' entry distances, by the
/// first lane's) each cost more than they saved, 5–15% in CPU time. Fans enter the child whose
/// centre is nearer their origin first: 9% faster on the dragon, where a vertex's blockers are
/// mostly its neighbours, and 7% slower on the open built-in scene (docs/performance.md).
///
/// A walk given a path to its lanes' one origin ([`PointPath`]) starts at the path's deepest
/// node rather than at the root: every lane meets the boxes on the path, so only the other
/// children along it are tested, and its steps down are not taken (4% on the dragon).
#[inline(always)]
fn traverse<P: Packet, I: Isa, Q: Query>(bvh: &Bvh, packet: &P, path: &PointPath, query: &mut Q) {
    let Some(root) = bvh.nodes.first() else {
        return;
    };
    let mut stack = [(0u32, 0 as LaneMask); STACK_SIZE];
    let mut stack_len = 0;
    // Lanes still walking.
    let mut open = packet.active();
    let mut node = match path.deepest() {
        // Every lane meets the boxes that hold its origin. The other children on the way down
        // are tested here, none waiting on another's answer, and stacked the deepest on top.
        Some(deepest) => {
            for &sibling in path.siblings() {
                let sibling_box = &bvh.nodes[sibling as usize];
                let met = open & packet.box_lanes::<I>(sibling_box, query.box_limit());
                stack[stack_len] = (sibling, met);
                stack_len += (met != 0) as usize;
            }
            &bvh.nodes[deepest as usize]
        }
        None => {
            open &= packet.box_lanes::<I>(root, query.box_limit());
            root
        }
    };
    if open == 0 {
        return;
    }
    let mut hits_at = LaneHits::default();
    // Lanes that met the current node's box and are still open.
    let mut lanes = open;
    loop {
        if node.is_leaf() {
            let first = node.left_or_first;
            let leaf = &bvh.triangles[first as usize..][..node.triangle_count as usize];
            for (index, tri) in (first..).zip(leaf) {
                let hits = packet.triangle_lanes::<I>(tri, lanes, query.limit(), &mut hits_at);
                if hits != 0 {
                    let done = query.record(hits, index, tri.source_index, &hits_at);
                    open &= !done;
                    lanes &= !done;
                    if open == 0 {
                        return;
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
            let in_left = lanes & packet.box_lanes::<I>(left, query.box_limit());
            let in_right = lanes & packet.box_lanes::<I>(right, query.box_limit());
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
        // Next stacked node that still has an open lane.
        loop {
            if stack_len == 0 {
                return;
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
    pub type Copy<P, Q> = fn(&Bvh, &P, &PointPath, &mut Q);

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
    pub fn traverse<P: Packet, Q: Query>(bvh: &Bvh, packet: &P, path: &PointPath, query: &mut Q) {
        match level() {
            // SAFETY: the CPU has the features the function is compiled for.
            Level::Avx512 => unsafe { avx512(bvh, packet, path, query) },
            // SAFETY: as above.
            Level::Avx2 => unsafe { avx2(bvh, packet, path, query) },
            Level::Sse2 => super::traverse::<P, x86::Sse2, Q>(bvh, packet, path, query),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma,bmi1,bmi2,popcnt")]
    unsafe fn avx512<P: Packet, Q: Query>(bvh: &Bvh, packet: &P, path: &PointPath, query: &mut Q) {
        super::traverse::<P, x86::Avx512, Q>(bvh, packet, path, query)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,popcnt")]
    unsafe fn avx2<P: Packet, Q: Query>(bvh: &Bvh, packet: &P, path: &PointPath, query: &mut Q) {
        super::traverse::<P, x86::Avx2, Q>(bvh, packet, path, query)
    }

    #[cfg(target_arch = "aarch64")]
    pub fn traverse<P: Packet, Q: Query>(bvh: &Bvh, packet: &P, path: &PointPath, query: &mut Q) {
        super::traverse::<P, arm::Neon, Q>(bvh, packet, path, query)
    }

    /// Work around the traversal (a vertex's packets built, its hits projected) that LLVM
    /// vectorizes from plain loops, compiled once per vector unit like the traversal: `run`,
    /// `#[inline(always)]` in each implementation, is inlined into each copy of
    /// [`on_widest_unit`] together with the `#[inline]` functions it calls.
    pub trait Kernel {
        type Output;
        fn run(self) -> Self::Output;
    }

    /// Runs `kernel` compiled for the widest vector unit of this machine (as `traverse`
    /// chooses). Same bits on every unit: no copy contracts a product and a sum into one.
    #[cfg(target_arch = "x86_64")]
    pub fn on_widest_unit<K: Kernel>(kernel: K) -> K::Output {
        match level() {
            // SAFETY: the CPU has the features the function is compiled for.
            Level::Avx512 => unsafe { avx512_kernel(kernel) },
            // SAFETY: as above.
            Level::Avx2 => unsafe { avx2_kernel(kernel) },
            Level::Sse2 => kernel.run(),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma,bmi1,bmi2,popcnt")]
    unsafe fn avx512_kernel<K: Kernel>(kernel: K) -> K::Output {
        kernel.run()
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,popcnt")]
    unsafe fn avx2_kernel<K: Kernel>(kernel: K) -> K::Output {
        kernel.run()
    }

    /// Other targets: the one copy.
    #[cfg(not(target_arch = "x86_64"))]
    pub fn on_widest_unit<K: Kernel>(kernel: K) -> K::Output {
        kernel.run()
    }

    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    pub fn traverse<P: Packet, Q: Query>(bvh: &Bvh, packet: &P, path: &PointPath, query: &mut Q) {
        super::traverse::<P, Portable, Q>(bvh, packet, path, query)
    }

    /// Every copy of the traversal this machine can run, for tests that compare them.
    #[cfg(test)]
    pub fn all_available<P: Packet, Q: Query>() -> Vec<(&'static str, Copy<P, Q>)> {
        let mut copies: Vec<(&'static str, Copy<P, Q>)> =
            vec![("portable", super::traverse::<P, Portable, Q>)];
        #[cfg(target_arch = "x86_64")]
        {
            copies.push(("sse2", super::traverse::<P, x86::Sse2, Q>));
            if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
                // SAFETY: detected.
                copies.push(("avx2", |b, p, s, q| unsafe { avx2(b, p, s, q) }));
            }
            if std::is_x86_feature_detected!("avx512f") {
                // SAFETY: detected.
                copies.push(("avx512", |b, p, s, q| unsafe { avx512(b, p, s, q) }));
            }
        }
        #[cfg(target_arch = "aarch64")]
        copies.push(("neon", super::traverse::<P, arm::Neon, Q>));
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
mod tests;
