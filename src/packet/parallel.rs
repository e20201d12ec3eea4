//! Parallel packets: rays that share one direction and start at different origins. The CPU
//! bake casts each direction of a set shared by all vertices (`DirectionFrame::World`) from 16
//! Morton-adjacent vertices at once; their rays are parallel and close, so they visit nearly
//! the same nodes, and everything that depends only on the direction is worked out once:
//!
//! - the near and far slab planes of every box (picked by the sign of each direction component);
//! - the Woop–Benthin–Wald permutation and shear constants, and each triangle vertex's
//!   coordinates permuted into the shear frame, once per triangle and packet.
//!
//! Per lane remain the slab distances, the translation of the vertices to the lane's origin and
//! the shear, the edge functions and the hit distance.
//!
//! (Shearing each vertex once per packet, relative to an anchor point, and subtracting a sheared
//! origin per lane would save a third of the triangle test's lane work and stays watertight, but
//! it moves the rounding: on the built-in scene's ground plane 0.33% of the rays, grazing their
//! own plane, came out blocked.)

use glam::Vec3;

use super::{
    max, min, sheared_triangle_lanes, Isa, LaneHits, LaneLimit, LaneMask, Lanes, Packet, ALL_LANES,
    LANES,
};
use crate::bvh::{BvhNode, BvhTriangle};
use crate::ray::{Ray, SLAB_WIDENING};

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

    /// The single ray of one lane, as [`crate::bvh::Bvh::occluded`] would trace it.
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
fn box_lanes<I: Isa>(packet: &RayPacket, node: &BvhNode, t_max: impl LaneLimit) -> LaneMask {
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
        far[lane] = min(min(min(fx, fy), fz) * SLAB_WIDENING, t_max.at(lane));
    }
    I::le_mask(&near, &far)
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
    t_max: impl LaneLimit,
    hits: &mut LaneHits,
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
    sheared_triangle_lanes::<I>([&a, &b, &c], shear, |_| sz, lanes, t_max, hits)
}

impl Packet for RayPacket<'_> {
    #[inline(always)]
    fn active(&self) -> LaneMask {
        self.active
    }
    #[inline(always)]
    fn box_lanes<I: Isa>(&self, node: &BvhNode, t_max: impl LaneLimit) -> LaneMask {
        box_lanes::<I>(self, node, t_max)
    }
    #[inline(always)]
    fn triangle_lanes<I: Isa>(
        &self,
        tri: &BvhTriangle,
        lanes: LaneMask,
        t_max: impl LaneLimit,
        hits: &mut LaneHits,
    ) -> LaneMask {
        triangle_lanes::<I>(self, tri, lanes, t_max, hits)
    }
}
