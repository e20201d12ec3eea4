//! Zonal (LDPRT) transfer on dragon_vrip_res3, side by side in one run (compare ratios; the
//! machine is shared and noisy): relighting every vertex from its SH transfer (a dot product
//! per channel) against relighting it from its zonal transfer (the SH basis at the vertex's
//! axis, then the zonal lobe's dot product), at 4 and 6 bands; and the fit itself, about the
//! normal and about the fitted axis.
//!
//! Run: `cargo bench --bench zonal` (criterion reports vertices per s).

use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use prt_gpu::bake::{self, BakeOptions, CpuBackend, NoProgress};
use prt_gpu::compress;
use prt_gpu::light::preview_light;
use prt_gpu::scene;
use prt_gpu::zonal::{ZonalAxis, ZonalSpec, ZonalTransfer};

/// The dragon baked shadowed at `bands` bands from 16 samples (the values do not matter).
fn dragon(bands: u32) -> bake::BakedMesh {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/dragon_vrip_res3.ply.gz");
    let mesh = scene::load(&path).expect("dragon");
    let options = BakeOptions {
        samples: 16,
        bands,
        ..BakeOptions::default()
    };
    bake::bake(mesh, &options, &CpuBackend, &NoProgress)
        .expect("bake")
        .0
}

fn relight_and_fit(c: &mut Criterion) {
    for bands in [4, 6] {
        let baked = dragon(bands);
        let normals = baked.scene.normals.as_deref().expect("prepared normals");
        let light = preview_light(bands).expect("light");
        let mut group = c.benchmark_group(format!("dragon_vrip_res3 {bands} bands, per vertex"));
        group.sample_size(20);
        group.warm_up_time(Duration::from_secs(1));
        group.measurement_time(Duration::from_secs(5));
        group.throughput(Throughput::Elements(baked.transfer.vertex_count() as u64));
        group.bench_function("relight SH transfer", |b| {
            b.iter(|| compress::radiance(&baked.transfer, &light))
        });
        for axis in [ZonalAxis::Normal, ZonalAxis::Fitted] {
            let spec = ZonalSpec { bands, axis };
            let zonal = ZonalTransfer::fit(&baked.transfer, normals, spec).expect("fit");
            group.bench_function(
                format!("relight zonal transfer ({} axis)", axis.name()),
                |b| b.iter(|| zonal.relight(zonal.axes(), &light).expect("relight")),
            );
            group.bench_function(format!("fit about the {} axis", axis.name()), |b| {
                b.iter(|| ZonalTransfer::fit(&baked.transfer, normals, spec).expect("fit"))
            });
        }
        group.finish();
    }
}

criterion_group!(benches, relight_and_fit);
criterion_main!(benches);
