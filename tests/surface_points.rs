//! Receivers on the surface, not at the vertices: the shadow-terminator rule, the least-squares
//! vertex fit against point-sampled vertices over the surface, and both backends.

mod common;

use glam::Vec3;
use prt_gpu::bake::{bake, bake_at, BakeOptions, CpuBackend, Fit, Mode, NoProgress};
use prt_gpu::light::ShLight;
use prt_gpu::receivers::{spread_points, PointDensity, Receivers, SurfacePoint};
use prt_gpu::sampling::Sampling;
use prt_gpu::scene::{builtin, prepare::prepare, Scene};
use prt_gpu::surface::{surface_error, surface_reference, texel_surface_error, SurfaceReference};

/// The rule at a point whose shading normal leans past its flat face: a direction below the
/// face's plane is blocked by the face, as a path tracer sees it. On a convex shape nothing
/// else blocks, so of cosine-distributed directions about the shading normal n_s exactly
/// `(1 + cos theta) / 2` are open, theta the angle between n_s and the face normal (the sky
/// view factor of a tilted plane): shadowed DC transfer is `albedo * Y00 * (1 + cos theta) / 2`
/// where trusting the shading hemisphere would give `albedo * Y00`.
#[test]
fn a_coarse_sphere_blocks_directions_below_the_face() {
    // An icosahedron: vertex normals lean 37 degrees from the faces.
    let (sphere, _) = prepare(builtin::icosphere(Vec3::ZERO, 1.0, 0)).unwrap();
    let points: Vec<SurfacePoint> = (0..sphere.triangle_count() as u32)
        .flat_map(|t| {
            [[0.8, 0.1, 0.1], [0.1, 0.45, 0.45], [1.0 / 3.0; 3]].map(|barycentrics| SurfacePoint {
                triangle: t,
                barycentrics,
            })
        })
        .collect();
    let receivers = Receivers::at_points(&sphere, &points);
    let samples = 4096;
    let options = BakeOptions {
        bands: 1,
        samples,
        sampling: Sampling::Cosine,
        mode: Mode::Shadowed,
        albedo: Some(Vec3::ONE),
        ..BakeOptions::default()
    };
    let mut leaning = 0;
    for backend in common::backends() {
        let (transfer, _) = bake_at(
            &sphere,
            &receivers,
            &options,
            backend.as_ref(),
            None,
            &NoProgress,
        )
        .unwrap();
        for (i, point) in points.iter().enumerate() {
            let corners = sphere.triangles[point.triangle as usize];
            let face = prt_gpu::receivers::face_normal(&sphere.positions, corners).normalize();
            let cos_theta = receivers.normals[i].dot(face) as f64;
            let open = (1.0 + cos_theta) / 2.0;
            // Each sample is open with probability `open`: a binomial fraction.
            let sigma = (open * (1.0 - open) / samples as f64).sqrt();
            let measured = transfer.vertex_channel(i, 0)[0] as f64 / Y00;
            assert!(
                (measured - open).abs() <= 5.0 * sigma + 1e-6,
                "{}: point {i}: open fraction {measured}, expected {open} (sigma {sigma})",
                backend.describe()
            );
            if open < 1.0 - 10.0 * sigma {
                leaning += 1;
            }
        }
    }
    assert!(
        leaning > 0,
        "no point leans past its face: the test shows nothing"
    );
}

/// The constant SH basis function, 1 / (2 sqrt(pi)).
const Y00: f64 = 0.282_094_791_773_878_14;

/// A plane with a thin box standing on it, coarse enough that its contact shadow falls between
/// the plane's vertices.
fn plane_with_thin_box() -> Scene {
    let plane = builtin::grid_plane(Vec3::ZERO, Vec3::X * 2.0, Vec3::NEG_Z * 2.0, 4, Vec3::ONE);
    let wall = builtin::closed_box(Vec3::new(-0.9, 0.0, -0.05), Vec3::new(0.9, 0.8, 0.05), 2);
    builtin::merge(&[plane, wall])
}

/// Surface error (relative RMS of relit radiance at held-out points) of point-sampled vertices
/// and of the least-squares fit at equal rays, each with several seeds: the spread between
/// seeds is the noise the ordering must clear.
#[test]
fn the_least_squares_fit_beats_point_vertices_over_the_surface_at_equal_rays() {
    let scene = plane_with_thin_box();
    let (prepared, _) = prepare(scene.clone()).unwrap();
    let light = sky_light(3);
    let base = BakeOptions {
        bands: 3,
        mode: Mode::Shadowed,
        ..BakeOptions::default()
    };
    let reference = reference_for(&prepared, &base, &light);
    let density = PointDensity::default();
    let errors = |fit: Fit, samples: u32| -> Vec<f64> {
        let options = BakeOptions {
            samples,
            fit,
            point_density: density,
            ..base.clone()
        };
        errors_over_seeds(&scene, &options, (&reference, &light))
    };
    // Equal rays: the fit bakes `per_vertex` times as many receivers with that many times
    // fewer samples.
    let point = errors(Fit::Point, 1024);
    let fitted = errors(Fit::LeastSquares, (1024.0 / density.per_vertex) as u32);
    let (point_mean, point_spread) = mean_and_spread(&point);
    let (fit_mean, fit_spread) = mean_and_spread(&fitted);
    eprintln!("surface error: point {point:?}, least squares {fitted:?}");
    assert!(
        fit_mean + 3.0 * (fit_spread + point_spread) < point_mean,
        "least squares {fit_mean:.4} (spread {fit_spread:.4}) not below point {point_mean:.4} \
         (spread {point_spread:.4})"
    );

    // Per texel, at a modest resolution, below both.
    let texels: Vec<f64> = (1..=4)
        .map(|seed| {
            let options = BakeOptions {
                samples: 256,
                seed,
                lightmap: Some(128),
                ..base.clone()
            };
            let (baked, _) = bake(scene.clone(), &options, &CpuBackend, &NoProgress).unwrap();
            let lightmap = baked.lightmap.as_ref().unwrap();
            texel_surface_error(&reference, lightmap, &light)
                .unwrap()
                .rms
                / reference.rms
        })
        .collect();
    let (texel_mean, texel_spread) = mean_and_spread(&texels);
    eprintln!("surface error: texels at 128 {texels:?}");
    assert!(
        texel_mean + 3.0 * (texel_spread + fit_spread) < fit_mean,
        "texels {texel_mean:.4} (spread {texel_spread:.4}) not below least squares {fit_mean:.4}"
    );
}

/// A 16,384-sample bake of `prepared` with `base` at 2,000 held-out points, relit by `light`.
fn reference_for(prepared: &Scene, base: &BakeOptions, light: &ShLight) -> SurfaceReference {
    let options = BakeOptions {
        samples: 16_384,
        seed: 999,
        ..base.clone()
    };
    surface_reference(prepared, 2000, 77, &options, &CpuBackend, light, None).unwrap()
}

/// The surface error of `scene`'s vertices baked with `options` at seeds 1 to 4, relative to
/// the `reference`'s RMS radiance under `light`.
fn errors_over_seeds(
    scene: &Scene,
    options: &BakeOptions,
    (reference, light): (&SurfaceReference, &ShLight),
) -> Vec<f64> {
    (1..=4)
        .map(|seed| {
            let options = BakeOptions {
                seed,
                ..options.clone()
            };
            let (baked, _) = bake(scene.clone(), &options, &CpuBackend, &NoProgress).unwrap();
            surface_error(reference, &baked.scene, &baked.transfer, light)
                .unwrap()
                .rms
                / reference.rms
        })
        .collect()
}

/// Mean and sample standard deviation.
fn mean_and_spread(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, variance.sqrt())
}

/// A sky brighter overhead than at the horizon, white: enough for shadows to matter.
fn sky_light(bands: u32) -> ShLight {
    prt_gpu::light::preview_light(bands).unwrap()
}

/// Unshadowed transfer on a flat plane is the same at every point (one normal, one sample
/// set): a field linear over each triangle, which the fit must give back exactly. Stratified
/// samples are one set shared by every point; cosine samples would turn about each point's
/// normal by its own angle, and each point's estimate would differ by its noise.
#[test]
fn the_fit_gives_back_the_constant_transfer_of_an_open_plane() {
    let plane = builtin::grid_plane(Vec3::ZERO, Vec3::X, Vec3::NEG_Z, 3, Vec3::splat(0.5));
    for mode in [Mode::Unshadowed, Mode::Shadowed] {
        let options = |fit| BakeOptions {
            bands: 3,
            samples: 64,
            mode,
            fit,
            sampling: Sampling::Stratified,
            ..BakeOptions::default()
        };
        let (points, _) = bake(
            plane.clone(),
            &options(Fit::Point),
            &CpuBackend,
            &NoProgress,
        )
        .unwrap();
        let (fitted, report) = bake(
            plane.clone(),
            &options(Fit::LeastSquares),
            &CpuBackend,
            &NoProgress,
        )
        .unwrap();
        assert!(report.receivers > points.transfer.vertex_count());
        assert_eq!(fitted.metadata.fit, Fit::LeastSquares);
        for (a, b) in fitted
            .transfer
            .coeffs()
            .iter()
            .zip(points.transfer.coeffs())
        {
            assert!(
                (a - b).abs() <= 1e-5 * b.abs().max(1e-3),
                "{mode:?}: {a} vs {b}"
            );
        }
    }
}

/// Cosine samples turn about each fitted point's normal by the point's own angle, so the
/// points' errors are independent and the fit averages them; one set shared by every point
/// (as point-sampled vertices share it) would leave the fit each point's common error. On the
/// built-in scene, at 16 samples a receiver where noise dominates, the fitted vertices are off
/// a 16,384-sample bake by under 0.8 of what point-sampled vertices are at each of four seeds,
/// and under 0.7 on average.
#[test]
fn turned_points_average_out_the_noise_the_fit_would_otherwise_keep() {
    let scene = builtin::default_scene();
    let (prepared, _) = prepare(scene.clone()).unwrap();
    let light = sky_light(3);
    let base = BakeOptions {
        bands: 3,
        mode: Mode::Shadowed,
        samples: 16,
        sampling: Sampling::Cosine,
        ..BakeOptions::default()
    };
    let reference = reference_for(&prepared, &base, &light);
    let errors = |fit: Fit| -> Vec<f64> {
        let options = BakeOptions {
            fit,
            ..base.clone()
        };
        errors_over_seeds(&scene, &options, (&reference, &light))
    };
    let (point, fitted) = (errors(Fit::Point), errors(Fit::LeastSquares));
    eprintln!(
        "16 samples a receiver: point {point:?}, least squares over turned points {fitted:?}"
    );
    // With one shared set the fit came within 3% of the point-sampled error at every seed.
    for (f, p) in fitted.iter().zip(&point) {
        assert!(f < &(0.8 * p), "least squares {f:.4} against point {p:.4}");
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (fit_mean, point_mean) = (mean(&fitted), mean(&point));
    assert!(
        fit_mean < 0.7 * point_mean,
        "least squares {fit_mean:.4} against point {point_mean:.4}"
    );
}

/// The fit with bounces on both backends: the direct pass and the gather at the surface points
/// run on each backend, the fit on the CPU for both; they agree as the vertex bakes do (a few
/// rays in 10^5 may differ, moving at most 1e-4 of the gather weight).
#[test]
fn least_squares_interreflection_agrees_on_cpu_and_gpu() {
    if common::gpu_baker().is_none() {
        return;
    }
    let options = BakeOptions {
        bands: 3,
        samples: 128,
        mode: Mode::Interreflected,
        fit: Fit::LeastSquares,
        ..BakeOptions::default()
    };
    let scene = plane_with_thin_box();
    let results: Vec<_> = common::backends()
        .iter()
        .map(|backend| bake(scene.clone(), &options, backend.as_ref(), &NoProgress).unwrap())
        .collect();
    let (cpu, gpu) = (&results[0].0.transfer, &results[1].0.transfer);
    let (size, difference) = size_and_difference(cpu.coeffs(), gpu.coeffs());
    eprintln!(
        "least-squares interreflection: CPU and GPU differ by {difference:.2e} of {size:.2e}"
    );
    assert!(results[0].1.bounces.len() == 3 && results[1].1.bounces.len() == 3);
    assert!(difference <= 1e-3 * size, "{difference} of {size}");
}

#[test]
fn spread_points_give_every_triangle_support() {
    let (scene, _) = prepare(plane_with_thin_box()).unwrap();
    let points = spread_points(&scene, PointDensity::default(), 1);
    let mut seen = vec![false; scene.triangle_count()];
    points.iter().for_each(|p| seen[p.triangle as usize] = true);
    assert!(seen.iter().all(|&s| s));
}

/// Texels with bounces on both backends: each texel's direct pass and its final gather from
/// the vertices run on each backend; the lightmaps agree as the vertex bakes do.
#[test]
fn interreflected_texels_agree_on_cpu_and_gpu() {
    if common::gpu_baker().is_none() {
        return;
    }
    let options = BakeOptions {
        bands: 3,
        samples: 64,
        mode: Mode::Interreflected,
        lightmap: Some(64),
        ..BakeOptions::default()
    };
    let scene = plane_with_thin_box();
    let maps: Vec<Vec<f32>> = common::backends()
        .iter()
        .map(|backend| {
            let (baked, _) = bake(scene.clone(), &options, backend.as_ref(), &NoProgress).unwrap();
            baked.lightmap.unwrap().transfer.into_coeffs()
        })
        .collect();
    let (size, difference) = size_and_difference(&maps[0], &maps[1]);
    eprintln!("interreflected texels: CPU and GPU differ by {difference:.2e} of {size:.2e}");
    assert!(
        size > 0.0 && difference <= 1e-3 * size,
        "{difference} of {size}"
    );
}

/// RMS of `a`, and RMS of `a - b`.
fn size_and_difference(a: &[f32], b: &[f32]) -> (f64, f64) {
    let rms = |values: &mut dyn Iterator<Item = f64>| {
        let (sum, n) = values.fold((0.0, 0), |(s, n), x| (s + x * x, n + 1));
        (sum / n as f64).sqrt()
    };
    let size = rms(&mut a.iter().map(|&x| x as f64));
    let difference = rms(&mut a.iter().zip(b).map(|(&x, &y)| (x - y) as f64));
    (size, difference)
}
