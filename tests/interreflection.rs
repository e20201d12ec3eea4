//! Interreflected transfer: a closed form, energy bounds, convex shapes, CPU against GPU.

mod common;

use std::path::PathBuf;

use glam::Vec3;
use prt_gpu::bake::BakedMesh;
use prt_gpu::bake::{bake, Backend, BakeOptions, BakeReport, CpuBackend, Mode, NoProgress};
use prt_gpu::scene::{self, builtin, Scene};

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// Exit radiance under unit constant light: the DC coefficient times l_00 = sqrt(4 pi).
fn radiance(baked: &BakedMesh, vertex: usize, channel: usize) -> f64 {
    baked.transfer.vertex_channel(vertex, channel)[0] as f64 * (4.0 * std::f64::consts::PI).sqrt()
}

fn run(
    scene: &Scene,
    mode: Mode,
    bounces: u32,
    albedo: f32,
    samples: u32,
    backend: &dyn Backend,
) -> (BakedMesh, BakeReport) {
    let options = BakeOptions {
        bands: 2,
        samples,
        mode,
        bounces,
        albedo: Some(Vec3::splat(albedo)),
        ..BakeOptions::default()
    };
    bake(scene.clone(), &options, backend, &NoProgress).unwrap()
}

/// The inside of a unit sphere whose cap above `z_cut` is cut away: triangles wound and
/// normals pointing inwards. Returns it and the opening's share f of the (tessellated) area.
fn open_sphere(subdivisions: u32, z_cut: f32) -> (Scene, f64) {
    let sphere = builtin::icosphere(Vec3::ZERO, 1.0, subdivisions);
    let area = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| sphere.positions[i as usize]);
        (b - a).cross(c - a).length() as f64 / 2.0
    };
    let total: f64 = sphere.triangles.iter().map(area).sum();
    let (cap, kept): (Vec<[u32; 3]>, Vec<[u32; 3]>) = sphere.triangles.iter().partition(|t| {
        let centroid: Vec3 = t
            .iter()
            .map(|&i| sphere.positions[i as usize])
            .sum::<Vec3>()
            / 3.0;
        centroid.z > z_cut
    });
    let opening = cap.iter().map(area).sum::<f64>() / total;
    let scene = Scene {
        normals: Some(sphere.positions.iter().map(|p| -p.normalize()).collect()),
        triangles: kept.iter().map(|&[a, b, c]| [a, c, b]).collect(),
        ..sphere
    };
    (scene, opening)
}

#[test]
fn open_sphere_matches_the_geometric_series() {
    // Every inner point of a sphere sees any part of it with a cosine-weighted share equal to
    // that part's share of the area (f for the opening), so under unit light
    // L_N = rho f sum_{k=0..N} (rho (1 - f))^k.
    // With rho = 1 this is also the white furnace with bounces: radiance rises monotonically
    // with N towards 1.
    let z_cut = 0.3;
    let (scene, f) = open_sphere(4, z_cut);
    for backend in common::backends() {
        // Lavapipe casts rays about ten times slower than the CPU: the GPU is held to the
        // series at one and at four bounces (every bounce's pass runs in the second), the CPU
        // at every count; the two agree bounce for bounce in the tests below.
        let counts: &[u32] = match backend.gpu_context() {
            None => &[0, 1, 2, 3, 4],
            Some(_) => &[1, 4],
        };
        for albedo in [1.0f32, 0.5] {
            let rho = albedo as f64;
            let mut previous: Option<Vec<f64>> = None;
            for &bounces in counts {
                let (baked, report) = run(
                    &scene,
                    Mode::Interreflected,
                    bounces,
                    albedo,
                    1024,
                    backend.as_ref(),
                );
                assert_eq!(report.bounces.len(), bounces as usize);
                let expected: f64 = (0..=bounces)
                    .map(|k| rho * f * (rho * (1.0 - f)).powi(k as i32))
                    .sum();
                // Vertices well below the rim, where the tessellated sphere is a sphere.
                let inner: Vec<usize> = (0..baked.scene.positions.len())
                    .filter(|&v| baked.scene.positions[v].z < z_cut - 0.4)
                    .collect();
                assert!(inner.len() > 100);
                let values: Vec<f64> = inner.iter().map(|&v| radiance(&baked, v, 0)).collect();
                let mean = values.iter().sum::<f64>() / values.len() as f64;
                let worst = values
                    .iter()
                    .map(|x| (x - expected).abs())
                    .fold(0.0, f64::max);
                eprintln!(
                    "{} rho {rho} N {bounces}: expected {expected:.4}, mean {mean:.4}, worst vertex off by {worst:.4}",
                    backend.describe()
                );
                // Averaged over hundreds of vertices the Monte-Carlo noise nearly cancels: what is
                // left is tessellation (flat facets, a polygonal rim), about half a percent.
                assert!(
                    (mean - expected).abs() < 0.01 * expected,
                    "mean {mean} vs {expected}"
                );
                // One vertex: the direct estimate averages X = 4 rho cos V over N samples, with
                // E[X^2] <= 4 rho^2 f, so 3 plain-MC standard errors are 6 rho sqrt(f / N);
                // stratification and the averaging of bounces only shrink the error.
                let per_vertex = 6.0 * rho * (f / 1024.0).sqrt() + 0.01 * expected;
                assert!(
                    worst < per_vertex,
                    "a vertex is off by {worst} > {per_vertex} (expected {expected})"
                );
                // Every vertex brightens with every bounce, and never past the furnace's 1.
                let all: Vec<f64> = (0..baked.scene.positions.len())
                    .map(|v| radiance(&baked, v, 0))
                    .collect();
                if let Some(before) = &previous {
                    for (v, (now, then)) in all.iter().zip(before).enumerate() {
                        assert!(
                            now >= then,
                            "vertex {v} darkened from {then} to {now} at N = {bounces}"
                        );
                    }
                }
                assert!(
                    all.iter().all(|&x| x <= 1.0 + per_vertex),
                    "radiance above 1"
                );
                previous = Some(all);
            }
        }
    }
}

#[test]
fn no_bounces_is_shadowed_and_a_convex_shape_gains_nothing() {
    let sphere = builtin::icosphere(Vec3::new(0.2, -0.1, 0.3), 0.7, 3);
    let scene = builtin::default_scene();
    for backend in common::backends() {
        // Interreflected with zero bounces is the shadowed bake, bit for bit: the closest-hit
        // traversal blocks exactly the rays the any-hit traversal blocks.
        let (shadowed, _) = run(&scene, Mode::Shadowed, 0, 0.8, 256, backend.as_ref());
        let (zero, _) = run(&scene, Mode::Interreflected, 0, 0.8, 256, backend.as_ref());
        assert!(
            zero.transfer == shadowed.transfer,
            "{}: N = 0 differs from shadowed",
            backend.describe()
        );

        // No ray of a convex shape hits it: bounces add exactly nothing.
        let (shadowed, _) = run(&sphere, Mode::Shadowed, 0, 1.0, 256, backend.as_ref());
        let (bounced, report) = run(&sphere, Mode::Interreflected, 3, 1.0, 256, backend.as_ref());
        assert_eq!(report.gather_entries, 0);
        assert!(report.bounces.iter().all(|b| b.relative_energy == 0.0));
        assert!(
            bounced.transfer == shadowed.transfer,
            "{}: a convex sphere gained light",
            backend.describe()
        );
    }
}

#[test]
fn bounces_add_non_negative_energy_and_converge() {
    // The built-in scene with its own albedos (all below 1): each vertex's DC term can only
    // grow with bounces, and the energy each bounce adds shrinks geometrically.
    let scene = builtin::default_scene();
    let (shadowed, _) = run_with_scene_albedo(&scene, Mode::Shadowed, 0);
    let (bounced, report) = run_with_scene_albedo(&scene, Mode::Interreflected, 6);
    for v in 0..shadowed.transfer.vertex_count() {
        for c in 0..3 {
            let (before, after) = (
                shadowed.transfer.vertex_channel(v, c)[0],
                bounced.transfer.vertex_channel(v, c)[0],
            );
            assert!(
                after >= before,
                "vertex {v} channel {c}: {before} -> {after}"
            );
        }
    }
    let energies: Vec<f64> = report.bounces.iter().map(|b| b.relative_energy).collect();
    eprintln!("relative energy per bounce: {energies:?}");
    assert_eq!(energies.len(), 6);
    assert!(
        energies[0] > 0.01,
        "the first bounce should add light in a scene with a wall"
    );
    for pair in energies.windows(2) {
        assert!(
            pair[1] < 0.8 * pair[0],
            "bounces do not converge: {energies:?}"
        );
    }
}

#[test]
fn bounce_tolerance_stops_early() {
    let scene = builtin::default_scene();
    let options = BakeOptions {
        bands: 2,
        samples: 256,
        mode: Mode::Interreflected,
        bounces: 20,
        bounce_tolerance: 0.01,
        ..BakeOptions::default()
    };
    let (baked, report) = bake(scene, &options, &CpuBackend, &NoProgress).unwrap();
    let n = report.bounces.len();
    assert!(n < 20, "never stopped");
    assert!(report.bounces[n - 1].relative_energy < 0.01);
    assert!(report.bounces[..n - 1]
        .iter()
        .all(|b| b.relative_energy >= 0.01));
    assert_eq!(baked.metadata.bounces as usize, n);
}

fn run_with_scene_albedo(scene: &Scene, mode: Mode, bounces: u32) -> (BakedMesh, BakeReport) {
    let options = BakeOptions {
        bands: 3,
        samples: 256,
        mode,
        bounces,
        ..BakeOptions::default()
    };
    bake(scene.clone(), &options, &CpuBackend, &NoProgress).unwrap()
}

/// CPU and GPU interreflection on the same inputs. The GPU's hits may differ from the CPU's for
/// a few rays (visibility, or which of two triangles at one distance is closest), which moves
/// gather weight between matrix entries. With `dW_p = sum_j |w_gpu - w_cpu|` and
/// `E^b` the bound after b bounces (E^0 the measured direct difference), bounce b can differ by
/// `rho_p (sum_j |dw_pj| |T^(b-1)_j| + sum_j w_pj E^(b-1)_j)` plus f32 rounding of the sums.
fn check_interreflection_agreement(scene: Scene, samples: u32, what: &str) {
    use prt_gpu::bake::bounce::{apply_cpu, direct_transfer_and_gather_matrix_cpu, GatherMatrix};
    use prt_gpu::bake::gpu::{direct_transfer_and_gather_matrix, Chunking};
    use prt_gpu::bake::{tint_by_albedo, BakeInputs};
    use prt_gpu::scene::prepare::prepare;

    let Some(baker) = common::gpu_baker() else {
        return;
    };
    let (scene, _) = prepare(scene).unwrap();
    let bands = 3;
    let coeffs = 9;
    let owned = BakeInputs::new(&scene, bands, samples, 3);
    let inputs = owned.view();
    let (cpu_direct, cpu_matrix, _) = direct_transfer_and_gather_matrix_cpu(&inputs, &NoProgress);
    let (gpu_direct, gpu_matrix, _) =
        direct_transfer_and_gather_matrix(baker, &inputs, Chunking::default(), &NoProgress)
            .unwrap();

    // How much gather weight moved between the two matrices.
    let row_difference = |p: usize| -> Vec<(u32, f32)> {
        let (a_cols, a_w) = cpu_matrix.row(p);
        let (b_cols, b_w) = gpu_matrix.row(p);
        let mut diff: Vec<(u32, f32)> = a_cols.iter().zip(a_w).map(|(&j, &w)| (j, -w)).collect();
        diff.extend(b_cols.iter().zip(b_w).map(|(&j, &w)| (j, w)));
        diff.sort_by_key(|e| e.0);
        let mut merged: Vec<(u32, f32)> = Vec::new();
        for (j, w) in diff {
            match merged.last_mut() {
                Some(last) if last.0 == j => last.1 += w,
                _ => merged.push((j, w)),
            }
        }
        merged
    };
    let total_weight: f64 = cpu_matrix.weights.iter().map(|&w| w as f64).sum();
    let moved: f64 = (0..cpu_matrix.rows())
        .map(|p| {
            row_difference(p)
                .iter()
                .map(|e| e.1.abs() as f64)
                .sum::<f64>()
        })
        .sum();
    eprintln!(
        "{what}: {:.2e} of the gather weight differs between CPU and GPU",
        moved / total_weight
    );
    assert!(
        moved <= 1e-4 * total_weight,
        "{what}: gather matrices differ by {moved} of {total_weight}"
    );

    let albedo = &scene.albedo;
    let mut cpu_t = tint_by_albedo(&cpu_direct, albedo, bands).into_coeffs();
    let mut gpu_t = tint_by_albedo(&gpu_direct, albedo, bands).into_coeffs();
    let mut bound: Vec<f64> = cpu_t
        .iter()
        .zip(&gpu_t)
        .map(|(a, b)| (a - b).abs() as f64)
        .collect();
    let uploaded = baker
        .upload_gather_matrix(&gpu_matrix, albedo, bands)
        .unwrap();
    let stride = 3 * coeffs;
    for b in 1..=3 {
        let cpu_next = apply_cpu(&cpu_matrix, &cpu_t, albedo, coeffs);
        let gpu_next = baker.bounce(&uploaded, &gpu_t).unwrap();
        let next_bound = next_bound(&gpu_matrix, &cpu_t, &bound, albedo, stride, &row_difference);
        for (i, ((c, g), e)) in cpu_next.iter().zip(&gpu_next).zip(&next_bound).enumerate() {
            let diff = (c - g).abs() as f64;
            assert!(
                diff <= *e,
                "{what} bounce {b}: value {i}: cpu {c}, gpu {g}, bound {e}"
            );
        }
        cpu_t = cpu_next;
        gpu_t = gpu_next;
        bound = next_bound;
    }

    fn next_bound(
        gpu_matrix: &GatherMatrix,
        cpu_previous: &[f32],
        previous_bound: &[f64],
        albedo: &[Vec3],
        stride: usize,
        row_difference: &dyn Fn(usize) -> Vec<(u32, f32)>,
    ) -> Vec<f64> {
        let mut out = vec![0.0; cpu_previous.len()];
        for p in 0..gpu_matrix.rows() {
            let (cols, weights) = gpu_matrix.row(p);
            let difference = row_difference(p);
            for i in 0..stride {
                let at = |j: u32| j as usize * stride + i;
                let moved: f64 = difference
                    .iter()
                    .map(|&(j, dw)| dw.abs() as f64 * cpu_previous[at(j)].abs() as f64)
                    .sum();
                let carried: f64 = cols
                    .iter()
                    .zip(weights)
                    .map(|(&j, &w)| w as f64 * previous_bound[at(j)])
                    .sum();
                let size: f64 = cols
                    .iter()
                    .zip(weights)
                    .map(|(&j, &w)| w as f64 * cpu_previous[at(j)].abs() as f64)
                    .sum();
                let rounding = (cols.len() as f64 + 4.0) * 2f64.powi(-23) * size;
                out[p * stride + i] =
                    albedo[p][i / (stride / 3)] as f64 * (moved + carried) + rounding + 1e-9;
            }
        }
        out
    }
}

#[test]
fn builtin_scene_bounces_agree_on_cpu_and_gpu() {
    check_interreflection_agreement(builtin::default_scene(), 1024, "built-in scene");
}

#[test]
fn dragon_bounces_agree_on_cpu_and_gpu() {
    check_interreflection_agreement(
        scene::load(&data("dragon_vrip_res3.ply.gz")).unwrap(),
        256,
        "dragon_vrip_res3",
    );
}
