//! Procedural shapes: the scene baked when no mesh is given, and known geometry for tests.
//!
//! All shapes wind their triangles counter-clockwise seen from outside (right-handed, +Y up)
//! and share vertices wherever triangles meet, so they are closed where they should be.

use std::collections::HashMap;

use glam::Vec3;

use super::prepare::{angle_weighted_normals, split_creases};
use super::{Scene, DEFAULT_ALBEDO};

/// More subdivisions than this would allocate gigabytes; 8 already gives 1.3 M triangles.
const MAX_SUBDIVISIONS: u32 = 8;

/// Grid resolutions are clamped to this, which keeps every index inside u32 and the
/// largest box at 25 M vertices.
const MAX_CELLS: u32 = 2048;

/// A sphere made by subdividing an icosahedron `subdivisions` times (clamped to 8), with
/// shared vertices and outward winding. Normals are `None`: `prepare` computes them.
/// The radius is taken as its absolute value, since a negative one would turn it inside out.
pub fn icosphere(center: Vec3, radius: f32, subdivisions: u32) -> Scene {
    let (mut directions, mut triangles) = icosahedron();
    for _ in 0..subdivisions.min(MAX_SUBDIVISIONS) {
        triangles = subdivide(&mut directions, &triangles);
    }
    let positions: Vec<Vec3> = directions
        .iter()
        .map(|d| center + *d * radius.abs())
        .collect();
    Scene {
        albedo: vec![DEFAULT_ALBEDO; positions.len()],
        positions,
        normals: None,
        triangles,
    }
}

/// Unit-length vertices and outward counter-clockwise faces of a regular icosahedron.
fn icosahedron() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5.0f32.sqrt()) / 2.0;
    let vertices = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .map(|(x, y, z)| Vec3::new(x, y, z).normalize());
    let faces = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    (vertices.to_vec(), faces)
}

/// Splits each triangle into four; edge midpoints are created once per edge (so neighbours
/// share them) and pushed out to the unit sphere.
fn subdivide(vertices: &mut Vec<Vec3>, triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
    let mut midpoint = |a: u32, b: u32| {
        *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
            let m = (vertices[a as usize] + vertices[b as usize]).normalize();
            vertices.push(m);
            vertices.len() as u32 - 1
        })
    };
    triangles
        .iter()
        .flat_map(|&[a, b, c]| {
            let (ab, bc, ca) = (midpoint(a, b), midpoint(b, c), midpoint(c, a));
            [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
        })
        .collect()
}

/// A flat grid of `cells`×`cells` quads (`cells` clamped to 1..=2048) spanning `center ± u_axis ± v_axis`.
///
/// Normals are `normalize(u_axis × v_axis)` and triangles are counter-clockwise seen from
/// that side. Parallel axes give zero normals and degenerate triangles, which `prepare`
/// rejects.
pub fn grid_plane(center: Vec3, u_axis: Vec3, v_axis: Vec3, cells: u32, albedo: Vec3) -> Scene {
    let n = cells.clamp(1, MAX_CELLS);
    let positions: Vec<Vec3> = (0..=n)
        .flat_map(|j| (0..=n).map(move |i| (i, j)))
        .map(|(i, j)| center + u_axis * signed_fraction(i, n) + v_axis * signed_fraction(j, n))
        .collect();
    let normal = u_axis.cross(v_axis).normalize_or_zero();
    let triangles = grid_triangles(n, |i, j| j * (n + 1) + i);
    Scene {
        normals: Some(vec![normal; positions.len()]),
        albedo: vec![albedo; positions.len()],
        positions,
        triangles,
    }
}

/// Maps grid line `i` of `0..=n` to [-1, 1], hitting both ends exactly.
fn signed_fraction(i: u32, n: u32) -> f32 {
    (2 * i as i64 - n as i64) as f32 / n as f32
}

/// Two triangles per cell of an n×n grid, counter-clockwise in the (i, j) plane, given the
/// vertex index of each grid point (which may create the vertex on first request).
fn grid_triangles(n: u32, mut index: impl FnMut(u32, u32) -> u32) -> Vec<[u32; 3]> {
    let mut triangles = Vec::with_capacity(2 * n as usize * n as usize);
    for j in 0..n {
        for i in 0..n {
            let (a, b) = (index(i, j), index(i + 1, j));
            let (c, d) = (index(i + 1, j + 1), index(i, j + 1));
            triangles.extend([[a, b, c], [a, c, d]]);
        }
    }
    triangles
}

/// A watertight axis-aligned box, each face split into `cells`×`cells` quads (`cells`
/// clamped to 1..=2048).
///
/// Vertices lie on an integer lattice over the box and each lattice point on the surface is
/// one vertex, so faces meeting at an edge or corner share vertices exactly. Winding is
/// outward; normals are `None`. `min` and `max` are sorted per axis first.
pub fn closed_box(min: Vec3, max: Vec3, cells: u32) -> Scene {
    let (lo, hi) = (min.min(max), min.max(max));
    let n = cells.clamp(1, MAX_CELLS);
    let mut lattice: HashMap<[u32; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for axis in 0..3 {
        for side in [0, n] {
            // (axis+1, axis+2) is a right-handed tangent pair for the +axis face; swapping it
            // flips the winding for the face on the min side.
            let (u, v) = if side == n {
                ((axis + 1) % 3, (axis + 2) % 3)
            } else {
                ((axis + 2) % 3, (axis + 1) % 3)
            };
            let mut vertex = |i: u32, j: u32| {
                let mut point = [0u32; 3];
                point[axis] = side;
                point[u] = i;
                point[v] = j;
                *lattice.entry(point).or_insert_with(|| {
                    positions.push(lattice_position(point, n, lo, hi));
                    positions.len() as u32 - 1
                })
            };
            triangles.extend(grid_triangles(n, &mut vertex));
        }
    }
    Scene {
        albedo: vec![DEFAULT_ALBEDO; positions.len()],
        positions,
        normals: None,
        triangles,
    }
}

fn lattice_position(point: [u32; 3], n: u32, lo: Vec3, hi: Vec3) -> Vec3 {
    let coordinate = |axis: usize| {
        let (i, a, b) = (point[axis], lo[axis], hi[axis]);
        // The end points are set exactly so the box spans exactly [min, max].
        match i {
            0 => a,
            i if i == n => b,
            i => a + (b - a) * (i as f32 / n as f32),
        }
    };
    Vec3::new(coordinate(0), coordinate(1), coordinate(2))
}

/// Concatenates scenes into one.
///
/// Normals: `None` if no part has them; otherwise parts without normals get angle-weighted
/// normals computed on that part alone, so a part's smoothing never reaches across into a
/// neighbouring part. A part whose attribute arrays do not match its vertex count (not
/// produced by this module) has its albedo padded or cut with [`DEFAULT_ALBEDO`] and its
/// normals computed.
pub fn merge(parts: &[Scene]) -> Scene {
    let has_normals = |part: &Scene| {
        part.normals
            .as_ref()
            .is_some_and(|n| n.len() == part.positions.len())
    };
    let keep_normals = parts.iter().any(has_normals);
    let mut merged = Scene {
        normals: keep_normals.then(Vec::new),
        ..Scene::default()
    };
    for part in parts {
        // Offsets past u32 saturate, so the indices end up out of range and `prepare`
        // reports them instead of wrapping onto other vertices.
        let offset = u32::try_from(merged.positions.len()).unwrap_or(u32::MAX);
        merged.positions.extend_from_slice(&part.positions);
        let mut albedo = part.albedo.clone();
        albedo.resize(part.positions.len(), DEFAULT_ALBEDO);
        merged.albedo.extend(albedo);
        merged.triangles.extend(
            part.triangles
                .iter()
                .map(|t| t.map(|i| i.saturating_add(offset))),
        );
        if let Some(normals) = merged.normals.as_mut() {
            match &part.normals {
                Some(own) if has_normals(part) => normals.extend_from_slice(own),
                _ => normals.extend(angle_weighted_normals(&part.positions, &part.triangles)),
            }
        }
    }
    merged
}

/// The scene baked when the user gives no mesh: a light grey ground, a red wall behind it
/// (colour bleeding onto the ground shows interreflection), a sphere and a blue box resting
/// on the ground. About 6,400 vertices.
pub fn default_scene() -> Scene {
    let ground = grid_plane(
        Vec3::ZERO,
        Vec3::new(0.0, 0.0, 2.0),
        Vec3::new(2.0, 0.0, 0.0),
        48,
        Vec3::splat(0.8),
    );
    let wall = grid_plane(
        Vec3::new(0.0, 1.25, -2.0),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.0, 1.25, 0.0),
        32,
        Vec3::new(0.8, 0.25, 0.2),
    );
    let sphere = icosphere(Vec3::new(-0.6, 0.6, -0.6), 0.6, 4);
    let mut cube = closed_box(Vec3::new(0.55, 0.0, -0.1), Vec3::new(1.25, 0.7, 0.6), 8);
    cube.albedo.fill(Vec3::new(0.3, 0.5, 0.8));
    merge(&[ground, wall, sphere, cube])
}

/// The same surface seen from the other side: every triangle's winding reversed and the
/// normals dropped (so that `merge` or `prepare` computes them facing the new way). A
/// [`closed_box`] turned inside out is a closed room.
pub fn seen_from_inside(mut scene: Scene) -> Scene {
    scene.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    scene.normals = None;
    scene
}

/// The scene baked for local lights when the user gives no mesh: two rooms 2.5 m high (7.25 m
/// by 4 m in all) split by a 25 cm wall with a doorway 1 m wide and 2 m high; a table, a red
/// cabinet and a blue ball in the first room, a green shelf in the second. Every part is
/// closed and the rooms' shell is a box seen from inside, so no ray leaves the scene (a
/// light in the second room reaches the first only through the doorway, by bounces).
/// Coordinates are binary fractions, so parts that touch share their corners exactly. Edges
/// sharper than [`HARD_EDGE_DEGREES`] are hard (`prepare::split_creases`): a room's corner
/// is not smoothed into a 45-degree normal, and a floor under a wall does not share its
/// vertices' normals with the wall's foot. About 13,000 vertices.
pub fn interior_scene() -> Scene {
    let part = |min: [f32; 3], max: [f32; 3], cells: u32, albedo: Vec3| {
        let mut part = closed_box(Vec3::from(min), Vec3::from(max), cells);
        part.albedo.fill(albedo);
        part
    };
    let walls = Vec3::new(0.8, 0.78, 0.72);
    let mut parts = vec![seen_from_inside(part(
        [-4.0, 0.0, -2.0],
        [3.25, 2.5, 2.0],
        40,
        walls,
    ))];
    // The wall between the rooms: beside the doorway, and the lintel above it.
    parts.push(part([0.0, 0.0, -2.0], [0.25, 2.5, -0.5], 8, walls));
    parts.push(part([0.0, 0.0, 0.5], [0.25, 2.5, 2.0], 8, walls));
    parts.push(part([0.0, 2.0, -0.5], [0.25, 2.5, 0.5], 4, walls));
    let wood = Vec3::new(0.55, 0.4, 0.25);
    parts.push(part([-2.75, 0.6875, -0.75], [-1.25, 0.8125, 0.75], 8, wood));
    for (x, z) in [
        (-2.75, -0.75),
        (-1.375, -0.75),
        (-2.75, 0.625),
        (-1.375, 0.625),
    ] {
        parts.push(part([x, 0.0, z], [x + 0.125, 0.6875, z + 0.125], 2, wood));
    }
    parts.push(part(
        [-4.0, 0.0, 1.25],
        [-3.25, 1.5, 2.0],
        6,
        Vec3::new(0.7, 0.15, 0.1),
    ));
    parts.push(part(
        [2.75, 0.0, -1.5],
        [3.25, 2.0, 0.0],
        6,
        Vec3::new(0.2, 0.6, 0.25),
    ));
    let mut ball = icosphere(Vec3::new(-0.875, 0.375, -1.25), 0.375, 3);
    ball.albedo.fill(Vec3::new(0.15, 0.3, 0.75));
    parts.push(ball);
    split_creases(&merge(&parts), HARD_EDGE_DEGREES)
}

/// The crease angle of the built-in interior, Blender's auto-smooth default: the ball's facets,
/// about 8 degrees apart, stay smooth.
pub const HARD_EDGE_DEGREES: f64 = 30.0;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::prepare::prepare;

    /// Every undirected edge used by exactly two triangles, once in each direction: closed
    /// and consistently oriented.
    fn assert_closed_and_oriented(triangles: &[[u32; 3]]) {
        let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
        for &[a, b, c] in triangles {
            for edge in [(a, b), (b, c), (c, a)] {
                *directed.entry(edge).or_default() += 1;
            }
        }
        for (&(a, b), &count) in &directed {
            assert_eq!(
                count, 1,
                "edge {a}->{b} used {count} times in one direction"
            );
            assert_eq!(
                directed.get(&(b, a)),
                Some(&1),
                "edge {a}-{b} is not shared by exactly two triangles"
            );
        }
    }

    fn face_normal(scene: &Scene, t: &[u32; 3]) -> Vec3 {
        let [a, b, c] = t.map(|i| scene.positions[i as usize]);
        (b - a).cross(c - a)
    }

    #[test]
    fn icosphere_is_closed_with_radial_normals() {
        // Angle-weighted normals converge only linearly on the icosphere's uneven triangles
        // (worst error 2.6e-3 at 4 subdivisions, halving with each one); 6 is the first level
        // within 1e-3.
        let center = Vec3::new(1.0, -2.0, 0.5);
        let sphere = icosphere(center, 2.0, 6);
        assert_eq!(sphere.vertex_count(), 10 * 4usize.pow(6) + 2);
        assert_eq!(sphere.triangle_count(), 20 * 4usize.pow(6));
        assert_closed_and_oriented(&sphere.triangles);
        for t in &sphere.triangles {
            let centroid = t
                .iter()
                .map(|&i| sphere.positions[i as usize])
                .sum::<Vec3>()
                / 3.0;
            assert!(face_normal(&sphere, t).dot(centroid - center) > 0.0);
        }

        let (prepared, report) = prepare(sphere).unwrap();
        assert_eq!(report.degenerate_triangles_removed, 0);
        assert_eq!(report.vertices_welded, 0);
        assert_closed_and_oriented(&prepared.triangles);
        for (p, n) in prepared.positions.iter().zip(prepared.normals.unwrap()) {
            assert!(((*p - center).length() - 2.0).abs() < 1e-5);
            let radial = (*p - center).normalize();
            assert!(n.distance(radial) < 1e-3, "normal {n} vs radial {radial}");
        }
    }

    #[test]
    fn icosphere_subdivisions_are_clamped() {
        assert_eq!(icosphere(Vec3::ZERO, 1.0, 0).triangle_count(), 20);
        let huge = icosphere(Vec3::ZERO, -1.0, u32::MAX);
        assert_eq!(huge.triangle_count(), 20 * 4usize.pow(MAX_SUBDIVISIONS));
        // A negative radius is taken as positive rather than turning the sphere inside out.
        let top = huge.positions.iter().map(|p| p.y).fold(f32::MIN, f32::max);
        assert!((top - 1.0).abs() < 1e-3);
        let t = huge.triangles[0].map(|i| huge.positions[i as usize]);
        assert!((t[1] - t[0]).cross(t[2] - t[0]).dot(t[0]) > 0.0);
    }

    #[test]
    fn closed_box_is_watertight_with_shared_vertices() {
        let (min, max) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(0.5, 0.25, 3.0));
        let cube = closed_box(max, min, 5);
        let n = 5usize;
        assert_eq!(cube.vertex_count(), 6 * (n + 1).pow(2) - 12 * (n + 1) + 8);
        assert_eq!(cube.triangle_count(), 6 * 2 * n * n);
        assert_closed_and_oriented(&cube.triangles);
        let center = (min + max) / 2.0;
        let mut distinct: Vec<[u32; 3]> = cube
            .positions
            .iter()
            .map(|p| p.to_array().map(f32::to_bits))
            .collect();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct.len(), cube.vertex_count());
        for p in &cube.positions {
            assert!(p.cmpge(min).all() && p.cmple(max).all());
        }
        for t in &cube.triangles {
            let centroid = t.iter().map(|&i| cube.positions[i as usize]).sum::<Vec3>() / 3.0;
            assert!(face_normal(&cube, t).dot(centroid - center) > 0.0);
        }
        let (prepared, report) = prepare(cube).unwrap();
        assert_eq!(
            report.vertices_welded + report.degenerate_triangles_removed,
            0
        );
        assert_closed_and_oriented(&prepared.triangles);
    }

    #[test]
    fn grid_plane_faces_its_normal() {
        let plane = grid_plane(
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 3.0),
            Vec3::new(1.5, 0.0, 0.0),
            4,
            Vec3::new(0.1, 0.2, 0.3),
        );
        assert_eq!(plane.vertex_count(), 25);
        assert_eq!(plane.triangle_count(), 32);
        let normals = plane.normals.as_ref().unwrap();
        assert!(normals.iter().all(|&n| n == Vec3::Y));
        for t in &plane.triangles {
            assert!(face_normal(&plane, t).normalize().distance(Vec3::Y) < 1e-6);
        }
        let corners = [plane.positions[0], plane.positions[24]];
        assert_eq!(
            corners,
            [Vec3::new(-1.5, 1.0, -3.0), Vec3::new(1.5, 1.0, 3.0)]
        );
        assert!(plane.albedo.iter().all(|&a| a == Vec3::new(0.1, 0.2, 0.3)));
    }

    #[test]
    fn merge_offsets_indices_and_fills_missing_normals() {
        let plane = grid_plane(Vec3::ZERO, Vec3::X, Vec3::Z * -1.0, 1, Vec3::ONE);
        let cube = closed_box(Vec3::ZERO, Vec3::ONE, 1);
        let merged = merge(&[plane.clone(), cube.clone()]);
        assert_eq!(merged.vertex_count(), 4 + 8);
        assert_eq!(merged.triangles[2], cube.triangles[0].map(|i| i + 4));
        let normals = merged.normals.unwrap();
        assert_eq!(normals[..4], [Vec3::Y; 4]);
        for (p, n) in cube.positions.iter().zip(&normals[4..]) {
            assert!(n.distance((*p - Vec3::splat(0.5)).normalize()) < 1e-6);
        }
        assert!(merge(&[cube.clone(), cube]).normals.is_none());
    }

    #[test]
    fn default_scene_prepares_cleanly() {
        let scene = default_scene();
        let (prepared, report) = prepare(scene).unwrap();
        assert!(!report.normals_computed);
        assert_eq!(report.degenerate_triangles_removed, 0);
        assert!(prepared.vertex_count() < 10_000, "{report:?}");
        let lowest = prepared
            .positions
            .iter()
            .map(|p| p.y)
            .fold(f32::MAX, f32::min);
        assert_eq!(lowest, 0.0);
        // The wall's albedo is present, so colour bleeding has a source.
        assert!(prepared.albedo.contains(&Vec3::new(0.8, 0.25, 0.2)));
    }
}
