//! Rays: robust origins, and the watertight ray–triangle and ray–box tests that the BVH
//! traversal (CPU here, WGSL on the GPU) is built from.

use glam::Vec3;

/// Relative size of the ray-origin offset: 2^-15 is 256 units in the last place of an f32.
///
/// The intersection tests below subtract the origin from triangle vertices and form products
/// of the differences; their rounding error is a few ulps of the coordinates involved. Moving
/// the origin 256 ulps off the surface clears that error with a wide margin while staying far
/// below any feature a mesh stored in f32 can resolve.
pub const ORIGIN_OFFSET_ULPS: f32 = 1.0 / 32768.0;

/// Moves a surface point off its surface along the unit normal `n`, by an amount that scales
/// with the magnitude of the coordinates (the size of their rounding error), never less than a
/// fixed fraction of the scene's extent so that points near the world origin still move.
///
/// `scene_extent` is the largest side of the scene's bounding box.
pub fn offset_ray_origin(p: Vec3, n: Vec3, scene_extent: f32) -> Vec3 {
    let magnitude = p.abs().max_element().max(scene_extent / 32.0);
    p + n * (magnitude * ORIGIN_OFFSET_ULPS)
}

/// Far end of every ray: f32::MAX rather than infinity, which WGSL cannot write as a literal.
pub const RAY_T_MAX: f32 = f32::MAX;

/// The triangle index of no triangle: a ray that escaped or was never cast, and the
/// placeholder triangle of an empty tree.
pub const NO_HIT: u32 = u32::MAX;

/// `1 + 2 gamma(3)` with `gamma(n) = n u / (1 - n u)`, u = 2^-24: widens the far slab distance of
/// a box test so that rounding in `(bound - origin) * inv_dir` can never make a ray miss a box
/// that it touches (pbrt-v4, "Robust ray–bounds intersections").
pub const SLAB_WIDENING: f32 =
    1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Direction components smaller than this are replaced by it (keeping the sign) before taking
/// reciprocals, so that a slab test never computes 0 * inf.
pub const MIN_DIRECTION_COMPONENT: f32 = 1e-20;

/// A ray with the per-ray constants of the box and triangle tests precomputed.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3,
    pub direction: Vec3,
    pub inv_direction: Vec3,
    /// Axis along which the direction is largest (becomes z in the triangle test's frame).
    pub axis_z: usize,
    pub axis_x: usize,
    pub axis_y: usize,
    /// Shear constants (dx/dz, dy/dz, 1/dz) in the permuted axes: after `p.xy -= shear.xy * p.z`
    /// the ray runs along +z.
    pub shear: Vec3,
}

impl Ray {
    pub fn new(origin: Vec3, direction: Vec3) -> Self {
        let safe = |d: f32| {
            if d.abs() < MIN_DIRECTION_COMPONENT {
                MIN_DIRECTION_COMPONENT.copysign(d)
            } else {
                d
            }
        };
        let inv_direction = Vec3::new(
            1.0 / safe(direction.x),
            1.0 / safe(direction.y),
            1.0 / safe(direction.z),
        );
        let abs = direction.abs();
        let axis_z = if abs.x > abs.y {
            if abs.x > abs.z {
                0
            } else {
                2
            }
        } else if abs.y > abs.z {
            1
        } else {
            2
        };
        let mut axis_x = (axis_z + 1) % 3;
        let mut axis_y = (axis_x + 1) % 3;
        // Keep the winding of the sheared triangle when the dominant component is negative.
        if direction[axis_z] < 0.0 {
            std::mem::swap(&mut axis_x, &mut axis_y);
        }
        let dz = direction[axis_z];
        let shear = Vec3::new(direction[axis_x] / dz, direction[axis_y] / dz, 1.0 / dz);
        Ray {
            origin,
            direction,
            inv_direction,
            axis_z,
            axis_x,
            axis_y,
            shear,
        }
    }
}

/// Slab test: the entry distance if the ray meets the box within `[t_min, t_max]`.
#[inline]
pub fn intersect_box(ray: &Ray, min: Vec3, max: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
    let t0 = (min - ray.origin) * ray.inv_direction;
    let t1 = (max - ray.origin) * ray.inv_direction;
    let near = t0.min(t1).max_element().max(t_min);
    let far = (t0.max(t1).min_element() * SLAB_WIDENING).min(t_max);
    (near <= far).then_some(near)
}

/// The far end of a closest-hit query once a hit at distance `t` (positive, finite) is known:
/// the next f32 after `t`, so that a triangle at the very same distance is still found, and
/// [`replaces`] settles the tie whatever order a traversal meets the two in. WGSL twin `past`
/// in wgsl/bvh.wgsl.
pub fn past(t: f32) -> f32 {
    t.next_up()
}

/// How far beyond the closest hit so far boxes are still entered, relative to its distance.
/// A box that holds a triangle hit at exactly that distance must not be passed by: its entry
/// distance is rounded otherwise than the triangle's hit distance, and differently for the
/// CPU's exact boxes and the GPU's grid-rounded ones, so without a margin a tie could be seen
/// by one traversal and not by another. 2^-12 is far above both roundings (a few ulps).
pub const TIE_REACH: f32 = 1.0 + 1.0 / 4096.0;

/// The far end of the box tests once a closest hit at `t` is known ([`TIE_REACH`]). WGSL twin
/// `reach` in wgsl/bvh.wgsl.
pub fn reach(t: f32) -> f32 {
    t * TIE_REACH
}

/// Whether a hit at `t` on the triangle at `index` in the scene's triangle list replaces the
/// closest hit so far, at `best_t` on `best_index`: it is nearer, or as near and first in the
/// scene's list. Where a ray meets two triangles at one distance (on an edge they share, or on
/// coincident faces, common in CAD models) every traversal, the CPU's single rays and packets
/// and the GPU's, then keeps the same one, whatever tree they walk: the scene's order, not the
/// tree's leaf order, settles the tie, so a better tree changes no answer. WGSL twin
/// `replaces` in wgsl/bvh.wgsl.
pub fn replaces(t: f32, index: u32, best_t: f32, best_index: u32) -> bool {
    t < best_t || (t == best_t && index < best_index)
}

/// A hit on a triangle: distance along the ray and barycentrics of vertices 1 and 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

/// The barycentrics of a hit's three corners from those of corners 1 and 2 (`u`, `v`).
pub fn barycentrics(u: f32, v: f32) -> [f32; 3] {
    [1.0 - u - v, u, v]
}

/// `values` at the corners `corners` of a triangle blended at barycentrics `(u, v)` of
/// corners 1 and 2: a hit's point, its interpolated shading normal.
pub fn blend_at(values: &[Vec3], corners: [u32; 3], u: f32, v: f32) -> Vec3 {
    corners
        .iter()
        .zip(barycentrics(u, v))
        .map(|(&j, b)| values[j as usize] * b)
        .sum()
}

/// Watertight ray–triangle intersection (Woop, Benthin, Wald 2013).
///
/// The vertices are translated to the ray origin and sheared so the ray runs along +z; the
/// 2D edge functions then decide coverage. A shared edge gives its two triangles edge functions
/// that are exact negatives of each other in floating point (same products, swapped operands of
/// one subtraction), so a ray through the edge is inside at least one of them: no ray slips
/// between triangles that share vertices. Edge functions of exactly zero count as inside.
#[inline]
pub fn intersect_triangle(
    ray: &Ray,
    v0: Vec3,
    v1: Vec3,
    v2: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<TriangleHit> {
    let (kx, ky, kz) = (ray.axis_x, ray.axis_y, ray.axis_z);
    let a = v0 - ray.origin;
    let b = v1 - ray.origin;
    let c = v2 - ray.origin;
    let (sx, sy, sz) = (ray.shear.x, ray.shear.y, ray.shear.z);
    let ax = a[kx] - sx * a[kz];
    let ay = a[ky] - sy * a[kz];
    let bx = b[kx] - sx * b[kz];
    let by = b[ky] - sy * b[kz];
    let cx = c[kx] - sx * c[kz];
    let cy = c[ky] - sy * c[kz];

    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let az = sz * a[kz];
    let bz = sz * b[kz];
    let cz = sz * c[kz];
    let t = (u * az + v * bz + w * cz) / det;
    if !(t > t_min && t < t_max) {
        return None;
    }
    Some(TriangleHit {
        t,
        u: v / det,
        v: w / det,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_the_inside_and_misses_the_outside_of_a_triangle() {
        let (v0, v1, v2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let down = |x: f32, y: f32| Ray::new(Vec3::new(x, y, 1.0), Vec3::NEG_Z);
        let hit = intersect_triangle(&down(0.25, 0.25), v0, v1, v2, 0.0, f32::INFINITY).unwrap();
        assert!((hit.t - 1.0).abs() < 1e-6);
        assert!((hit.u - 0.25).abs() < 1e-6 && (hit.v - 0.25).abs() < 1e-6);
        assert!(intersect_triangle(&down(0.6, 0.6), v0, v1, v2, 0.0, f32::INFINITY).is_none());
        // Both faces are hit (visibility is two-sided) but never behind the origin.
        let up = Ray::new(Vec3::new(0.2, 0.2, -1.0), Vec3::Z);
        assert!(intersect_triangle(&up, v0, v1, v2, 0.0, f32::INFINITY).is_some());
        let away = Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::Z);
        assert!(intersect_triangle(&away, v0, v1, v2, 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn shared_edge_is_covered_from_any_direction() {
        // Two triangles sharing the diagonal of a skewed planar quad, hit through points of
        // the shared edge from random sides. (On a folded quad a ray can graze a silhouette
        // edge and miss legitimately, so the quad is planar.)
        let plane = |x: f32, y: f32| Vec3::new(x, y, 0.3 * x - 0.7 * y + 0.1);
        let (a, b, c, d) = (
            plane(0.1, 0.0),
            plane(1.3, 0.1),
            plane(1.1, 1.2),
            plane(-0.2, 0.9),
        );
        let normal = (b - a).cross(c - a).normalize();
        let mut rng = crate::sampling::Pcg32::new(5);
        let mut rays = 0;
        while rays < 20_000 {
            let s = rng.next_f32();
            let on_edge = a + (c - a) * s;
            let dir = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5)
                .normalize_or(Vec3::Z);
            if dir.dot(normal).abs() < 0.05 {
                continue;
            }
            rays += 1;
            let origin = on_edge - dir * (1.0 + 3.0 * rng.next_f32());
            let ray = Ray::new(origin, dir);
            let hit = intersect_triangle(&ray, a, b, c, 0.0, f32::INFINITY)
                .or_else(|| intersect_triangle(&ray, a, c, d, 0.0, f32::INFINITY));
            assert!(
                hit.is_some(),
                "ray from {origin} along {dir} (s = {s}) slipped through"
            );
        }
    }

    #[test]
    fn box_test_accepts_flat_boxes_and_axis_parallel_rays() {
        // A flat box (one triangle in the plane y = 0) is hit by rays crossing its plane.
        let min = Vec3::new(-1.0, 0.0, -1.0);
        let max = Vec3::new(1.0, 0.0, 1.0);
        let ray = Ray::new(Vec3::new(0.3, 2.0, 0.1), Vec3::NEG_Y);
        assert_eq!(intersect_box(&ray, min, max, 0.0, f32::INFINITY), Some(2.0));
        let slanted = Ray::new(Vec3::new(0.99, 1.0, -0.99), Vec3::new(0.0, -1.0, 0.0));
        assert!(intersect_box(&slanted, min, max, 0.0, f32::INFINITY).is_some());
        // Direction components of zero must not produce NaN (0 * inf) in the slab test.
        let thick_max = Vec3::new(1.0, 0.5, 1.0);
        let parallel = Ray::new(Vec3::new(-3.0, 0.25, 0.5), Vec3::X);
        assert_eq!(
            intersect_box(&parallel, min, thick_max, 0.0, f32::INFINITY),
            Some(2.0)
        );
        let above = Ray::new(Vec3::new(-3.0, 0.75, 0.5), Vec3::X);
        assert!(intersect_box(&above, min, thick_max, 0.0, f32::INFINITY).is_none());
        let on_face = Ray::new(Vec3::new(-3.0, 0.5, 1.0), Vec3::X);
        assert!(
            intersect_box(&on_face, min, thick_max, 0.0, 1.0).is_none(),
            "t_max honoured"
        );
    }

    #[test]
    fn origin_offset_scales_with_the_coordinates() {
        let n = Vec3::Y;
        let near = offset_ray_origin(Vec3::new(0.0, 0.0, 0.0), n, 2.0);
        assert!((near.y - 2.0 / 32.0 / 32768.0).abs() < 1e-12);
        let far = offset_ray_origin(Vec3::new(1000.0, 0.0, 0.0), n, 2.0);
        assert!((far.y - 1000.0 / 32768.0).abs() < 1e-6);
        assert_eq!(far.x, 1000.0);
    }
}
