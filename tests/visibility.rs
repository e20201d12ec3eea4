//! Visibility that must be exact: convex shapes never shadow themselves, planes never shadow
//! themselves, and closed boxes never leak.

mod common;

use glam::Vec3;
use prt_gpu::bake::gpu::{visibility_bits_and_transfer, Chunking, GpuBaker};
use prt_gpu::bake::{bake, Backend, BakeOptions, DirectInputs, Mode, NoProgress};
use prt_gpu::bvh::Bvh;
use prt_gpu::ray::{Ray, RAY_T_MAX};
use prt_gpu::sampling::{DirectionFrame, Estimator, Pcg32, SampleSet};
use prt_gpu::scene::{builtin, prepare::prepare, Scene};
use prt_gpu::sh::rotation::EulerShRotation;
use prt_gpu::sh::ShTable;

fn bake_both(scene: Scene, backend: &dyn Backend) -> (Vec<f32>, Vec<f32>, u64) {
    let options = BakeOptions {
        bands: 3,
        samples: 256,
        ..BakeOptions::default()
    };
    let shadowed = bake(scene.clone(), &options, backend, &NoProgress).unwrap();
    let unshadowed = bake(
        scene,
        &BakeOptions {
            mode: Mode::Unshadowed,
            ..options
        },
        backend,
        &NoProgress,
    )
    .unwrap();
    (
        shadowed.0.transfer.coeffs().to_vec(),
        unshadowed.0.transfer.coeffs().to_vec(),
        shadowed.1.rays_cast,
    )
}

fn assert_no_ray_hits(scene: Scene, what: &str) {
    for backend in common::backends() {
        let (shadowed, unshadowed, rays) = bake_both(scene.clone(), backend.as_ref());
        assert!(rays > 0);
        // Any blocked ray would drop a positive cosine term from the sum: exact equality means
        // not a single ray hit.
        let differing = shadowed
            .iter()
            .zip(&unshadowed)
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(
            differing,
            0,
            "{what} ({}): {differing} coefficients differ ({rays} rays)",
            backend.describe()
        );
    }
}

#[test]
fn convex_sphere_never_shadows_itself_at_any_scale() {
    for scale in [1e-3f32, 1e-1, 1.0, 1e2, 1e4] {
        let sphere = builtin::icosphere(Vec3::ZERO, scale, 4);
        assert_no_ray_hits(sphere, &format!("sphere of radius {scale}"));
    }
}

#[test]
fn convex_sphere_far_from_the_origin_never_shadows_itself() {
    for center in [Vec3::new(1e3, 0.0, 0.0), Vec3::new(-700.0, 500.0, 400.0)] {
        let sphere = builtin::icosphere(center, 1.0, 4);
        assert_no_ray_hits(sphere, &format!("unit sphere at {center}"));
    }
}

#[test]
fn flat_plane_does_not_shadow_itself() {
    for (center, size) in [(Vec3::ZERO, 1.0f32), (Vec3::new(250.0, -30.0, 1e3), 40.0)] {
        let plane = builtin::grid_plane(
            center,
            Vec3::new(size, 0.0, 0.0),
            Vec3::new(0.0, 0.2 * size, -size),
            24,
            Vec3::splat(0.5),
        );
        assert_no_ray_hits(plane, &format!("plane at {center}"));
    }
}

#[test]
fn coplanar_overlapping_planes_do_not_shadow_each_other() {
    // Two tessellations of one tilted plane: every vertex of one lies inside a triangle of the
    // other, where rounding puts the surface a few ulps above or below it. Only a robust
    // origin offset keeps those triangles from shadowing the vertex.
    for (center, size) in [
        (Vec3::new(0.3, 0.1, -0.2), 1.0f32),
        (Vec3::new(-600.0, 80.0, 300.0), 25.0),
    ] {
        let u = Vec3::new(size, 0.13 * size, 0.0);
        let v = Vec3::new(0.0, 0.29 * size, -size);
        let a = builtin::grid_plane(center, u, v, 24, Vec3::splat(0.5));
        let b = builtin::grid_plane(center, u, v, 17, Vec3::splat(0.5));
        assert_no_ray_hits(
            builtin::merge(&[a, b]),
            &format!("coplanar planes at {center}"),
        );
    }
}

fn closed_box_bvh(min: Vec3, max: Vec3, cells: u32) -> (Bvh, Vec<Vec3>) {
    let (scene, _) = prepare(builtin::closed_box(min, max, cells)).unwrap();
    let bvh = Bvh::build(&scene.positions, &scene.triangles);
    (bvh, scene.positions)
}

#[test]
fn rays_from_inside_a_closed_box_never_escape() {
    let (min, max) = (Vec3::new(-1.0, -0.5, -2.0), Vec3::new(3.0, 1.5, 0.5));
    let (bvh, _) = closed_box_bvh(min, max, 7);
    let mut rng = Pcg32::new(2024);
    let mut escapes = 0;
    let rays = 1_000_000;
    for _ in 0..rays {
        let t = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let origin = min + (max - min) * (0.001 + 0.998 * t);
        let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let Some(direction) = d.try_normalize() else {
            continue;
        };
        if !bvh.occluded(&Ray::new(origin, direction), RAY_T_MAX) {
            escapes += 1;
        }
    }
    assert_eq!(
        escapes, 0,
        "{escapes} of {rays} random rays escaped the box"
    );

    // The GPU: 1000 interior origins, each casting the same 1024 random directions (two
    // "vertices" per origin with opposite normals, so each direction is cast once): a million rays.
    let Some(baker) = common::gpu_baker() else {
        return;
    };
    let origins: Vec<Vec3> = (0..1000)
        .map(|_| {
            let t = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            min + (max - min) * (0.001 + 0.998 * t)
        })
        .collect();
    let directions: Vec<Vec3> = (0..1024)
        .map(|_| {
            (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0)
                .normalize_or(Vec3::Y)
        })
        .collect();
    let (escaped, cast) = gpu_escapes(baker, &bvh, &origins, directions);
    assert!(cast >= 1_000_000, "only {cast} rays cast");
    assert_eq!(
        escaped, 0,
        "GPU: {escaped} of {cast} random rays escaped the box"
    );
}

#[test]
fn a_closed_room_with_smooth_corners_bakes_no_light_at_any_vertex() {
    // A box seen from inside, its normals computed (angle-weighted, no crease split): a
    // corner's normal runs along the diagonal, and its tangent plane cuts through the walls.
    // Its vertices' rays must still start inside the room (receivers::vertex_ray_starts keeps
    // the origin in front of every face); before, 6 of the 8 corners saw a third of the sky.
    for cells in [1, 2, 5] {
        let room = builtin::seen_from_inside(builtin::closed_box(-Vec3::ONE, Vec3::ONE, cells));
        for backend in common::backends() {
            let options = BakeOptions {
                bands: 2,
                samples: 1024,
                ..BakeOptions::default()
            };
            let (baked, report) =
                bake(room.clone(), &options, backend.as_ref(), &NoProgress).unwrap();
            assert!(report.rays_cast > 0);
            let lit = baked
                .transfer
                .coeffs()
                .chunks(baked.transfer.coeffs_per_channel() * 3)
                .filter(|vertex| vertex.iter().any(|&t| t != 0.0))
                .count();
            assert_eq!(
                lit,
                0,
                "{cells} cells, {}: {lit} vertices lit",
                backend.describe()
            );
        }
    }
}

/// Rays from every origin along every direction on the GPU: (escaped, cast).
fn gpu_escapes(baker: &GpuBaker, bvh: &Bvh, origins: &[Vec3], directions: Vec<Vec3>) -> (u64, u64) {
    // Each origin twice, with normals +X and -X, so every direction is above one horizon.
    let doubled: Vec<Vec3> = origins.iter().flat_map(|&o| [o, o]).collect();
    let normals: Vec<Vec3> = origins
        .iter()
        .flat_map(|_| [Vec3::X, Vec3::NEG_X])
        .collect();
    let cast = directions.iter().filter(|d| d.x != 0.0).count() as u64 * origins.len() as u64;
    let weight = 4.0 * std::f64::consts::PI / directions.len() as f64;
    let samples = SampleSet::new(directions, weight, DirectionFrame::World);
    let table = ShTable::new(1, &samples.directions);
    let inputs = DirectInputs {
        origins: &doubled,
        normals: &normals,
        triangles: &[],
        vertex_normals: &[],
        bvh,
        samples: &samples,
        table: &table,
        estimator: Estimator::Visible,
        tangent_to_world: &EulerShRotation::new(1),
        turns: None,
    };
    let (bits, _) =
        visibility_bits_and_transfer(baker, &inputs, Mode::Shadowed, Chunking::default()).unwrap();
    let escaped = bits.iter().map(|w| w.count_ones() as u64).sum();
    (escaped, cast)
}

#[test]
fn rays_aimed_at_shared_edges_and_corners_never_escape() {
    let (min, max) = (Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0));
    let (bvh, vertices) = closed_box_bvh(min, max, 5);
    // Targets: every mesh vertex (corners of triangles) and points on the grid lines, which
    // are edges shared by two triangles; plus the diagonals of each cell (also shared edges).
    let mut targets = vertices.clone();
    let mut rng = Pcg32::new(7);
    for _ in 0..20_000 {
        let a = vertices[(rng.next_u32() as usize) % vertices.len()];
        let b = vertices[(rng.next_u32() as usize) % vertices.len()];
        // Points between two grid vertices on the same face line lie on a shared edge only when
        // the segment is an edge; keep those sharing two coordinates (grid lines).
        let same = (a - b).abs().cmplt(Vec3::splat(1e-6));
        if same.bitmask().count_ones() == 2 {
            targets.push(a + (b - a) * rng.next_f32());
        }
    }
    let origins_per_target = 1_000_000usize.div_ceil(targets.len());
    let mut escapes = 0;
    let mut rays = 0;
    for &target in &targets {
        for _ in 0..origins_per_target {
            let t = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let origin = min + (max - min) * (0.01 + 0.98 * t);
            let Some(direction) = (target - origin).try_normalize() else {
                continue;
            };
            rays += 1;
            if !bvh.occluded(&Ray::new(origin, direction), RAY_T_MAX) {
                escapes += 1;
            }
        }
    }
    assert!(rays >= 1_000_000, "only {rays} rays");
    assert_eq!(escapes, 0, "{escapes} of {rays} edge-aimed rays escaped");

    // The GPU shares one direction set among the vertices of a bake, so aim from one origin
    // at a time, every target from each origin.
    let Some(baker) = common::gpu_baker() else {
        return;
    };
    let (mut escaped, mut cast) = (0, 0);
    for _ in 0..1_000_000usize.div_ceil(targets.len()) {
        let t = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let origin = min + (max - min) * (0.01 + 0.98 * t);
        let directions = targets.iter().map(|&p| (p - origin).normalize()).collect();
        let (e, c) = gpu_escapes(baker, &bvh, &[origin], directions);
        escaped += e;
        cast += c;
    }
    assert!(cast >= 999_000, "only {cast} rays cast");
    assert_eq!(
        escaped, 0,
        "GPU: {escaped} of {cast} edge-aimed rays escaped"
    );
}
