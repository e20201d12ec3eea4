//! Times the GPU backend's shadowed direct-transfer pass (visibility + projection, read-back
//! included) on dragon_vrip_res3, 1024 samples, 4 bands, and reports rays per wall-second and
//! per CPU-second. lavapipe runs its shader threads inside this process, so the process's CPU
//! time (user + system, from /proc/self/stat) is what the kernel cost, whatever else runs on
//! the machine; on a shared machine compare CPU-seconds, not wall time.
//!
//! ```sh
//! XDG_RUNTIME_DIR=/tmp cargo run --release --example visibility_timing -- [rounds] [stride] [--verify]
//! ```
//! `stride` > 1 bakes every stride-th vertex only (a quicker, unbiased subset of the rays).
//! `--verify` also checks the GPU's visibility bits against the CPU backend's.
//! To compare two versions of the kernels, build this example in both and alternate the runs
//! (docs/performance.md).

use std::path::PathBuf;
use std::time::Instant;

use prt_gpu::bake::gpu::{self, Chunking, GpuBaker};
use prt_gpu::bake::{cpu, BakeInputs, Mode, NoProgress};
use prt_gpu::device::DeviceChoice;
use prt_gpu::scene::{self, prepare::prepare};

mod common;
use common::cpu_seconds;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let verify = args.iter().any(|a| a == "--verify");
    args.retain(|a| a != "--verify");
    let rounds: usize = args.first().map_or(3, |a| a.parse().expect("rounds"));
    let stride: usize = args.get(1).map_or(1, |a| a.parse().expect("stride"));

    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/dragon_vrip_res3.ply.gz");
    let (mesh, _) = prepare(scene::load(&path).expect("dragon")).expect("prepare");
    let mut owned = BakeInputs::new(&mesh, 4, 1024, 1);
    if stride > 1 {
        owned.origins = owned.origins.iter().copied().step_by(stride).collect();
        owned.normals = owned.normals.iter().copied().step_by(stride).collect();
    }
    let inputs = owned.view();

    let mut bakers: Vec<(String, GpuBaker)> = Vec::new();
    let open = || {
        prt_gpu::device::open(DeviceChoice::Gpu, None)
            .expect("adapter")
            .expect("gpu")
    };
    bakers.push(("built-in".into(), GpuBaker::new(open()).expect("compile")));
    eprintln!(
        "adapter: {}; {} vertices, {} samples",
        bakers[0].1.context.adapter.label(),
        inputs.origins.len(),
        inputs.samples.len()
    );

    if verify {
        let cpu_bits = cpu::visibility_bits(&inputs, Mode::Shadowed);
        for (name, baker) in &bakers {
            let (bits, _) = gpu::visibility_bits_and_transfer(
                baker,
                &inputs,
                Mode::Shadowed,
                Chunking::default(),
            )
            .expect("gpu bake");
            let differing: u32 = bits
                .iter()
                .zip(&cpu_bits)
                .map(|(g, c)| (g ^ c).count_ones())
                .sum();
            eprintln!("{name}: {differing} rays differ from the CPU");
        }
    }

    let mut results: Vec<Vec<(f64, f64)>> = vec![Vec::new(); bakers.len()];
    let mut rays = 0;
    for round in 0..rounds {
        for (i, (name, baker)) in bakers.iter().enumerate() {
            let (wall0, cpu0) = (Instant::now(), cpu_seconds());
            let (_, run) = gpu::direct_transfer(
                baker,
                &inputs,
                Mode::Shadowed,
                Chunking::default(),
                &NoProgress,
            )
            .expect("gpu bake");
            let (wall, cpu) = (wall0.elapsed().as_secs_f64(), cpu_seconds() - cpu0);
            rays = run.rays_cast;
            println!(
                "round {round} {name}: {:.2} wall-s {:.2} CPU-s  {:.3} M rays/wall-s  {:.3} M rays/CPU-s",
                wall,
                cpu,
                rays as f64 / wall / 1e6,
                rays as f64 / cpu / 1e6
            );
            results[i].push((wall, cpu));
        }
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!("{rays} rays per bake; medians:");
    for ((name, _), r) in bakers.iter().zip(&results) {
        let wall = median(r.iter().map(|x| x.0).collect());
        let cpu = median(r.iter().map(|x| x.1).collect());
        println!(
            "{name}: {wall:.2} wall-s {cpu:.2} CPU-s  {:.3} M rays/wall-s  {:.3} M rays/CPU-s",
            rays as f64 / wall / 1e6,
            rays as f64 / cpu / 1e6
        );
    }
}
