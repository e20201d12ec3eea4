//! Local lights against an independent oracle: Mitsuba 3's path tracer (src/testing/oracle.rs)
//! renders the same prepared scene — positions, the baker's own shading normals, per-vertex
//! albedo — under the same point or spot light, and its exit radiance at the vertices is the
//! truth the bake's direct light, its bounces and the relit file are held to.
//!
//! Which vertices are compared: `oracle::measurable_vertices` (geometry alone, nothing of the
//! baker's): a vertex whose normal is within 10 degrees of every face around it, and which
//! touches no other part of the scene. A vertex on a room's edge has a normal bent 45 degrees
//! off both walls (the boxes share their corners, so normals are averaged across the edge),
//! and one on the line where a cabinet meets a wall is half hidden: the radiance there is no
//! one value, and the path tracer's query lands on one face of it.
//!
//! Tolerances: a point light's direct term has no noise on either side (the oracle's paths
//! all see the same light), so shadow-ray direct light is held to the issue's 2% outright.
//! Bounced light has the oracle's standard error (reported per point, combined over the
//! points as an RMS) beside the baker's error; the bound is on the baker's share,
//! `sqrt(rms^2 - noise^2)`, since independent errors add in quadrature.

mod common;

use std::sync::OnceLock;

use glam::Vec3;
use prt_gpu::bake::{Backend, NoProgress};
use prt_gpu::local::depth::{visibility, DepthLookup, DirectionGrid};
use prt_gpu::local::lights::{direct_radiance, LocalLight, Spot};
use prt_gpu::local::operator::sparse_indirect;
use prt_gpu::local::{self, LocalBake, LocalInputs, LocalOptions, Relighter, Shadows};
use prt_gpu::scene::prepare::prepare;
use prt_gpu::scene::{builtin, Scene};
use prt_gpu::testing::oracle::{self, OracleLight, OracleRadiance, SurfacePoint};

/// Paths per vertex for bounced light: the oracle's noise is then 1.5–3% of the radiance (the
/// bound is on what lies beyond it).
const ORACLE_PATHS: u32 = 512;
/// The bounds asserted, on the baker's share of the RMS error: the issue's 2% for direct light
/// (shadow rays: at most 0.5% measured) and 3% for bounced light through the sparse operator
/// (at most 2.9% measured, a light 0.4 m from the ball). Measured ceilings where the issue's
/// bound is not met, asserted so that a regression fails (docs/accuracy.md has every figure):
/// the compressed operator with point lights (3.4%), and a spot light, whose cone lights a
/// bright patch with a hard edge that the per-vertex gather interpolates (4.0% sparse, 5.3%
/// compressed).
const DIRECT_BOUND: f64 = 0.02;
const SPARSE_BOUND: f64 = 0.03;
const COMPRESSED_BOUND: f64 = 0.035;
const SPOT_SPARSE_BOUND: f64 = 0.045;
const SPOT_COMPRESSED_BOUND: f64 = 0.055;

/// A bake of a scene for local lights (two bounces, the CLI's other defaults), and the
/// vertices the oracle is compared at.
struct Case {
    bake: LocalBake,
    measured: Vec<usize>,
    points: Vec<SurfacePoint>,
}

fn bake_case(scene: Scene) -> Case {
    let (scene, _) = prepare(scene).unwrap();
    let options = LocalOptions {
        bounces: 2,
        ..LocalOptions::default()
    };
    let (bake, _) = local::bake_prepared(scene, &options, &Backend::Cpu, &NoProgress).unwrap();
    let keep = oracle::measurable_vertices(&bake.scene, 10.0);
    let measured: Vec<usize> = (0..keep.len()).filter(|&v| keep[v]).collect();
    let all = oracle::vertex_points(&bake.scene);
    assert_eq!(all.len(), bake.scene.positions.len());
    let points = measured.iter().map(|&v| all[v]).collect();
    println!(
        "{} of {} vertices measured",
        measured.len(),
        bake.scene.positions.len()
    );
    Case {
        bake,
        measured,
        points,
    }
}

fn interior() -> &'static Case {
    static CASE: OnceLock<Case> = OnceLock::new();
    CASE.get_or_init(|| bake_case(builtin::interior_scene()))
}

/// A second interior, not the built-in one: a closed 6 x 3 x 4 m room split by a partition
/// with a doorway, a table in the left room and a cabinet in the right one.
fn two_rooms() -> Scene {
    let part = |min: [f32; 3], max: [f32; 3], cells: u32, albedo: Vec3| {
        let mut part = builtin::closed_box(Vec3::from(min), Vec3::from(max), cells);
        part.albedo.fill(albedo);
        part
    };
    let walls = Vec3::new(0.75, 0.75, 0.7);
    let wood = Vec3::new(0.6, 0.45, 0.3);
    let mut parts = vec![builtin::seen_from_inside(part(
        [-3.0, 0.0, -2.0],
        [3.0, 3.0, 2.0],
        40,
        walls,
    ))];
    parts.push(part([0.5, 0.0, -2.0], [0.75, 3.0, -1.5], 4, walls));
    parts.push(part([0.5, 0.0, -0.5], [0.75, 3.0, 2.0], 12, walls));
    parts.push(part([0.5, 2.0, -1.5], [0.75, 3.0, -0.5], 4, walls));
    parts.push(part([-2.25, 0.6875, -0.5], [-0.75, 0.75, 0.75], 8, wood));
    for (x, z) in [
        (-2.25, -0.5),
        (-0.875, -0.5),
        (-2.25, 0.625),
        (-0.875, 0.625),
    ] {
        parts.push(part([x, 0.0, z], [x + 0.125, 0.6875, z + 0.125], 2, wood));
    }
    parts.push(part(
        [2.25, 0.0, 1.0],
        [3.0, 1.75, 2.0],
        6,
        Vec3::new(0.3, 0.35, 0.7),
    ));
    builtin::merge(&parts)
}

fn second_interior() -> &'static Case {
    static CASE: OnceLock<Case> = OnceLock::new();
    CASE.get_or_init(|| bake_case(two_rooms()))
}

fn pick<T: Copy>(values: &[T], at: &[usize]) -> Vec<T> {
    at.iter().map(|&i| values[i]).collect()
}

fn add(a: &[Vec3], b: &[Vec3]) -> Vec<Vec3> {
    a.iter().zip(b).map(|(x, y)| *x + *y).collect()
}

/// The baker's share of an RMS error beside the oracle's noise (independent errors add in
/// quadrature).
fn beyond_noise(rms: f64, noise: f64) -> f64 {
    (rms * rms - noise * noise).max(0.0).sqrt()
}

fn oracle_light(light: &LocalLight) -> OracleLight {
    match light.spot {
        None => OracleLight::Point {
            position: light.position,
            intensity: light.intensity,
        },
        Some(spot) => OracleLight::Spot {
            position: light.position,
            direction: spot.direction,
            half_angle_degrees: spot.cos_half_angle.acos().to_degrees(),
            intensity: light.intensity,
        },
    }
}

fn spot(position: [f32; 3], towards: [f32; 3], degrees: f32, intensity: f32) -> LocalLight {
    LocalLight {
        position: Vec3::from(position),
        intensity,
        spot: Some(Spot {
            direction: Vec3::from(towards).normalize(),
            cos_half_angle: degrees.to_radians().cos(),
        }),
    }
}

/// The oracle at the case's measured vertices after `bounces` bounces.
fn truth(case: &Case, light: &LocalLight, bounces: u32) -> Option<OracleRadiance> {
    let paths = if bounces == 0 { 1 } else { ORACLE_PATHS };
    oracle::path_trace(
        &case.bake.scene,
        &case.points,
        &oracle_light(light),
        bounces,
        paths,
    )
}

/// Direct light, one and two bounces, sparse and compressed, against the path tracer for
/// each light: the assertions of the issue, and every figure printed. Light positions have
/// four decimals of no pattern: positions on the scene's lattice of binary fractions and
/// tenths (1.9, 2.6, -1.1 was one) line up exactly with a part's edge and a vertex, and the
/// shadow ray of that vertex grazes the edge, where either answer is right within rounding.
fn check_against_the_path_tracer(name: &str, case: &Case, lights: &[LocalLight]) {
    let bake = &case.bake;
    let exact = Relighter::new(bake);
    let everywhere = vec![true; case.points.len()];
    let mut failures = Vec::new();
    for light in lights {
        let Some(direct_truth) = truth(case, light, 0) else {
            return;
        };
        let one_truth = truth(case, light, 1).unwrap();
        let two_truth = truth(case, light, 2).unwrap();
        let frame = exact.frame(&[*light], local::OperatorForm::Sparse);
        let one = sparse_indirect(&bake.matrix, &bake.scene.albedo, 1, &frame.direct);
        let compressed = bake.operator.indirect(&frame.irradiance);
        let measured = |values: &[Vec3]| pick(values, &case.measured);
        let direct = measured(&frame.direct);
        let (direct_error, _) = oracle::relative_rms(&direct, &direct_truth, &everywhere);
        let (one_error, one_noise) =
            oracle::relative_rms(&add(&direct, &measured(&one)), &one_truth, &everywhere);
        let (sparse_error, noise) = oracle::relative_rms(
            &add(&direct, &measured(&frame.indirect)),
            &two_truth,
            &everywhere,
        );
        let (compressed_error, _) = oracle::relative_rms(
            &add(&direct, &measured(&compressed)),
            &two_truth,
            &everywhere,
        );
        println!(
            "{name}, {}: direct {:.2}%; 1 bounce {:.2}% (oracle noise {:.2}%); 2 bounces \
             sparse {:.2}%, compressed {:.2}% (oracle noise {:.2}%; beyond it {:.2}%, {:.2}%); \
             oracle {}, {:.1} s",
            local::lights::describe(&[*light]),
            100.0 * direct_error,
            100.0 * one_error,
            100.0 * one_noise,
            100.0 * sparse_error,
            100.0 * compressed_error,
            100.0 * noise,
            100.0 * beyond_noise(sparse_error, noise),
            100.0 * beyond_noise(compressed_error, noise),
            two_truth.variant,
            two_truth.seconds,
        );
        let light_name = local::lights::describe(&[*light]);
        for (what, error, noise) in [
            ("direct light, shadow rays", direct_error, 0.0),
            ("1 bounce, sparse", one_error, one_noise),
            ("2 bounces, sparse", sparse_error, noise),
            ("2 bounces, compressed", compressed_error, noise),
        ] {
            // One row of docs/accuracy.md (ci/accuracy.sh collects them).
            println!(
                "accuracy-row | local lights, {name}, {light_name}: {what} | {:.2}% | {:.2}% | \
                 beyond the noise {:.2}% |",
                100.0 * error,
                100.0 * noise,
                100.0 * beyond_noise(error, noise),
            );
        }
        let (sparse_bound, compressed_bound) = match light.spot {
            None => (SPARSE_BOUND, COMPRESSED_BOUND),
            Some(_) => (SPOT_SPARSE_BOUND, SPOT_COMPRESSED_BOUND),
        };
        if direct_error > DIRECT_BOUND {
            failures.push(format!("direct {direct_error:.4} at {}", light.position));
        }
        for (what, error, noise, bound) in [
            ("1 bounce", one_error, one_noise, sparse_bound),
            ("2 bounces sparse", sparse_error, noise, sparse_bound),
            (
                "2 bounces compressed",
                compressed_error,
                noise,
                compressed_bound,
            ),
        ] {
            if beyond_noise(error, noise) > bound {
                failures.push(format!(
                    "{what} {error:.4} (noise {noise:.4}) at {}",
                    light.position
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{name}: {failures:?}");
}

#[test]
fn local_lights_match_the_path_tracer_in_the_built_in_interior() {
    let lights = [
        // Over the table; beside the ball, low.
        LocalLight::point(Vec3::new(-1.5313, 1.4689, 0.1127), 5.0),
        LocalLight::point(Vec3::new(-0.4719, 0.4283, -0.4137), 2.0),
        // The second room: its light reaches the first only by bounces through the door.
        LocalLight::point(Vec3::new(1.6091, 1.2317, 1.0283), 5.0),
        spot([-2.3071, 2.1939, -0.3023], [0.4, -1.0, 0.2], 35.0, 8.0),
    ];
    check_against_the_path_tracer("built-in interior", interior(), &lights);
}

#[test]
fn local_lights_match_the_path_tracer_in_a_second_two_room_interior() {
    let lights = [
        LocalLight::point(Vec3::new(-1.3717, 1.8293, 0.2911), 5.0),
        // Under the table.
        LocalLight::point(Vec3::new(-1.4329, 0.4087, 0.0713), 2.0),
        // The right room, beside its cabinet.
        LocalLight::point(Vec3::new(1.8617, 1.5791, 0.4423), 5.0),
        spot([1.9087, 2.6013, -1.1041], [-0.3, -1.0, 0.4], 40.0, 8.0),
    ];
    check_against_the_path_tracer("two rooms", second_interior(), &lights);
}

/// The depth maps' direct light converges to the path tracer's as their grid grows (here the
/// uncompressed maps, every direction kept), and the compressed maps the bake stores stay
/// near the uncompressed maps of their grid: what `--shadows depth-maps` costs in accuracy.
#[test]
fn depth_map_shadows_converge_to_the_path_tracer_with_the_grid() {
    let case = interior();
    let bake = &case.bake;
    let lights = [
        LocalLight::point(Vec3::new(-1.5313, 1.4689, 0.1127), 5.0),
        LocalLight::point(Vec3::new(-2.1093, 0.3717, 0.2089), 2.0),
    ];
    let everywhere = vec![true; case.points.len()];
    let relighter = Relighter::with_shadows(bake, Shadows::DepthMaps);
    let receivers = relighter.receiver_frames();
    let mut inputs = LocalInputs::new(&bake.scene, &bake.options);
    for light in &lights {
        let Some(truth) = truth(case, light, 0) else {
            return;
        };
        let direct_with = |lookup: &dyn DepthLookup, grid: &DirectionGrid| {
            let irradiance: Vec<f32> = case
                .measured
                .iter()
                .map(|&p| {
                    let open =
                        light.unshadowed_irradiance(receivers.positions[p], receivers.normals[p]);
                    let seen = visibility(
                        lookup,
                        grid,
                        p,
                        &receivers.frames[p],
                        receivers.origins[p],
                        light.position,
                    );
                    open * seen
                })
                .collect();
            let albedo = pick(&bake.scene.albedo, &case.measured);
            oracle::relative_rms(&direct_radiance(&irradiance, &albedo), &truth, &everywhere).0
        };
        let mut errors = Vec::new();
        for side in [8, 16, 32] {
            let grid = DirectionGrid { side };
            let maps = local::depth_maps(&bake.scene, &mut inputs, grid, &Backend::Cpu).unwrap();
            errors.push(direct_with(&maps, &grid));
        }
        let stored = direct_with(&bake.depth, &bake.grid);
        println!(
            "{}: depth-map direct light against the path tracer, grid 8/16/32 uncompressed: \
             {:.2}% / {:.2}% / {:.2}%; the bake's compressed 16 x 16: {:.2}%",
            local::lights::describe(&[*light]),
            100.0 * errors[0],
            100.0 * errors[1],
            100.0 * errors[2],
            100.0 * stored
        );
        for (what, error) in [
            ("grid 8 x 8, uncompressed", errors[0]),
            ("grid 16 x 16, uncompressed", errors[1]),
            ("grid 32 x 32, uncompressed", errors[2]),
            ("grid 16 x 16 compressed (the bake's default)", stored),
        ] {
            println!(
                "accuracy-row | local lights, built-in interior, {}: direct light, depth maps, \
                 {what} | {:.2}% | 0 | converges with the grid (asserted) |",
                local::lights::describe(&[*light]),
                100.0 * error
            );
        }
        assert!(
            errors[0] > errors[1] && errors[1] > errors[2],
            "no convergence: {errors:?}"
        );
        // The error lives at shadow edges a cell wide: halving the cell about halves it.
        assert!(errors[2] < 0.7 * errors[0], "{errors:?}");
        assert!(stored < 1.5 * errors[1], "{stored} against {errors:?}");
    }
}

/// Reads a relit copy with numpy alone: `_RADIANCE`, `COLOR_0` and `extras.prt.relit.scale`.
const RELIT_READER: &str = r#"
import json, struct, sys
import numpy as np
data = open(sys.argv[1], "rb").read()
length = struct.unpack_from("<I", data, 12)[0]
doc = json.loads(data[20:20 + length])
bin_start = 20 + length + 8
def attribute(name):
    accessor = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"][name]]
    view = doc["bufferViews"][accessor["bufferView"]]
    start = bin_start + view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    return np.frombuffer(data, "<f4", accessor["count"] * 3, start).reshape(-1, 3)
print(json.dumps({
    "radiance": attribute("_RADIANCE").tolist(),
    "color": attribute("COLOR_0").tolist(),
    "scale": doc["meshes"][0]["extras"]["prt"]["relit"]["scale"],
}))
"#;

/// What a user does: `bake --mode local`, `render --point-light ... -o relit.glb`, and the
/// relit file's radiance read back by numpy, against the path tracer. Its `_RADIANCE` is the
/// radiance; `COLOR_0` is that over the stated scale (a scale above 1 here, so reading
/// `COLOR_0` alone is off by it, as a user once was).
#[test]
fn a_relit_file_holds_radiance_that_matches_the_path_tracer() {
    if !oracle::available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| {
        let out = common::prt_gpu(args, dir.path());
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    run(&[
        "bake",
        "--mode",
        "local",
        "--bounces",
        "2",
        "--device",
        "cpu",
        "-o",
        "room.glb",
    ]);
    let said = run(&[
        "render",
        "room.glb",
        "--point-light=-1.5313,1.4689,0.1127,5",
        "--operator",
        "sparse",
        "-o",
        "relit.glb",
    ]);
    assert!(said.contains("_RADIANCE = exit radiance"), "{said}");
    let relit = dir.path().join("relit.glb");
    if let Some(report) = common::validate_gltf(&relit) {
        assert_eq!(report.num_errors, 0, "{report:?}");
    }
    let read = prt_gpu::testing::python_json(RELIT_READER, &relit);
    let as_vec3s = |key: &str| -> Vec<Vec3> {
        read[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| {
                let c: Vec<f32> = c
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_f64().unwrap() as f32)
                    .collect();
                Vec3::new(c[0], c[1], c[2])
            })
            .collect()
    };
    let (radiance, color) = (as_vec3s("radiance"), as_vec3s("color"));
    let scale = read["scale"].as_f64().unwrap() as f32;
    assert!(scale > 1.0, "{scale}");
    for (r, c) in radiance.iter().zip(&color) {
        assert!((r.max(Vec3::ZERO) / scale - *c).abs().max_element() < 1e-6);
    }
    let bake = prt_gpu::glb::local::read_local_glb(&dir.path().join("room.glb")).unwrap();
    let keep = oracle::measurable_vertices(&bake.scene, 10.0);
    let measured: Vec<usize> = (0..keep.len()).filter(|&v| keep[v]).collect();
    let points = pick(&oracle::vertex_points(&bake.scene), &measured);
    let light = OracleLight::Point {
        position: Vec3::new(-1.5313, 1.4689, 0.1127),
        intensity: 5.0,
    };
    let truth =
        oracle::path_trace(&bake.scene, &points, &light, 2, ORACLE_PATHS).expect("available");
    let everywhere = vec![true; points.len()];
    let (error, noise) = oracle::relative_rms(&pick(&radiance, &measured), &truth, &everywhere);
    let (unscaled_colour_error, _) =
        oracle::relative_rms(&pick(&color, &measured), &truth, &everywhere);
    println!(
        "relit file: _RADIANCE {:.2}% from the path tracer (noise {:.2}%); COLOR_0 read as \
         radiance would be {:.1}% off",
        100.0 * error,
        100.0 * noise,
        100.0 * unscaled_colour_error
    );
    println!(
        "accuracy-row | local lights, relit file (bake --mode local, render -o relit.glb, read \
         by numpy), built-in interior: _RADIANCE, 2 bounces, sparse | {:.2}% | {:.2}% | \
         COLOR_0 read as radiance: {:.1}% |",
        100.0 * error,
        100.0 * noise,
        100.0 * unscaled_colour_error
    );
    assert!(beyond_noise(error, noise) < SPARSE_BOUND, "{error} {noise}");
}
