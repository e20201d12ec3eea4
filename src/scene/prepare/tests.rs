//! Tests of `prepare`.

use super::*;
use crate::scene::DEFAULT_ALBEDO;
use std::path::Path;

/// A box's corners split into one vertex per face, each with that face's normal (a room's
/// corner is not one vertex bent 45 degrees off both walls), while a tessellated ball, whose
/// facets meet at a few degrees, keeps one smooth vertex per position.
#[test]
fn creases_split_a_box_and_leave_a_ball_smooth() {
    use crate::scene::builtin;
    let cube = builtin::closed_box(Vec3::ZERO, Vec3::ONE, 1);
    let split = split_creases(&cube, 30.0);
    assert_eq!(cube.positions.len(), 8);
    assert_eq!(split.positions.len(), 24, "each corner on three faces");
    let normals = split.normals.as_deref().unwrap();
    for (t, triangle) in split.triangles.iter().enumerate() {
        let [a, b, c] = triangle.map(|i| split.positions[i as usize]);
        let face = (b - a).cross(c - a).normalize();
        for &v in triangle {
            assert!(normals[v as usize].dot(face) > 0.9999, "triangle {t}");
        }
    }
    let ball = builtin::icosphere(Vec3::ZERO, 1.0, 3);
    let smooth = split_creases(&ball, 30.0);
    let positions = |scene: &Scene| {
        let mut keys: Vec<[u32; 3]> = scene.positions.iter().map(|&p| key(p)).collect();
        keys.sort_unstable();
        keys.dedup();
        keys.len()
    };
    assert_eq!(smooth.positions.len(), positions(&ball));
    // At 180 degrees nothing is a crease: every corner of the box takes the smooth normal.
    assert_eq!(split_creases(&cube, 180.0).positions.len(), 8);
}

fn scene(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Scene {
    Scene {
        albedo: vec![DEFAULT_ALBEDO; positions.len()],
        positions,
        normals: None,
        triangles,
    }
}

fn geometry_message(result: Result<(Scene, PrepareReport)>) -> String {
    match result {
        Err(Error::Geometry(message)) => message,
        other => panic!("expected a geometry error, got {other:?}"),
    }
}

fn unit_cube() -> Scene {
    let positions = (0..8)
        .map(|i| Vec3::new((i & 1) as f32, (i >> 1 & 1) as f32, (i >> 2 & 1) as f32))
        .collect();
    // Outward winding; corners 0 and 7 are touched by two triangles on some faces and by
    // one on others, which is what makes angle weighting matter.
    let triangles = vec![
        [0, 2, 3],
        [0, 3, 1],
        [4, 5, 7],
        [4, 7, 6],
        [0, 1, 5],
        [0, 5, 4],
        [2, 6, 7],
        [2, 7, 3],
        [0, 4, 6],
        [0, 6, 2],
        [1, 3, 7],
        [1, 7, 5],
    ];
    scene(positions, triangles)
}

#[test]
fn cube_corner_normal_is_the_diagonal() {
    let cube = unit_cube();
    let normals = angle_weighted_normals(&cube.positions, &cube.triangles);
    for (p, n) in cube.positions.iter().zip(&normals) {
        let expected = (*p - Vec3::splat(0.5)).normalize();
        assert!(
            n.distance(expected) < 1e-6,
            "corner {p}: normal {n}, expected {expected}"
        );
    }
}

#[test]
fn opposite_coincident_triangles_fall_back_to_first_face() {
    let positions = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let normals = angle_weighted_normals(&positions, &[[0, 1, 2], [0, 2, 1]]);
    assert_eq!(normals, vec![Vec3::Z; 3]);
}

/// A fan of four triangles around the origin in the plane z = 0, facing +z; vertex 0 is
/// the centre, 1 to 4 the ring.
fn flat_fan() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, -Vec3::X, -Vec3::Y];
    let triangles = vec![[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]];
    (positions, triangles)
}

#[test]
fn a_sliver_folded_back_over_the_surface_does_not_tip_its_corners_normals() {
    let (mut positions, mut triangles) = flat_fan();
    // A sliver on the fan's edge 0-1, folded back over the fan (its normal within 12° of
    // -z) with a wide angle at the centre: counted, it tips the centre's normal by 8°.
    positions.push(Vec3::new(-0.866, 0.5, 0.1));
    triangles.push([0, 5, 1]);
    let (normals, folded) = normals_without_folds(&positions, &triangles);
    assert_eq!(folded, 1);
    for v in [0, 1] {
        assert!(
            normals[v].distance(Vec3::Z) < 1e-6,
            "vertex {v}: {}",
            normals[v]
        );
    }
    // The sliver's own corner has no other triangle: it keeps the sliver's normal.
    assert!(normals[5].z < -0.9);
    // Without the fold rule the centre would tilt, so the test above has teeth.
    let tipped = (DVec3::Z * std::f64::consts::TAU
        + DVec3::new(0.0, 0.196, -0.981) * 150f64.to_radians())
    .normalize();
    assert!(tipped.angle_between(DVec3::Z) > 5f64.to_radians());
}

#[test]
fn a_flap_doubled_with_both_windings_takes_the_surfaces_side_in_either_order() {
    for flap in [[[1, 2, 5], [2, 1, 5]], [[2, 1, 5], [1, 2, 5]]] {
        let (mut positions, mut triangles) = flat_fan();
        // A flap beyond the fan's edge 1-2, lying in its plane, stored twice with opposite
        // windings (as scanned meshes have them): the sum at its tip cancels, and the
        // winding that agrees with the fan across the shared edge gives the normal.
        positions.push(Vec3::new(1.0, 1.0, 0.0));
        triangles.extend(flap);
        let (normals, folded) = normals_without_folds(&positions, &triangles);
        assert_eq!(folded, 1, "{flap:?}");
        assert_eq!(normals[5], Vec3::Z, "{flap:?}");
    }
}

#[test]
fn a_knife_edge_keeps_the_bisector() {
    // Two faces meeting at 160° along the x axis, each with a neighbour on its own side:
    // sharp, but not folded, so the edge's normal stays their bisector.
    let positions = vec![
        Vec3::ZERO,
        Vec3::X,
        Vec3::new(0.5, 1.0, 0.18),
        Vec3::new(0.5, -1.0, 0.18),
        Vec3::new(1.5, 1.0, 0.18),
        Vec3::new(1.5, -1.0, 0.18),
    ];
    let triangles = vec![[0, 1, 2], [1, 4, 2], [1, 0, 3], [1, 3, 5]];
    let (normals, folded) = normals_without_folds(&positions, &triangles);
    assert_eq!(folded, 0);
    assert!(normals[0].distance(Vec3::Z) < 1e-6, "{}", normals[0]);
}

#[test]
fn unreferenced_vertex_gets_zero_normal_and_bad_indices_are_ignored() {
    let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE];
    let normals = angle_weighted_normals(&positions, &[[0, 1, 2], [0, 1, 99]]);
    assert_eq!(normals, vec![Vec3::Z, Vec3::Z, Vec3::Z, Vec3::ZERO]);
}

#[test]
fn teapot_welds_to_529_vertices() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/teapot.obj");
    let loaded = crate::scene::obj::load(&path).unwrap();
    assert_eq!(loaded.vertex_count(), 792);
    assert!(loaded.normals.is_none());
    let (prepared, report) = prepare(loaded).unwrap();
    assert_eq!(prepared.vertex_count(), 529);
    assert_eq!(report.vertices, 529);
    assert_eq!(report.input_vertices, 792);
    assert!(report.normals_computed);
    assert_eq!(
        report.vertices_welded + report.unreferenced_vertices_removed,
        792 - 529
    );
    assert_eq!(
        report.triangles + report.degenerate_triangles_removed,
        report.input_triangles
    );
    let normals = prepared.normals.as_ref().unwrap();
    assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-5));
}

#[test]
fn nan_position_is_an_error_naming_the_vertex() {
    let mut s = unit_cube();
    s.positions[5].y = f32::NAN;
    let message = geometry_message(prepare(s));
    assert!(message.contains("vertex 5"), "{message}");
    assert!(message.contains("NaN"), "{message}");
}

#[test]
fn infinite_position_is_an_error() {
    let mut s = unit_cube();
    s.positions[2].x = f32::NEG_INFINITY;
    assert!(geometry_message(prepare(s)).contains("vertex 2"));
}

#[test]
fn out_of_range_index_is_an_error_naming_the_triangle() {
    let mut s = unit_cube();
    s.triangles[3][1] = 8;
    let message = geometry_message(prepare(s));
    assert!(message.contains("triangle 3"), "{message}");
    assert!(message.contains("vertex 8"), "{message}");
}

#[test]
fn empty_meshes_are_errors() {
    let message = geometry_message(prepare(Scene::default()));
    assert!(message.contains("no vertices"), "{message}");
    let message = geometry_message(prepare(scene(vec![Vec3::ZERO; 3], vec![])));
    assert!(message.contains("no triangles"), "{message}");
}

#[test]
fn attribute_length_mismatch_is_an_error() {
    let mut s = unit_cube();
    s.albedo.pop();
    assert!(geometry_message(prepare(s)).contains("albedo"));
    let mut s = unit_cube();
    s.normals = Some(vec![Vec3::Y; 3]);
    assert!(geometry_message(prepare(s)).contains("normals"));
}

#[test]
fn degenerate_triangles_are_removed() {
    let mut s = unit_cube();
    let p = Vec3::new(0.1, 0.2, 0.3);
    // Scaling by powers of two is exact, so these three are exactly collinear; the last
    // vertex duplicates the position of vertex 1 under another index.
    s.positions.extend([p, p * 2.0, p * 4.0, Vec3::X]);
    s.albedo.extend([DEFAULT_ALBEDO; 4]);
    s.triangles.extend([[0, 0, 1], [8, 9, 10], [1, 2, 11]]);

    let (prepared, report) = prepare(s).unwrap();
    assert_eq!(report.degenerate_triangles_removed, 3);
    assert_eq!(prepared.triangle_count(), 12);
    assert_eq!(report.unreferenced_vertices_removed, 4);
    assert_eq!(prepared.vertex_count(), 8);
}

#[test]
fn nearly_collinear_f32_points_are_not_degenerate() {
    // Exactly collinear in f32 is rare; a point one ulp off the line must be kept.
    let a = Vec3::new(0.1, 0.2, 0.3);
    let b = Vec3::new(0.2, 0.4, 0.6);
    let off = Vec3::new(0.4, f32::from_bits(0.8f32.to_bits() + 1), 1.2);
    assert!(!cross_is_exactly_zero(a, b, off));
    assert!(cross_is_exactly_zero(
        Vec3::ZERO,
        Vec3::ONE,
        Vec3::splat(3.0)
    ));
    let d = Vec3::new(3.0, -5.0, 7.0);
    let tiny = f32::powi(2.0, -60);
    assert!(cross_is_exactly_zero(d * tiny, d * 0.75, d / tiny));
}

#[test]
fn all_degenerate_is_an_error() {
    let s = scene(
        vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0],
        vec![[0, 1, 2], [1, 1, 2]],
    );
    let message = geometry_message(prepare(s));
    assert_eq!(message, "all 2 triangles are degenerate");
}

#[test]
fn invalid_normals_are_recomputed_and_reported() {
    let mut s = unit_cube();
    let mut normals = vec![Vec3::Y; 8];
    normals[4] = Vec3::new(f32::NAN, 0.0, 0.0);
    s.normals = Some(normals);
    let (prepared, report) = prepare(s).unwrap();
    assert!(report.invalid_normals_replaced && report.normals_computed);
    for (p, n) in prepared.positions.iter().zip(prepared.normals.unwrap()) {
        assert!(n.distance((*p - Vec3::splat(0.5)).normalize()) < 1e-6);
    }
    assert_eq!(
        report.repairs().as_deref(),
        Some("repaired the mesh: non-finite or zero normals: all normals recomputed")
    );
    // Computing the normals a file lacks is no repair.
    let (_, report) = prepare(unit_cube()).unwrap();
    assert!(report.normals_computed && report.repairs().is_none());
}

#[test]
fn given_normals_are_normalized_and_split_vertices_kept() {
    // Two quads sharing an edge, with a hard crease: shared positions, different normals.
    let positions = vec![
        Vec3::ZERO,
        Vec3::X,
        Vec3::new(1.0, 0.0, 1.0),
        Vec3::Z,
        Vec3::ZERO,
        Vec3::X,
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::Y,
    ];
    let mut s = scene(positions, vec![[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7]]);
    s.normals = Some([vec![Vec3::Y * 3.0; 4], vec![Vec3::Z * 0.5; 4]].concat());
    let (prepared, report) = prepare(s).unwrap();
    assert!(!report.normals_computed);
    assert_eq!(report.vertices_welded, 0);
    assert_eq!(prepared.vertex_count(), 8);
    let normals = prepared.normals.unwrap();
    assert!(normals.iter().all(|&n| n == Vec3::Y || n == Vec3::Z));
}

#[test]
fn identical_vertices_with_normals_are_welded() {
    let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X, Vec3::Y, Vec3::ONE];
    let mut s = scene(positions, vec![[0, 1, 2], [3, 5, 4]]);
    s.normals = Some(vec![Vec3::Z; 6]);
    let (prepared, report) = prepare(s).unwrap();
    assert_eq!(report.vertices_welded, 2);
    assert_eq!(prepared.vertex_count(), 4);
}

#[test]
fn colour_seam_welds_apart_but_shares_the_normal() {
    // A folded strip whose two halves differ in albedo: the seam vertices are not welded,
    // but their normals must still come from both halves.
    let positions = vec![
        Vec3::ZERO,
        Vec3::X,
        Vec3::new(0.0, 1.0, -1.0),
        Vec3::ZERO,
        Vec3::X,
        Vec3::new(0.0, 1.0, 1.0),
    ];
    let mut s = scene(positions, vec![[0, 1, 2], [3, 5, 4]]);
    s.albedo[3..].fill(Vec3::new(0.2, 0.3, 0.4));
    let (prepared, report) = prepare(s).unwrap();
    assert_eq!(report.vertices_welded, 0);
    let normals = prepared.normals.unwrap();
    for (p, n) in prepared.positions.iter().zip(normals) {
        if p.y == 0.0 {
            assert!(n.distance(Vec3::Y) < 1e-6, "seam normal {n}");
        }
    }
}

#[test]
fn negative_zero_welds_with_positive_zero() {
    let positions = vec![
        Vec3::ZERO,
        Vec3::X,
        Vec3::Y,
        Vec3::new(-0.0, 0.0, -0.0),
        Vec3::Z,
    ];
    let s = scene(positions, vec![[0, 1, 2], [3, 2, 4]]);
    let (prepared, report) = prepare(s).unwrap();
    assert_eq!(report.vertices_welded, 1);
    assert_eq!(prepared.vertex_count(), 4);
}

#[test]
fn the_vertex_map_sends_every_input_vertex_to_its_prepared_twin() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/teapot.obj");
    let mut loaded = crate::scene::obj::load(&path).unwrap();
    // An unreferenced vertex and one used only by a degenerate triangle are dropped.
    loaded.positions.push(Vec3::splat(9.0));
    loaded.albedo.push(Vec3::ONE);
    let lonely = loaded.positions.len() as u32;
    loaded.positions.push(Vec3::splat(7.0));
    loaded.albedo.push(Vec3::ONE);
    loaded.triangles.push([lonely, lonely, 0]);
    if let Some(normals) = &mut loaded.normals {
        normals.extend([Vec3::Y, Vec3::Y]);
    }
    let (prepared, report, map) = prepare_mapped(loaded.clone()).unwrap();
    assert_eq!(map.len(), loaded.positions.len());
    assert_eq!(map[lonely as usize - 1], DROPPED);
    assert_eq!(map[lonely as usize], DROPPED);
    let dropped = map.iter().filter(|&&m| m == DROPPED).count();
    assert_eq!(dropped, report.unreferenced_vertices_removed);
    for (input, &to) in map.iter().enumerate() {
        if to != DROPPED {
            assert_eq!(prepared.positions[to as usize], loaded.positions[input]);
            assert_eq!(prepared.albedo[to as usize], loaded.albedo[input]);
        }
    }
    // Every input triangle that survives is the prepared triangle through the map.
    let kept: Vec<[u32; 3]> = loaded
        .triangles
        .iter()
        .filter(|t| t[0] != lonely)
        .map(|t| t.map(|i| map[i as usize]))
        .collect();
    assert_eq!(kept, prepared.triangles);
}

#[test]
fn prepared_triangles_keep_order_and_geometry() {
    let mut s = unit_cube();
    s.positions.reverse();
    for t in &mut s.triangles {
        *t = t.map(|i| 7 - i);
    }
    let original: Vec<[Vec3; 3]> = s
        .triangles
        .iter()
        .map(|t| t.map(|i| s.positions[i as usize]))
        .collect();
    let (prepared, _) = prepare(s).unwrap();
    let after: Vec<[Vec3; 3]> = prepared
        .triangles
        .iter()
        .map(|t| t.map(|i| prepared.positions[i as usize]))
        .collect();
    assert_eq!(original, after);
    // Morton order of the unit cube corners is the binary count x + 2y + 4z.
    let expected: Vec<Vec3> = unit_cube().positions;
    assert_eq!(prepared.positions, expected);
}
