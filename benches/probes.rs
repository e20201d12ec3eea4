//! Probes around dragon_vrip_res3 on the CPU backend, side by side in one run (compare ratios;
//! the machine is shared and noisy): baking probes (each casts its samples over the whole
//! sphere) against baking the vertices (over their hemisphere), per receiver, at 1,024 samples
//! and 4 bands; and relighting 10,000 probes, as a run-time would once a frame, in each form.
//!
//! The GPU entries (relighting: the matrices uploaded once, each frame the light uploaded and
//! the relit SH read back) run on any adapter (PRT_GPU_BENCH_ADAPTER=name picks one;
//! PRT_GPU_BENCH_SKIP_GPU=1 skips them).
//!
//! Run: `cargo bench --bench probes` (criterion reports probes, vertices or relit probes per s).

use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use prt_gpu::bake::{self, cpu, BakeInputs, BakeOptions, CpuBackend, Mode, NoProgress};
use prt_gpu::device::DeviceChoice;
use prt_gpu::probes::{self, ProbeForm, ProbePlacement, ProbeSpec};
use prt_gpu::sampling::{Pcg32, Sampling};
use prt_gpu::scene;

const SAMPLES: u32 = 1024;

/// The dragon baked (shadowed, 4 bands), and `count` random points in its bounding box.
fn dragon_and_points(count: usize) -> (bake::BakedMesh, Vec<[f32; 3]>) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/dragon_vrip_res3.ply.gz");
    let mesh = scene::load(&path).expect("dragon");
    let options = BakeOptions {
        samples: 16,
        ..BakeOptions::default()
    };
    let (baked, _) = bake::bake(mesh, &options, &CpuBackend, &NoProgress).expect("bake");
    let (lo, hi) = baked.scene.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let mut random = Pcg32::new(3);
    let mut next = || random.next_f32();
    let points = (0..count)
        .map(|_| (lo + (hi - lo) * Vec3::new(next(), next(), next())).to_array())
        .collect();
    (baked, points)
}

fn bake_probes_against_vertices(c: &mut Criterion) {
    let count = 2000;
    let (baked, points) = dragon_and_points(count);
    let mut group =
        c.benchmark_group("dragon_vrip_res3 shadowed 1024 samples 4 bands, per receiver");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(20));
    group.throughput(Throughput::Elements(count as u64));
    let spec = ProbeSpec {
        placement: ProbePlacement::Points(points),
        form: ProbeForm::Radiance,
    };
    group.bench_function("probes (sphere)", |b| {
        b.iter(|| probes::bake_probes(&baked, &spec, (SAMPLES, 1), &CpuBackend, &NoProgress))
    });
    let mesh = &baked.scene;
    let inputs = BakeInputs::with_sampling(mesh, 4, SAMPLES, 1, Sampling::Stratified);
    group.throughput(Throughput::Elements(mesh.vertex_count() as u64));
    group.bench_function("vertices (stratified sphere, hemisphere cast)", |b| {
        b.iter(|| cpu::direct_transfer(&inputs.view(), Mode::Shadowed, &NoProgress))
    });
    group.finish();
}

fn relight_probes(c: &mut Criterion) {
    let count = 10_000;
    let gpu = match std::env::var_os("PRT_GPU_BENCH_SKIP_GPU") {
        Some(_) => None,
        None => {
            let adapter = std::env::var("PRT_GPU_BENCH_ADAPTER").ok();
            prt_gpu::device::open(DeviceChoice::Gpu, adapter.as_deref())
                .inspect_err(|e| eprintln!("no GPU entry: {e}"))
                .ok()
                .flatten()
        }
    };
    let mut group = c.benchmark_group("relight 10,000 probes, 4 bands, RGB");
    group.sample_size(20);
    group.throughput(Throughput::Elements(count as u64));
    for form in [ProbeForm::Radiance, ProbeForm::Irradiance] {
        let rows = match form {
            ProbeForm::Radiance => 16,
            ProbeForm::Irradiance => 9,
        };
        let set = probes::ProbeSet {
            bands: 4,
            channels: 3,
            form,
            rows,
            grid: None,
            positions: vec![Vec3::ZERO; count],
            status: vec![probes::ProbeStatus::Placed; count],
            matrices: (0..count * 3 * rows * 16)
                .map(|i| (i % 7) as f32 * 0.1)
                .collect(),
            samples: SAMPLES,
        };
        let light = vec![[0.5f32, 0.4, 0.3]; 16];
        group.bench_function(format!("cpu, {} form", form.name()), |b| {
            b.iter(|| set.relight(&light))
        });
        if let Some(context) = &gpu {
            let uploaded = probes::gpu::GpuProbes::new(context, &set).expect("upload");
            let name = format!("gpu {}, {} form", context.adapter.label(), form.name());
            group.bench_function(name, |b| {
                b.iter(|| uploaded.relight(&light).expect("relight"))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bake_probes_against_vertices, relight_probes);
criterion_main!(benches);
