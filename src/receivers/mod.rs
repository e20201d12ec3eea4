//! Receivers: the points a bake computes transfer at. The mesh's vertices are one set; points
//! spread over the triangles (for the least-squares vertex fit, `fit.rs`) and held-out points
//! (for the surface error) are others. Both backends bake any set the same way, from its
//! positions, shading normals and albedo.
//!
//! A point on a triangle is its index and barycentric weights; its shading normal is the
//! normalised interpolation of the corners' normals, as a renderer shades it. Where that normal
//! leans past the flat face (a coarse mesh's shadow terminator) the bake keeps the path
//! tracer's rule: a direction below the face's own plane hits the face and is blocked.

pub mod atlas;
pub mod denoise;
pub mod dilation;
pub mod fit;
pub mod seams;
pub mod texel_fit;
pub mod texels;
pub mod uv_set;

use glam::{DVec3, Vec3};

use crate::ray::offset_ray_origin;
use crate::sampling::{pcg_hash, Pcg32};
use crate::scene::Scene;

/// A point on a triangle: `position = sum_i barycentrics[i] * corner_i`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    pub triangle: u32,
    /// Weights of the triangle's three corners, non-negative, summing to one.
    pub barycentrics: [f32; 3],
}

/// A set of receivers, structure of arrays: what a bake reads of each. Where they came from
/// (the vertices, or `SurfacePoint`s) is the caller's: it keeps the points it made them from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Receivers {
    pub positions: Vec<Vec3>,
    /// Where each receiver's rays start before the offset along its normal: its position, or
    /// for a vertex its position slid a little into its own faces ([`vertex_ray_starts`]).
    pub ray_starts: Vec<Vec3>,
    /// Unit shading normals.
    pub normals: Vec<Vec3>,
    pub albedo: Vec<Vec3>,
}

impl Receivers {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The vertices of a prepared scene (normals present).
    pub fn vertices(scene: &Scene) -> Receivers {
        let normals = scene.normals.clone().expect("a prepared scene has normals");
        Receivers {
            positions: scene.positions.clone(),
            ray_starts: vertex_ray_starts(scene),
            normals,
            albedo: scene.albedo.clone(),
        }
    }

    /// Points on the triangles of a prepared scene, everything interpolated from the corners.
    pub fn at_points(scene: &Scene, points: &[SurfacePoint]) -> Receivers {
        let normals = scene
            .normals
            .as_ref()
            .expect("a prepared scene has normals");
        let mut receivers = Receivers {
            positions: Vec::with_capacity(points.len()),
            ray_starts: Vec::new(),
            normals: Vec::with_capacity(points.len()),
            albedo: Vec::with_capacity(points.len()),
        };
        for &point in points {
            let corners = scene.triangles[point.triangle as usize];
            let blend = |values: &[Vec3]| -> Vec3 {
                corners
                    .iter()
                    .zip(point.barycentrics)
                    .map(|(&c, b)| values[c as usize] * b)
                    .sum()
            };
            receivers.positions.push(blend(&scene.positions));
            receivers
                .normals
                .push(shading_normal(blend(normals), &scene.positions, corners));
            receivers.albedo.push(blend(&scene.albedo));
        }
        receivers.ray_starts = receivers.positions.clone();
        receivers
    }
}

/// How far a vertex's rays start towards its faces: this fraction of the way to their mean
/// centroid.
pub const VERTEX_SLIDE: f64 = 1e-3;

/// Every vertex of a prepared scene slid [`VERTEX_SLIDE`] of the way towards the mean centroid
/// of the triangles that use it, within its tangent plane: a vertex's radiance is the limit of
/// its own faces', and where it sits on a line other geometry meets (a wall's foot on the
/// floor, a table leg's top under the table), a ray from the line itself would start exactly on
/// the other surface and see it or not by rounding. A vertex inside a flat or gently curved
/// patch barely moves (its faces' centroids surround it).
///
/// The slide is shortened where it would carry the ray origin (the start moved off along the
/// normal, `ray::offset_ray_origin`) behind one of the vertex's own faces. Where a smooth
/// normal spans a sharp concave corner (a room's corner, its normal along the diagonal) the
/// tangent plane cuts through the faces, and a full slide put the origin outside the room: a
/// third of a corner's rays escaped to the sky. Shortened, the origin stays in front of every
/// face that faces its normal by at least half the height the normal offset gives it.
pub fn vertex_ray_starts(scene: &Scene) -> Vec<Vec3> {
    let normals = scene
        .normals
        .as_deref()
        .expect("a prepared scene has normals");
    let mut centroids = vec![(DVec3::ZERO, 0u32); scene.positions.len()];
    for triangle in &scene.triangles {
        let centroid: DVec3 = triangle
            .iter()
            .map(|&i| scene.positions[i as usize].as_dvec3())
            .sum::<DVec3>()
            / 3.0;
        for &i in triangle {
            let (sum, count) = &mut centroids[i as usize];
            *sum += centroid;
            *count += 1;
        }
    }
    let slides: Vec<DVec3> = scene
        .positions
        .iter()
        .zip(normals)
        .zip(centroids)
        .map(|((&p, &n), (sum, count))| {
            if count == 0 {
                return DVec3::ZERO;
            }
            let (p, n) = (p.as_dvec3(), n.as_dvec3());
            let towards = sum / count as f64 - p;
            (towards - n * n.dot(towards)) * VERTEX_SLIDE
        })
        .collect();
    let scales = slide_scales(scene, normals, &slides);
    scene
        .positions
        .iter()
        .zip(slides.iter().zip(scales))
        .map(|(&p, (&slide, scale))| (p.as_dvec3() + slide * scale).as_vec3())
        .collect()
}

/// How much of each vertex's `slide` keeps its ray origin in front of its own faces (see
/// [`vertex_ray_starts`]): 1, or less where a face would otherwise be crossed. Faces turned
/// away from the vertex's normal (folded slivers) are left out: no origin along the normal is
/// in front of them.
fn slide_scales(scene: &Scene, normals: &[Vec3], slides: &[DVec3]) -> Vec<f64> {
    let extent = scene.extent();
    let mut scales = vec![1.0f64; scene.positions.len()];
    for &triangle in &scene.triangles {
        let Some(face) = face_normal(&scene.positions, triangle)
            .as_dvec3()
            .try_normalize()
        else {
            continue;
        };
        for i in triangle.map(|i| i as usize) {
            let behind = -face.dot(slides[i]);
            let p = scene.positions[i];
            let lift = face.dot((offset_ray_origin(p, normals[i], extent) - p).as_dvec3());
            if behind > 0.0 && lift > 0.0 {
                scales[i] = scales[i].min(0.5 * lift / behind);
            }
        }
    }
    scales
}

/// The interpolated normal, normalised; the face normal where the corners' normals cancel.
fn shading_normal(interpolated: Vec3, positions: &[Vec3], corners: [u32; 3]) -> Vec3 {
    interpolated
        .try_normalize()
        .unwrap_or_else(|| face_normal(positions, corners).normalize_or_zero())
}

/// The (unnormalised, twice-area-long) normal of a triangle, by its winding.
pub fn face_normal(positions: &[Vec3], corners: [u32; 3]) -> Vec3 {
    let [a, b, c] = corners.map(|i| positions[i as usize]);
    (b - a).cross(c - a)
}

/// The area of every triangle.
pub fn triangle_areas(scene: &Scene) -> Vec<f64> {
    scene
        .triangles
        .iter()
        .map(|&t| 0.5 * face_normal(&scene.positions, t).as_dvec3().length())
        .collect()
}

/// How many points [`spread_points`] gives each triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointDensity {
    /// Points in all, on average, per vertex of the mesh.
    pub per_vertex: f32,
    /// The fewest points any triangle gets (three in general position pin down a linear field).
    pub min_per_triangle: u32,
}

impl Default for PointDensity {
    fn default() -> Self {
        PointDensity {
            per_vertex: 8.0,
            min_per_triangle: 3,
        }
    }
}

/// Points spread over every triangle: `per_vertex * vertices` in all, shared by area, at least
/// `min_per_triangle` on each. Each triangle's points are a stratified pattern turned by a
/// shift drawn from `(seed, triangle)` alone, so a triangle's points do not depend on the
/// others (nor on their order).
pub fn spread_points(scene: &Scene, density: PointDensity, seed: u64) -> Vec<SurfacePoint> {
    let mut points = Vec::new();
    for (t, count) in points_per_triangle(scene, density).enumerate() {
        let mut rng = Pcg32::new(seed ^ ((pcg_hash(t as u32) as u64) << 32 | t as u64));
        let shift = [rng.next_f32() as f64, rng.next_f32() as f64];
        for i in 0..count {
            let (u, v) = r2_point(i, shift);
            points.push(SurfacePoint {
                triangle: t as u32,
                barycentrics: square_to_triangle(u, v),
            });
        }
    }
    points
}

/// How many points [`spread_points`] puts on each triangle: its share by area of
/// `per_vertex * vertices`, and no fewer than `min_per_triangle`.
fn points_per_triangle(scene: &Scene, density: PointDensity) -> impl Iterator<Item = u32> {
    let areas = triangle_areas(scene);
    let total: f64 = areas.iter().sum();
    let budget = density.per_vertex as f64 * scene.vertex_count() as f64;
    areas.into_iter().map(move |area| {
        let share = if total > 0.0 {
            (budget * area / total).round() as u32
        } else {
            0
        };
        share.max(density.min_per_triangle)
    })
}

/// How many points [`spread_points`] spreads, without spreading them.
pub fn spread_point_count(scene: &Scene, density: PointDensity) -> usize {
    points_per_triangle(scene, density)
        .map(|n| n as usize)
        .sum()
}

/// `count` points, independently and uniformly by area over the whole surface (the held-out
/// points of the surface error).
pub fn uniform_points(scene: &Scene, count: usize, seed: u64) -> Vec<SurfacePoint> {
    let areas = triangle_areas(scene);
    let mut cumulative = Vec::with_capacity(areas.len());
    let mut sum = 0.0;
    for a in &areas {
        sum += a;
        cumulative.push(sum);
    }
    let mut rng = Pcg32::new(seed);
    let mut draw = || rng.next_u32() as f64 / 4_294_967_296.0;
    (0..count)
        .map(|_| {
            let target = draw() * sum;
            let t = cumulative
                .partition_point(|&c| c <= target)
                .min(areas.len() - 1);
            SurfacePoint {
                triangle: t as u32,
                barycentrics: square_to_triangle(draw(), draw()),
            }
        })
        .collect()
}

/// Point i of the R2 sequence (Roberts' plastic-number lattice), shifted modulo one: a
/// well-spread 2D set of any size.
fn r2_point(i: u32, shift: [f64; 2]) -> (f64, f64) {
    const G: f64 = 1.324_717_957_244_746;
    let a = [1.0 / G, 1.0 / (G * G)];
    let f = |k: usize| (shift[k] + a[k] * (i as f64 + 0.5)).fract();
    (f(0), f(1))
}

/// Uniform on the unit square to uniform on the triangle (the square-root map), as barycentrics.
pub fn square_to_triangle(u: f64, v: f64) -> [f32; 3] {
    let s = u.sqrt();
    let b1 = s * (1.0 - v);
    let b2 = s * v;
    [(1.0 - b1 - b2).max(0.0) as f32, b1 as f32, b2 as f32]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;
    use crate::scene::prepare::prepare;

    /// A vertex on a wall's bottom edge starts its rays up the wall, off the line where the
    /// wall meets a floor; a vertex inside the wall, its faces all round it, does not move off
    /// its point by more than rounding; no start leaves the vertex's tangent plane.
    #[test]
    fn vertex_rays_start_inside_their_own_faces() {
        let wall = builtin::grid_plane(Vec3::new(0.0, 1.0, 0.0), Vec3::X, Vec3::Y, 4, Vec3::ONE);
        let starts = vertex_ray_starts(&wall);
        for (v, (&p, &start)) in wall.positions.iter().zip(&starts).enumerate() {
            let moved = start - p;
            assert!(
                moved.z.abs() < 1e-9,
                "vertex {v} left the wall's plane: {moved}"
            );
            if p.y == 0.0 && p.x.abs() < 1.0 {
                // The bottom edge: its faces lie above it.
                assert!(moved.y > 1e-5 && moved.y < 1e-3, "vertex {v}: {moved}");
            }
            if p.y > 0.0 && p.y < 2.0 && p.x.abs() < 1.0 {
                assert!(moved.length() < 1e-6, "inside vertex {v} moved {moved}");
            }
        }
    }

    fn plane() -> Scene {
        let flat = builtin::grid_plane(Vec3::ZERO, Vec3::X, Vec3::Z, 4, Vec3::ONE);
        prepare(flat).unwrap().0
    }

    #[test]
    fn spread_points_share_by_area_with_a_floor() {
        let scene = plane();
        let density = PointDensity {
            per_vertex: 8.0,
            min_per_triangle: 3,
        };
        let points = spread_points(&scene, density, 5);
        let mut per_triangle = vec![0u32; scene.triangle_count()];
        for p in &points {
            per_triangle[p.triangle as usize] += 1;
            let sum: f32 = p.barycentrics.iter().sum();
            assert!((sum - 1.0).abs() < 1e-6);
            assert!(p.barycentrics.iter().all(|&b| b >= 0.0));
        }
        // Equal areas: equal shares of 8 x 25 vertices over 32 triangles, rounded.
        let expected = (8.0 * scene.vertex_count() as f64 / scene.triangle_count() as f64).round();
        assert!(per_triangle.iter().all(|&n| n as f64 == expected.max(3.0)));
        let sparse = spread_points(
            &scene,
            PointDensity {
                per_vertex: 0.1,
                min_per_triangle: 3,
            },
            5,
        );
        assert_eq!(sparse.len(), 3 * scene.triangle_count());
    }

    #[test]
    fn uniform_points_cover_triangles_in_proportion_to_area() {
        // Two triangles, one three times the other's area.
        let scene = Scene {
            positions: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::Y,
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(5.0, 0.0, 0.0),
                Vec3::new(2.0, 1.0, 0.0),
            ],
            normals: Some(vec![Vec3::Z; 6]),
            albedo: vec![Vec3::ONE; 6],
            triangles: vec![[0, 1, 2], [3, 4, 5]],
        };
        let points = uniform_points(&scene, 40_000, 3);
        let on_large = points.iter().filter(|p| p.triangle == 1).count() as f64;
        // Binomial with p = 0.75: standard deviation sqrt(40000 * 0.75 * 0.25) ~ 87.
        assert!((on_large - 30_000.0).abs() < 5.0 * 87.0, "{on_large}");
        let receivers = Receivers::at_points(&scene, &points[..10]);
        for (p, point) in receivers.positions.iter().zip(&points) {
            let c = scene.triangles[point.triangle as usize];
            let b = point.barycentrics;
            let expected = scene.positions[c[0] as usize] * b[0]
                + scene.positions[c[1] as usize] * b[1]
                + scene.positions[c[2] as usize] * b[2];
            assert!((*p - expected).length() < 1e-6);
        }
        assert!(receivers
            .normals
            .iter()
            .all(|n| (*n - Vec3::Z).length() < 1e-6));
    }
}
