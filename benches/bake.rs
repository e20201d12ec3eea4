//! Shadowed bake of dragon_vrip_res3 (23k vertices, 1024 samples, 4 bands): rays per second of
//! the direct-transfer pass on the CPU backend (direction-major ray packets, and the plain
//! vertex-major single-ray order they replaced) and, where an adapter exists, the GPU backend,
//! side by side in one run (the machine is shared and noisy: compare ratios, not absolutes).
//! A second group does the same on the CPU for the cosine set (the default), whose packets are
//! fans from one vertex.
//!
//! Run: `cargo bench --bench bake` (criterion reports the throughput in rays/s).
//! PRT_GPU_BENCH_ADAPTER=name picks the adapter; without any adapter the GPU entry is skipped.
//! PRT_GPU_BENCH_SKIP_GPU=1 skips it too (on lavapipe it takes minutes).

use std::path::PathBuf;
use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion, Throughput};
use prt_gpu::bake::gpu::{self, Chunking, GpuBaker};
use prt_gpu::bake::{cpu, BakeInputs, DirectInputs, Mode, NoProgress};
use prt_gpu::device::DeviceChoice;
use prt_gpu::sampling::Sampling;
use prt_gpu::scene::{self, prepare::prepare, Scene};

fn dragon() -> Scene {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/dragon_vrip_res3.ply.gz");
    prepare(scene::load(&path).expect("dragon"))
        .expect("prepare")
        .0
}

/// A group timing the CPU's direct pass on `inputs` in packets (`packets`: the entry's name)
/// and in single rays, with rays/s as the throughput.
fn cpu_group<'c>(
    c: &'c mut Criterion,
    name: &str,
    inputs: &DirectInputs,
    packets: &str,
) -> BenchmarkGroup<'c, WallTime> {
    let (_, rays) = cpu::direct_transfer(inputs, Mode::Shadowed, &NoProgress);
    let mut group = c.benchmark_group(name);
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(30));
    group.throughput(Throughput::Elements(rays));
    group.bench_function(packets, |b| {
        b.iter(|| cpu::direct_transfer(inputs, Mode::Shadowed, &NoProgress))
    });
    group.bench_function("cpu single rays", |b| {
        b.iter(|| cpu::direct_transfer_single_rays(inputs, Mode::Shadowed, &NoProgress))
    });
    group
}

fn cosine_dragon(c: &mut Criterion) {
    let owned = BakeInputs::with_sampling(&dragon(), 4, 1024, 1, Sampling::Cosine);
    let name = "dragon_vrip_res3 shadowed 1024 cosine samples 4 bands";
    cpu_group(c, name, &owned.view(), "cpu fans").finish();
}

fn shadowed_dragon(c: &mut Criterion) {
    let mesh = dragon();
    let owned = BakeInputs::new(&mesh, 4, 1024, 1);
    let inputs = owned.view();
    let name = "dragon_vrip_res3 shadowed 1024 samples 4 bands";
    let mut group = cpu_group(c, name, &inputs, "cpu packets");

    if std::env::var_os("PRT_GPU_BENCH_SKIP_GPU").is_some() {
        group.finish();
        return;
    }
    let adapter = std::env::var("PRT_GPU_BENCH_ADAPTER").ok();
    match prt_gpu::device::open(DeviceChoice::Gpu, adapter.as_deref()) {
        Ok(Some(context)) => {
            let name = format!("gpu {}", context.adapter.label());
            let baker = GpuBaker::new(context).expect("compile kernels");
            group.measurement_time(Duration::from_secs(120));
            group.bench_function(name, |b| {
                b.iter(|| {
                    gpu::direct_transfer(
                        &baker,
                        &inputs,
                        Mode::Shadowed,
                        Chunking::default(),
                        &NoProgress,
                    )
                    .expect("gpu bake")
                })
            });
        }
        Ok(None) => unreachable!("DeviceChoice::Gpu never falls back"),
        Err(e) => eprintln!("no GPU entry: {e}"),
    }
    group.finish();
}

criterion_group!(benches, shadowed_dragon, cosine_dragon);
criterion_main!(benches);
