//! Fan packets: rays that share one origin and fan out in up to 16 directions. The CPU bake
//! casts a tangent-frame set (`DirectionFrame::Tangent`, the cosine set) this way: every vertex
//! turns the set into its own directions, so no two vertices share a ray direction, but the
//! rays of one vertex share their origin, and the samples of one run of the set
//! (`SampleSet::fan_runs`, a small cone) leave it through nearly the same boxes. Worked out
//! once per packet rather than per lane:
//!
//! - the translation of every box plane to the origin, `bound - origin`;
//! - the translation of every triangle vertex to the origin, `v - origin`.
//!
//! Per lane remain the slab products with the lane's reciprocal direction, the lane's
//! permutation and shear of the translated vertices, the edge functions and the hit distance.
//! Where lanes meet both children of a node, the one whose centre is nearer the origin is
//! entered first: a vertex is mostly blocked by its neighbours.

use glam::Vec3;

use super::{
    max, min, sheared_triangle_lanes, Isa, LaneHits, LaneLimit, LaneMask, Lanes, Packet, ALL_LANES,
    LANES,
};
use crate::bvh::{BvhNode, BvhTriangle};
use crate::ray::{MIN_DIRECTION_COMPONENT, SLAB_WIDENING};

/// Up to [`LANES`] rays from one origin, with the per-ray constants of the box and triangle
/// tests of each lane laid out by lane.
#[derive(Clone, Debug)]
#[repr(C, align(64))]
pub struct FanPacket {
    /// Reciprocal directions by axis, `[axis][lane]`.
    inv_direction: [Lanes; 3],
    /// Shear constants by lane, `[sx, sy, sz][lane]` (see [`crate::ray::Ray::shear`]).
    shear: [Lanes; 3],
    /// The triangle test's permutation by lane, `[axis_x, axis_y, axis_z][lane]`.
    axes: [[u32; LANES]; 3],
    origin: [f32; 3],
    /// Lanes that take part; the others never report a hit.
    pub active: LaneMask,
}

impl FanPacket {
    /// Rays from `origin` along each of `directions` (at most [`LANES`]), those in `active`
    /// taking part; lanes beyond `directions.len()` are empty.
    #[inline(always)]
    pub fn new(origin: Vec3, directions: &[Vec3], active: LaneMask) -> Self {
        assert!(
            directions.len() <= LANES,
            "a packet holds at most {LANES} rays"
        );
        let filled = ALL_LANES >> (LANES - directions.len());
        // Empty lanes repeat the first direction so that they compute harmless finite numbers.
        let first = directions.first().copied().unwrap_or(Vec3::Z);
        let directions: [Vec3; LANES] =
            std::array::from_fn(|lane| directions.get(lane).copied().unwrap_or(first));
        let mut packet = FanPacket {
            inv_direction: [[0.0; LANES]; 3],
            shear: [[0.0; LANES]; 3],
            axes: [[0; LANES]; 3],
            origin: origin.to_array(),
            active: active & filled,
        };
        // `Ray::new`'s constants, step for step, in a loop over lanes that compiles to vector
        // code (building 16 `Ray`s and transposing them took a fifth of the bake).
        for (lane, direction) in directions.iter().enumerate() {
            let [x, y, z] = direction.to_array();
            packet.inv_direction[0][lane] = 1.0 / away_from_zero(x);
            packet.inv_direction[1][lane] = 1.0 / away_from_zero(y);
            packet.inv_direction[2][lane] = 1.0 / away_from_zero(z);
            let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
            let axis_z: u32 = if ax > ay {
                if ax > az {
                    0
                } else {
                    2
                }
            } else if ay > az {
                1
            } else {
                2
            };
            let next = |axis: u32| if axis == 2 { 0 } else { axis + 1 };
            let v = [x, y, z];
            let dz = component(&v, axis_z);
            let (axis_x, axis_y) = if dz < 0.0 {
                (next(next(axis_z)), next(axis_z))
            } else {
                (next(axis_z), next(next(axis_z)))
            };
            packet.axes[0][lane] = axis_x;
            packet.axes[1][lane] = axis_y;
            packet.axes[2][lane] = axis_z;
            packet.shear[0][lane] = component(&v, axis_x) / dz;
            packet.shear[1][lane] = component(&v, axis_y) / dz;
            packet.shear[2][lane] = 1.0 / dz;
        }
        packet
    }

    /// The point every lane starts from.
    pub(super) fn origin(&self) -> Vec3 {
        Vec3::from_array(self.origin)
    }

    /// `v - origin`, the first step of both tests, shared by every lane.
    #[inline(always)]
    fn translated(&self, v: [f32; 3]) -> [f32; 3] {
        let o = self.origin;
        [v[0] - o[0], v[1] - o[1], v[2] - o[2]]
    }
}

/// `Ray::new`'s guard against zero direction components.
#[inline(always)]
fn away_from_zero(d: f32) -> f32 {
    if d.abs() < MIN_DIRECTION_COMPONENT {
        MIN_DIRECTION_COMPONENT.copysign(d)
    } else {
        d
    }
}

/// Component `axis` of `v`, by selects rather than an index, so that a loop over lanes with
/// different axes stays vector code.
#[inline(always)]
fn component(v: &[f32; 3], axis: u32) -> f32 {
    if axis == 0 {
        v[0]
    } else if axis == 1 {
        v[1]
    } else {
        v[2]
    }
}

impl Packet for FanPacket {
    #[inline(always)]
    fn active(&self) -> LaneMask {
        self.active
    }

    /// The child whose centre is nearer the shared origin first.
    #[inline(always)]
    fn right_first(&self, left: &BvhNode, right: &BvhNode) -> bool {
        let o = Vec3::from_array(self.origin);
        let centre_distance = |n: &BvhNode| (n.min() + n.max() - 2.0 * o).length_squared();
        centre_distance(right) < centre_distance(left)
    }

    /// `ray::intersect_box` lane by lane: `(bound - origin) * inv_dir`, the nearer and farther
    /// of the two planes per axis, entry no earlier than 0, exit widened and capped at `t_max`.
    #[inline(always)]
    fn box_lanes<I: Isa>(&self, node: &BvhNode, t_max: impl LaneLimit) -> LaneMask {
        let words: &[f32; 8] = bytemuck::cast_ref(node);
        let low = self.translated([words[0], words[1], words[2]]);
        let high = self.translated([words[4], words[5], words[6]]);
        let inv = &self.inv_direction;
        let mut near = [0.0f32; LANES];
        let mut far = [0.0f32; LANES];
        for lane in 0..LANES {
            let (lx, hx) = (low[0] * inv[0][lane], high[0] * inv[0][lane]);
            let (ly, hy) = (low[1] * inv[1][lane], high[1] * inv[1][lane]);
            let (lz, hz) = (low[2] * inv[2][lane], high[2] * inv[2][lane]);
            near[lane] = max(max(min(lx, hx), min(ly, hy)), max(min(lz, hz), 0.0));
            let exit = min(min(max(lx, hx), max(ly, hy)), max(lz, hz));
            far[lane] = min(exit * SLAB_WIDENING, t_max.at(lane));
        }
        I::le_mask(&near, &far)
    }

    /// `ray::intersect_triangle` lane by lane: the vertices are translated to the origin once,
    /// then each lane permutes and shears them with its own constants.
    #[inline(always)]
    fn triangle_lanes<I: Isa>(
        &self,
        tri: &BvhTriangle,
        lanes: LaneMask,
        t_max: impl LaneLimit,
        hits: &mut LaneHits,
    ) -> LaneMask {
        let a = self.translated(tri.v0);
        let b = self.translated(tri.v1);
        let c = self.translated(tri.v2);
        let [kx, ky, kz] = &self.axes;
        let [sx, sy, sz] = &self.shear;
        let shear = |v: &[f32; 3], lane: usize| {
            let z = component(v, kz[lane]);
            (
                component(v, kx[lane]) - sx[lane] * z,
                component(v, ky[lane]) - sy[lane] * z,
                z,
            )
        };
        sheared_triangle_lanes::<I>([&a, &b, &c], shear, |lane| sz[lane], lanes, t_max, hits)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ray::Ray;
    use crate::sampling::Pcg32;

    #[test]
    fn lane_constants_are_those_of_single_rays() {
        // Random directions, and the cases where `Ray::new` branches: ties between the largest
        // components, negative dominant axes, zero and tiny components.
        let mut rng = Pcg32::new(17);
        let mut directions = vec![
            Vec3::X,
            Vec3::NEG_Y,
            Vec3::Z,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 1.0),
            Vec3::new(0.0, -1.0, -1.0),
            Vec3::new(1e-30, -1e-25, -1.0),
            Vec3::new(-0.0, 0.6, -0.8),
        ];
        while directions.len() < 16 * 64 {
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            directions.push(v.normalize_or(Vec3::X));
        }
        let origin = Vec3::new(0.5, -2.0, 3.0);
        for fan in directions.chunks(LANES) {
            let packet = FanPacket::new(origin, fan, ALL_LANES);
            for (lane, &d) in fan.iter().enumerate() {
                let ray = Ray::new(origin, d);
                let bits = |v: [f32; 3]| v.map(f32::to_bits);
                let lane_of = |arrays: &[Lanes; 3]| [0, 1, 2].map(|a| arrays[a][lane]);
                assert_eq!(
                    bits(lane_of(&packet.inv_direction)),
                    bits(ray.inv_direction.to_array()),
                    "{d}"
                );
                assert_eq!(
                    bits(lane_of(&packet.shear)),
                    bits(ray.shear.to_array()),
                    "{d}"
                );
                let axes = [0, 1, 2].map(|a| packet.axes[a][lane] as usize);
                assert_eq!(axes, [ray.axis_x, ray.axis_y, ray.axis_z], "{d}");
            }
        }
    }
}
