//! The GPU backend against the CPU reference, ray for ray and coefficient for coefficient.
//!
//! Tolerance, from first principles: both backends read the same origins, directions and SH
//! table. A ray whose visibility differs changes coefficient k of its vertex by at most
//! `(w/pi) max_s |cos_s y_k(s)|`; the rest is rounding, and the GPU's f32 sum over a vertex's
//! samples (per 32-sample word, then over words) errs by at most
//! `gamma(32 + words + 4) (w/pi) sum_s |cos_s y_k(s)|`.

mod common;

use std::path::PathBuf;

use prt_gpu::bake::cpu;
use prt_gpu::bake::gpu::{visibility_bits_and_transfer, Chunking, GpuBaker};
use prt_gpu::bake::{BakeInputs, Mode};
use prt_gpu::sampling::Sampling;
use prt_gpu::scene::{self, builtin, prepare::prepare, Scene};
use prt_gpu::sh::coeff_count;

/// Inputs of a bake of `scene` with `bands` bands and `samples` samples.
fn prepared(scene: Scene, bands: u32, samples: u32) -> BakeInputs {
    let (scene, _) = prepare(scene).unwrap();
    BakeInputs::new(&scene, bands, samples, 7)
}

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// Compares one bake on both backends; returns (rays cast, rays whose visibility differs).
fn compare(
    baker: &GpuBaker,
    prepared: &BakeInputs,
    mode: Mode,
    chunking: Chunking,
    what: &str,
) -> (u64, u64) {
    let inputs = prepared.view();
    let n = coeff_count(inputs.table.bands);
    let words = cpu::words_per_vertex(inputs.samples.len());
    let cpu_bits = cpu::visibility_bits(&inputs, mode);
    let (cpu_transfer, rays) = cpu::direct_transfer(&inputs, mode, &prt_gpu::bake::NoProgress);
    let (gpu_bits, gpu_transfer) =
        visibility_bits_and_transfer(baker, &inputs, mode, chunking).unwrap();
    assert_eq!(gpu_bits.len(), cpu_bits.len());

    let scale = cpu::transfer_scale(&inputs);
    let gamma = |m: f64| m * 2f64.powi(-24) / (1.0 - m * 2f64.powi(-24));
    let rounding = gamma((32 + words + 4) as f64);
    let mut differing_rays = 0u64;
    for v in 0..inputs.origins.len() {
        let cpu_row = &cpu_bits[v * words..(v + 1) * words];
        let gpu_row = &gpu_bits[v * words..(v + 1) * words];
        let differing: Vec<usize> = (0..inputs.samples.len())
            .filter(|&s| (cpu_row[s / 32] ^ gpu_row[s / 32]) & (1 << (s % 32)) != 0)
            .collect();
        differing_rays += differing.len() as u64;
        for k in 0..n {
            let term = |s: usize| {
                (inputs.normals[v].dot(inputs.samples.directions[s]) as f64
                    * inputs.table.row(s)[k] as f64)
                    .abs()
            };
            let visible_sum: f64 = (0..inputs.samples.len())
                .filter(|&s| (cpu_row[s / 32] | gpu_row[s / 32]) & (1 << (s % 32)) != 0)
                .map(term)
                .sum();
            let flipped: f64 = differing.iter().map(|&s| term(s)).sum();
            let (c, g) = (
                cpu_transfer[v * n + k] as f64,
                gpu_transfer[v * n + k] as f64,
            );
            let tolerance =
                scale * (flipped + rounding * visible_sum) + 2f64.powi(-23) * c.abs() + 1e-12;
            assert!(
                (c - g).abs() <= tolerance,
                "{what}: vertex {v}, k = {k}: cpu {c}, gpu {g}, tolerance {tolerance} ({} rays differ)",
                differing.len()
            );
        }
    }
    (rays, differing_rays)
}

fn check_scene(scene: Scene, samples: u32, what: &str) {
    let Some(baker) = common::gpu_baker() else {
        return;
    };
    let prepared = prepared(scene, 4, samples);
    let (rays, differing) = compare(baker, &prepared, Mode::Shadowed, Chunking::default(), what);
    eprintln!("{what}: {differing} of {rays} rays differ between CPU and GPU");
    assert!(rays > 0);
    assert!(
        differing as f64 <= 1e-5 * rays as f64,
        "{what}: {differing} of {rays} rays differ (more than 1 in 10^5)"
    );
    let (_, differing) = compare(
        baker,
        &prepared,
        Mode::Unshadowed,
        Chunking::default(),
        what,
    );
    assert!(
        differing as f64 <= 1e-5 * rays as f64,
        "{what} unshadowed: {differing} rays differ"
    );
}

#[test]
fn builtin_scene_agrees() {
    check_scene(builtin::default_scene(), 1024, "built-in scene");
}

#[test]
fn bunny_agrees() {
    check_scene(scene::load(&data("bunny.obj")).unwrap(), 1024, "bunny");
}

#[test]
fn dragon_agrees() {
    check_scene(
        scene::load(&data("dragon_vrip_res3.ply.gz")).unwrap(),
        256,
        "dragon_vrip_res3",
    );
}

#[test]
fn many_small_chunks_equal_one_big_chunk() {
    let Some(baker) = common::gpu_baker() else {
        return;
    };
    // 324 samples: the last 64-sample chunk is partial; 8 bands: 64 coefficients.
    let prepared = prepared(scene::load(&data("teapot.obj")).unwrap(), 8, 324);
    let inputs = prepared.view();
    let whole =
        visibility_bits_and_transfer(baker, &inputs, Mode::Shadowed, Chunking::default()).unwrap();
    let small = Chunking {
        max_vertices: Some(37),
        max_samples: Some(64),
        max_steps: None,
    };
    let chunked = visibility_bits_and_transfer(baker, &inputs, Mode::Shadowed, small).unwrap();
    assert!(whole.0 == chunked.0, "visibility bits depend on chunking");
    // Sums over sample chunks are added in another order: equal within f32 rounding of the
    // vertex's largest coefficient (a few ulps; small coefficients are sums that cancel).
    let n = coeff_count(8);
    for (v, (a, b)) in whole.1.chunks(n).zip(chunked.1.chunks(n)).enumerate() {
        let size = a.iter().fold(0.0f32, |m, x| m.max(x.abs()));
        for k in 0..n {
            assert!(
                (a[k] - b[k]).abs() <= 1e-5 * size,
                "vertex {v}, k = {k}: {} vs {}",
                a[k],
                b[k]
            );
        }
    }
    // And the chunked bake still agrees with the CPU ray for ray.
    let (rays, differing) = compare(
        baker,
        &prepared,
        Mode::Shadowed,
        small,
        "teapot in small chunks",
    );
    assert!(differing as f64 <= 1e-5 * rays as f64);
    // The GPU counts its rays chunk by chunk; in total they are the CPU's.
    for chunking in [Chunking::default(), small] {
        let (_, run) = prt_gpu::bake::gpu::direct_transfer(
            baker,
            &inputs,
            Mode::Shadowed,
            chunking,
            &prt_gpu::bake::NoProgress,
        )
        .unwrap();
        assert_eq!(run.rays_cast, rays, "{chunking:?}");
    }
}

#[test]
fn a_traversal_past_its_step_budget_is_an_error_not_a_wrong_answer() {
    // llvmpipe silently truncates long loops; the kernel counts its own steps instead. With a
    // budget too small for any real traversal, every ray that needs more must be reported.
    let Some(baker) = common::gpu_baker() else {
        return;
    };
    let prepared = prepared(scene::load(&data("bunny.obj")).unwrap(), 2, 64);
    let tiny = Chunking {
        max_steps: Some(4),
        ..Chunking::default()
    };
    let Err(error) = visibility_bits_and_transfer(baker, &prepared.view(), Mode::Shadowed, tiny)
    else {
        panic!("a 4-step budget cannot trace the bunny");
    };
    assert!(error.to_string().contains("traversal steps"), "{error}");
}

#[test]
fn auto_never_picks_a_software_adapter() {
    let adapters = prt_gpu::device::list_adapters();
    let only_software = !adapters.is_empty() && adapters.iter().all(|a| a.is_software());
    let opened = prt_gpu::device::open(prt_gpu::device::DeviceChoice::Auto, None).unwrap();
    if only_software || adapters.is_empty() {
        assert!(opened.is_none(), "auto opened a software adapter");
    } else {
        assert!(!opened.unwrap().adapter.is_software());
    }
}

#[test]
fn surface_points_agree() {
    use prt_gpu::bake::BakeOptions;
    use prt_gpu::receivers::{spread_points, PointDensity, Receivers};
    use prt_gpu::sampling::Sampling;
    let Some(baker) = common::gpu_baker() else {
        return;
    };
    // Points inside the bunny's triangles, their normals interpolated: the receivers of the
    // least-squares fit, checked ray for ray as the vertices are.
    let (scene, _) = prepare(scene::load(&data("bunny.obj")).unwrap()).unwrap();
    let density = PointDensity {
        per_vertex: 2.0,
        min_per_triangle: 1,
    };
    let receivers = Receivers::at_points(&scene, &spread_points(&scene, density, 3));
    let options = BakeOptions {
        bands: 4,
        samples: 256,
        sampling: Sampling::Stratified,
        seed: 7,
        ..BakeOptions::default()
    };
    let prepared = BakeInputs::for_receivers(&scene, &receivers, &options);
    for mode in [Mode::Shadowed, Mode::Unshadowed] {
        let (rays, differing) = compare(baker, &prepared, mode, Chunking::default(), "points");
        eprintln!("bunny surface points, {mode:?}: {differing} of {rays} rays differ");
        assert!(
            differing as f64 <= 1e-5 * (rays.max(1)) as f64,
            "{mode:?}: {differing} of {rays} rays differ"
        );
    }
}

/// The kernels with the emulated division (`divide_rounded`), which an adapter whose own `/`
/// is not IEEE's bakes with (an NVIDIA H200's is not; lavapipe's is, so the shared baker divides
/// with `/` here): the same rays and transfer as the CPU, shadowed and interreflected hits.
#[test]
fn the_emulated_division_bakes_the_cpus_rays() {
    use prt_gpu::bake::gpu::Division;
    let Some(context) = prt_gpu::device::any_adapter_or_skip() else {
        return;
    };
    let baker = GpuBaker::dividing(context, Division::Emulated).unwrap();
    assert_eq!(baker.division(), Division::Emulated);
    let prepared = prepared(builtin::default_scene(), 4, 256);
    let (rays, differing) = compare(
        &baker,
        &prepared,
        Mode::Shadowed,
        Chunking::default(),
        "emulated division",
    );
    assert!(rays > 0);
    assert_eq!(differing, 0, "{differing} of {rays} rays differ");
    // Closest hits (distances compared, barycentrics divided): the gather matrix, entry for
    // entry.
    let inputs = prepared.view();
    let (_, cpu_matrix, _) = prt_gpu::bake::bounce::direct_transfer_and_gather_matrix_cpu(
        &inputs,
        &prt_gpu::bake::NoProgress,
    );
    let (_, gpu_matrix, _) = prt_gpu::bake::gpu::direct_transfer_and_gather_matrix(
        &baker,
        &inputs,
        Chunking::default(),
        &prt_gpu::bake::NoProgress,
    )
    .unwrap();
    assert!(!cpu_matrix.weights.is_empty());
    assert!(gpu_matrix == cpu_matrix, "the gather matrices differ");
}

/// Closest hits on a CAD model with coincident faces (2CylinderEngine: meshes shown by several
/// nodes, faces that touch), where a ray often meets two triangles at one distance. The CPU
/// (fan packets) and the GPU (its own traversal, grid-rounded boxes, another visiting order)
/// must keep the same triangle for every ray: the tie rule (`ray::replaces`) decides, not the
/// order. With fan packets that kept the first triangle they met, an H200 kept another
/// triangle than the CPU on 767 of 86,688,768 rays of this mesh (1024 cosine samples); with the
/// rule but box tests cut off exactly at the closest hit (no `ray::reach`), lavapipe did on 10
/// of 5,418,048 (64 samples).
#[test]
fn closest_hits_agree_on_coincident_faces() {
    let Some(baker) = common::gpu_baker() else {
        return;
    };
    let (scene, _) = prepare(scene::load(&data("gltf/2CylinderEngine.glb")).unwrap()).unwrap();
    // Single rays on the CPU for a set shared by all vertices, fan packets for the cosine set.
    for sampling in [Sampling::Stratified, Sampling::Cosine] {
        let prepared = BakeInputs::with_sampling(&scene, 2, 16, 7, sampling);
        let inputs = prepared.view();
        let (cpu_hits, rays) = cpu::closest_hit_triangles(&inputs);
        let gpu_hits = prt_gpu::bake::gpu::closest_hits(
            baker,
            &inputs,
            Chunking::default(),
            &prt_gpu::bake::NoProgress,
        )
        .unwrap();
        let mut hits = 0;
        for (v, (c, g)) in cpu_hits.iter().zip(&gpu_hits).enumerate() {
            let g: Vec<(u32, u32)> = g.iter().map(|&(s, hit)| (s, hit.triangle)).collect();
            assert_eq!(c, &g, "{sampling:?}: receiver {v}");
            hits += c.len();
        }
        eprintln!("2CylinderEngine, {sampling:?}: {hits} closest hits of {rays} rays, the same on CPU and GPU");
        assert!(hits as u64 > rays / 2, "too few hits to test anything");
    }
}

/// Texels to be denoised cast the cosine set turned about their normals by their own angles
/// (`sampling::ReceiverTurns`): the GPU turns each receiver's frame as the CPU does, in whole
/// and in chunks (whose receivers keep the turns they have in the whole), ray for ray with the
/// emulated division; the turns change the rays cast.
#[test]
fn turned_frames_cast_the_cpus_rays() {
    use prt_gpu::bake::gpu::Division;
    use prt_gpu::bake::BakeOptions;
    use prt_gpu::receivers::Receivers;
    let Some(context) = prt_gpu::device::any_adapter_or_skip() else {
        return;
    };
    let baker = GpuBaker::dividing(context, Division::Emulated).unwrap();
    let (scene, _) = prepare(builtin::default_scene()).unwrap();
    let options = BakeOptions {
        bands: 4,
        samples: 256,
        sampling: Sampling::Cosine,
        seed: 7,
        turns: true,
        ..BakeOptions::default()
    };
    let receivers = Receivers::vertices(&scene);
    let turned = BakeInputs::for_receivers(&scene, &receivers, &options);
    assert!(turned.turns.is_some());
    let small = Chunking {
        max_vertices: Some(37),
        max_samples: Some(64),
        max_steps: None,
    };
    for chunking in [Chunking::default(), small] {
        let (rays, differing) = compare(&baker, &turned, Mode::Shadowed, chunking, "turned");
        assert!(rays > 0);
        assert_eq!(
            differing, 0,
            "{chunking:?}: {differing} of {rays} rays differ"
        );
    }
    let plain = BakeInputs::for_receivers(
        &scene,
        &receivers,
        &BakeOptions {
            turns: false,
            ..options
        },
    );
    let turned_bits = cpu::visibility_bits(&turned.view(), Mode::Shadowed);
    let plain_bits = cpu::visibility_bits(&plain.view(), Mode::Shadowed);
    let words = cpu::words_per_vertex(256);
    let changed = turned_bits
        .chunks(words)
        .zip(plain_bits.chunks(words))
        .filter(|(a, b)| a != b)
        .count();
    let vertices = turned.origins.len();
    assert!(
        changed * 2 > vertices,
        "the turns changed the rays of {changed} of {vertices} vertices"
    );
}

/// The lightmap denoiser on the GPU (wgsl/denoise.wgsl) against the CPU's
/// (`receivers::denoise`): on a bumpy surface cut into charts with invalid texels, at 3 and 8
/// bands (the second in two coefficient groups), whole and in bands of 5 rows, within f32
/// rounding of the sums.
#[test]
fn denoising_agrees() {
    use prt_gpu::bake::gpu::denoise::{denoise, denoise_in_bands};
    use prt_gpu::receivers::denoise::{self as reference, DenoiseGuide, NO_CHART};
    use prt_gpu::sampling::Pcg32;
    let Some(baker) = common::gpu_baker() else {
        return;
    };
    let (width, height) = (37u32, 29u32);
    let mut rng = Pcg32::new(11);
    let (mut positions, mut normals, mut charts) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..width * height {
        let (x, y) = ((i % width) as f32, (i / width) as f32);
        let slope = glam::Vec2::new((0.3 * x).cos(), -(0.2 * y).sin()) * 0.8;
        positions.push(glam::Vec3::new(
            x,
            y,
            0.8 * (0.3 * x).sin() + 0.8 * (0.2 * y).cos(),
        ));
        normals.push(glam::Vec3::new(-slope.x, -slope.y, 1.0).normalize());
        let chart = (x as u32 / 9) + 5 * (y as u32 / 11);
        charts.push(if rng.next_f32() < 0.1 {
            NO_CHART
        } else {
            chart
        });
    }
    let levels = (0..width * height).map(|_| rng.next_f32()).collect();
    let noise = (0..width * height)
        .map(|_| 0.05 + 0.2 * rng.next_f32())
        .collect();
    let geometry = (positions, normals);
    let guide = DenoiseGuide::new((width, height), geometry, charts, (levels, noise));
    for bands in [3usize, 8] {
        let stride = 3 * bands * bands;
        let image: Vec<f32> = (0..(width * height) as usize * stride)
            .map(|_| rng.next_f32() - 0.3)
            .collect();
        let cpu = reference::denoise(&guide, &image, stride);
        assert_ne!(cpu, image);
        for gpu in [
            denoise(baker, &guide, &image, stride).unwrap(),
            denoise_in_bands(baker, &guide, (&image, stride), 5).unwrap(),
        ] {
            assert_eq!(gpu.len(), cpu.len());
            for (i, (c, g)) in cpu.iter().zip(&gpu).enumerate() {
                assert!(
                    (c - g).abs() <= 1e-5,
                    "{bands} bands, float {i}: cpu {c}, gpu {g}"
                );
            }
        }
    }
}
