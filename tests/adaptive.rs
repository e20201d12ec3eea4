//! Baking to an error target: rays go where the scene needs them, and the error reached matches
//! the error asked for, against a converged bake.

mod common;

use glam::Vec3;
use prt_gpu::bake::adaptive::TargetError;
use prt_gpu::bake::{bake, BakeOptions, BakedMesh, CpuBackend, GpuBackend, Mode, NoProgress};
use prt_gpu::scene::{builtin, Scene};
use prt_gpu::sh::{coeff_count, unshadowed_transfer};

/// A ground plane whose left half is open and whose right half has a slot as deep as it is
/// wide (two walls 0.6 apart, 0.6 high): its floor sees half its sky, where an estimate
/// varies most (a receiver that sees nothing has nothing to estimate).
fn open_and_slotted() -> Scene {
    let ground = builtin::grid_plane(Vec3::ZERO, Vec3::X * 2.0, Vec3::NEG_Z * 1.0, 16, Vec3::ONE);
    let wall = |z0: f32, z1: f32| {
        builtin::closed_box(Vec3::new(0.25, -0.1, z0), Vec3::new(2.2, 0.6, z1), 2)
    };
    builtin::merge(&[ground, wall(-0.9, -0.3), wall(0.3, 0.9)])
}

const BANDS: u32 = 3;

fn bake_with(scene: &Scene, options: BakeOptions) -> BakedMesh {
    let options = BakeOptions {
        bands: BANDS,
        mode: Mode::Shadowed,
        albedo: Some(Vec3::ONE),
        ..options
    };
    bake(scene.clone(), &options, &CpuBackend, &NoProgress)
        .unwrap()
        .0
}

/// The red channel's transfer of vertex `v` (albedo one: the albedo-free transfer).
fn transfer_of(baked: &BakedMesh, v: usize) -> &[f32] {
    baked.transfer.vertex_channel(v, 0)
}

/// The norm of unoccluded transfer (the same for every normal): what errors are relative to.
fn open_norm() -> f64 {
    unshadowed_transfer(BANDS, glam::DVec3::Y)
        .iter()
        .map(|x| x * x)
        .sum::<f64>()
        .sqrt()
}

/// Which prepared vertices are open ground, which the slot's floor.
fn open_and_slot(scene: &Scene) -> (Vec<usize>, Vec<usize>) {
    let positions = &scene.positions;
    let on_ground = |v: usize| positions[v].y.abs() < 1e-6;
    let open = (0..positions.len())
        .filter(|&v| on_ground(v) && positions[v].x < -0.5)
        .collect();
    let slot = (0..positions.len())
        .filter(|&v| on_ground(v) && positions[v].x > 0.5 && positions[v].z.abs() < 0.2)
        .collect();
    (open, slot)
}

/// The median of the samples the receivers of `group` cast.
fn median_samples(samples: &[u32], group: &[usize]) -> u32 {
    let mut s: Vec<u32> = group.iter().map(|&v| samples[v]).collect();
    s.sort_unstable();
    s[s.len() / 2]
}

#[test]
fn open_receivers_stop_early_and_every_receiver_meets_the_target() {
    let scene = open_and_slotted();
    let target = TargetError {
        relative: 0.005,
        max_samples: 16_384,
    };
    let (adaptive, report) = bake(
        scene.clone(),
        &BakeOptions {
            bands: BANDS,
            mode: Mode::Shadowed,
            albedo: Some(Vec3::ONE),
            target_error: Some(target),
            seed: 3,
            ..BakeOptions::default()
        },
        &CpuBackend,
        &NoProgress,
    )
    .unwrap();
    let converged = bake_with(
        &scene,
        BakeOptions {
            samples: 65_536,
            seed: 99,
            ..BakeOptions::default()
        },
    );
    let open_norm = open_norm();
    let (open, slot) = open_and_slot(&adaptive.scene);
    assert!(
        open.len() > 20 && slot.len() > 3,
        "{} open, {} slot",
        open.len(),
        slot.len()
    );

    // Far fewer rays under open sky than in the slot.
    let samples = &report.adaptive.as_ref().unwrap().per_receiver;
    let median = |group: &[usize]| median_samples(samples, group);
    eprintln!(
        "median samples: open {}, slot {}",
        median(&open),
        median(&slot)
    );
    assert!(4 * median(&open) <= median(&slot));

    let error = |v: usize| -> f64 {
        let a = transfer_of(&adaptive, v);
        let c = transfer_of(&converged, v);
        let squares: f64 = a.iter().zip(c).map(|(x, y)| ((x - y) as f64).powi(2)).sum();
        squares.sqrt() / open_norm
    };
    for (name, group) in [("open", &open), ("slot", &slot)] {
        let errors: Vec<f64> = group.iter().map(|&v| error(v)).collect();
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        let within = |k: f64| {
            errors.iter().filter(|&&e| e <= k * target.relative).count() as f64
                / errors.len() as f64
        };
        eprintln!(
            "{name}: {} receivers, RMS error {rms:.4} for a target of {}; within 1x {:.2}, 2x {:.2}, 3x {:.2}",
            errors.len(),
            target.relative,
            within(1.0),
            within(2.0),
            within(3.0)
        );
        // The estimate is honest: the error reached is the error asked for, on average.
        assert!(rms <= 1.5 * target.relative, "{name}: RMS error {rms}");
        assert!(
            within(3.0) >= 0.95,
            "{name}: coverage at 3x {}",
            within(3.0)
        );
    }
}

#[test]
fn the_slot_gets_more_rays_than_the_open_ground() {
    // Bake each group's receivers alone through the least-squares-free path: the report's
    // samples of a scene made only of open ground against one made of the slot.
    let target = TargetError {
        relative: 0.02,
        max_samples: 16_384,
    };
    let samples_of = |scene: Scene| {
        let options = BakeOptions {
            bands: BANDS,
            target_error: Some(target),
            ..BakeOptions::default()
        };
        bake(scene, &options, &CpuBackend, &NoProgress)
            .unwrap()
            .1
            .adaptive
            .unwrap()
    };
    let open = samples_of(builtin::grid_plane(
        Vec3::ZERO,
        Vec3::X,
        Vec3::NEG_Z,
        4,
        Vec3::ONE,
    ));
    let slotted = samples_of(open_and_slotted());
    eprintln!("open plane: {open:?}\nwith the slot: {slotted:?}");
    // The open plane's receivers all stop at the floor of batches.
    assert_eq!(open.samples_max, open.samples_min);
    assert!(slotted.samples_max >= 4 * open.samples_max);
}

#[test]
fn an_error_targeted_bake_is_deterministic() {
    let scene = open_and_slotted();
    let options = BakeOptions {
        target_error: Some(TargetError {
            relative: 0.05,
            max_samples: 2048,
        }),
        ..BakeOptions::default()
    };
    let a = bake_with(&scene, options.clone());
    let b = bake_with(&scene, options);
    assert_eq!(a.transfer.coeffs(), b.transfer.coeffs());
    assert_eq!(a.metadata, b.metadata);
    assert_eq!(
        a.transfer.coeffs().len(),
        a.scene.vertex_count() * 3 * coeff_count(BANDS)
    );
}

#[test]
fn bad_targets_are_refused() {
    let scene = open_and_slotted();
    for relative in [0.0, 2.0, f64::NAN] {
        let options = BakeOptions {
            target_error: Some(TargetError {
                relative,
                max_samples: 4096,
            }),
            ..BakeOptions::default()
        };
        let error = bake(scene.clone(), &options, &CpuBackend, &NoProgress).unwrap_err();
        assert!(error.to_string().contains("--target-error"), "{error}");
    }
}

/// Interreflected transfer to an error target: the slot's floor, lit by its walls, casts more
/// rays than the open ground, and every receiver's transfer — its direct light and two
/// bounces gathered through the rays the target chose — is within the target of a converged
/// interreflected bake (RMS over each group), as shadowed transfer is.
#[test]
fn an_interreflected_bake_to_an_error_target_meets_it() {
    let scene = open_and_slotted();
    let target = TargetError {
        relative: 0.005,
        max_samples: 16_384,
    };
    let options = BakeOptions {
        bands: BANDS,
        mode: Mode::Interreflected,
        albedo: Some(Vec3::splat(0.8)),
        bounces: 2,
        ..BakeOptions::default()
    };
    let (adaptive, report) = bake(
        scene.clone(),
        &BakeOptions {
            target_error: Some(target),
            seed: 3,
            ..options.clone()
        },
        &CpuBackend,
        &NoProgress,
    )
    .unwrap();
    let converged = bake(
        scene.clone(),
        &BakeOptions {
            samples: 65_536,
            seed: 99,
            ..options.clone()
        },
        &CpuBackend,
        &NoProgress,
    )
    .unwrap()
    .0;
    let direct_only = bake(
        scene,
        &BakeOptions {
            samples: 65_536,
            seed: 99,
            bounces: 0,
            ..options
        },
        &CpuBackend,
        &NoProgress,
    )
    .unwrap()
    .0;
    let open_norm = open_norm();
    let (open, slot) = open_and_slot(&adaptive.scene);
    let samples = &report.adaptive.as_ref().unwrap().per_receiver;
    let median = |group: &[usize]| median_samples(samples, group);
    eprintln!(
        "median samples: open {}, slot {}",
        median(&open),
        median(&slot)
    );
    assert!(4 * median(&open) <= median(&slot));
    // Red channel over the albedo: the albedo-free transfer with its bounces.
    let scaled = |baked: &BakedMesh, v: usize| -> Vec<f64> {
        transfer_of(baked, v)
            .iter()
            .map(|&x| x as f64 / 0.8)
            .collect()
    };
    let rms = |group: &[usize], a: &BakedMesh, b: &BakedMesh| -> f64 {
        let squares: f64 = group
            .iter()
            .map(|&v| {
                let (x, y) = (scaled(a, v), scaled(b, v));
                x.iter().zip(&y).map(|(x, y)| (x - y).powi(2)).sum::<f64>()
            })
            .sum();
        (squares / group.len() as f64).sqrt() / open_norm
    };
    for (name, group) in [("open", &open), ("slot", &slot)] {
        let error = rms(group, &adaptive, &converged);
        let bounced = rms(group, &converged, &direct_only);
        eprintln!(
            "interreflected {name}: {} receivers, median {} samples, RMS error {error:.4} for a \
             target of {}; the bounces add {bounced:.4}",
            group.len(),
            median(group),
            target.relative
        );
        assert!(error <= 1.5 * target.relative, "{name}: RMS error {error}");
    }
}

/// The GPU bakes to an error target with the CPU's batches: each receiver stops after the same
/// batch (but for one whose error lands within float rounding of the target), and its transfer
/// is the CPU's to float rounding; interreflected too, where the bounces gather through the
/// batches' closest hits on each backend.
#[test]
fn an_error_targeted_bake_on_the_gpu_is_the_cpus() {
    let Some(baker) = common::gpu_baker() else {
        return;
    };
    for mode in [Mode::Shadowed, Mode::Interreflected] {
        gpu_and_cpu_agree_on_a_target(baker, mode);
    }
}

fn gpu_and_cpu_agree_on_a_target(baker: &prt_gpu::bake::gpu::GpuBaker, mode: Mode) {
    let scene = open_and_slotted();
    let options = BakeOptions {
        bands: BANDS,
        mode,
        albedo: Some(Vec3::ONE),
        target_error: Some(TargetError {
            relative: 0.01,
            max_samples: 4096,
        }),
        seed: 5,
        ..BakeOptions::default()
    };
    let (cpu, cpu_report) = bake(scene.clone(), &options, &CpuBackend, &NoProgress).unwrap();
    let gpu_backend = GpuBackend::new(baker);
    let (gpu, gpu_report) = bake(scene, &options, &gpu_backend, &NoProgress).unwrap();
    assert!(
        gpu.metadata.backend.starts_with("gpu"),
        "{}",
        gpu.metadata.backend
    );
    let (cpu_samples, gpu_samples) = (
        &cpu_report.adaptive.as_ref().unwrap().per_receiver,
        &gpu_report.adaptive.as_ref().unwrap().per_receiver,
    );
    let receivers = cpu_samples.len();
    let differing = cpu_samples
        .iter()
        .zip(gpu_samples)
        .filter(|(c, g)| c != g)
        .count();
    assert!(differing * 100 <= receivers, "{differing} of {receivers}");
    // The open receivers stop early and the slotted ones go on, on both.
    let (fewest, most) = (
        gpu_samples.iter().min().unwrap(),
        gpu_samples.iter().max().unwrap(),
    );
    assert!(most >= &(4 * fewest), "{fewest}..{most}");
    let (mut compared, mut largest) = (0, 0.0f32);
    for v in 0..receivers {
        if cpu_samples[v] != gpu_samples[v] {
            continue;
        }
        for (c, g) in transfer_of(&cpu, v).iter().zip(transfer_of(&gpu, v)) {
            assert!(
                (c - g).abs() <= 1e-5 * (1.0 + c.abs()),
                "vertex {v}: {c} vs {g}"
            );
            largest = largest.max((c - g).abs());
        }
        compared += 1;
    }
    eprintln!(
        "{mode:?}: {differing} of {receivers} receivers stop after another batch; {compared} \
         compared, largest difference {largest:.2e}; rays {} (cpu) and {} (gpu)",
        cpu_report.rays_cast, gpu_report.rays_cast
    );
    assert!(compared > 100, "{compared}");
}
