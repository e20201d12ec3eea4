//! Shadowed bake of dragon_vrip_res3 (23k vertices, 1024 samples, 4 bands): rays per second of
//! the direct-transfer pass, the part that scales with samples x vertices.
//!
//! Run: `cargo bench --bench bake` (criterion reports the throughput in rays/s).

use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use prt_gpu::bake::{cpu, DirectInputs, Mode, NoProgress};
use prt_gpu::bvh::Bvh;
use prt_gpu::sampling::stratified_sphere;
use prt_gpu::scene::{self, prepare::prepare};
use prt_gpu::sh::ShTable;

fn shadowed_dragon(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/dragon_vrip_res3.ply.gz");
    let (mesh, _) = prepare(scene::load(&path).expect("dragon")).expect("prepare");
    let normals = mesh.normals.clone().unwrap();
    let bvh = Bvh::build(&mesh.positions, &mesh.triangles);
    let samples = stratified_sphere(1024, 1);
    let table = ShTable::new(4, &samples.directions);
    let origins = prt_gpu::bake::ray_origins(&mesh.positions, &normals, &bvh);
    let inputs = DirectInputs {
        origins: &origins,
        normals: &normals,
        bvh: &bvh,
        samples: &samples,
        table: &table,
    };
    let (_, rays) = cpu::direct_transfer(&inputs, Mode::Shadowed, &NoProgress);

    let mut group = c.benchmark_group("dragon_vrip_res3 shadowed 1024 samples 4 bands");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(40));
    group.throughput(Throughput::Elements(rays));
    group.bench_function("cpu", |b| {
        b.iter(|| cpu::direct_transfer(&inputs, Mode::Shadowed, &NoProgress))
    });
    group.finish();
}

criterion_group!(benches, shadowed_dragon);
criterion_main!(benches);
