//! What the order of a tangent-frame sample set costs: the shadowed direct-transfer pass of
//! dragon_vrip_res3 (1024 cosine samples, 4 bands) with the same samples in three orders,
//! alternating, on the CPU backend and (with an adapter) the GPU backend:
//!
//! - `lattice`: the Fibonacci lattice's own order, consecutive samples a golden angle apart;
//! - `morton 3d`: Morton order of the directions in their bounding box;
//! - `morton disk`: Morton order on the unit disk of Malley's lift, the order the bake uses.
//!
//! Every order gives the same transfer up to summation order. Reports rays per wall-second and,
//! for the GPU (lavapipe runs its threads in this process), per CPU-second. The CPU casts
//! runs of samples that `SampleSet::fan_runs` forms by direction, whatever the stored order,
//! so its figures are the control.
//!
//! ```sh
//! XDG_RUNTIME_DIR=/tmp cargo run --release --example sample_order -- [rounds]
//! ```

use std::path::PathBuf;
use std::time::Instant;

use prt_gpu::bake::gpu::{self, Chunking, GpuBaker};
use prt_gpu::bake::{cpu, BakeInputs, Mode, NoProgress};
use prt_gpu::device::DeviceChoice;
use prt_gpu::morton::morton_order;
use prt_gpu::sampling::{cosine_hemisphere, cosine_hemisphere_lattice_order, SampleSet, Sampling};
use prt_gpu::scene::{self, prepare::prepare};
use prt_gpu::sh::ShTable;

mod common;
use common::cpu_seconds;

fn main() {
    let rounds: usize = std::env::args()
        .nth(1)
        .map_or(2, |a| a.parse().expect("rounds"));
    let (samples, bands, seed) = (1024, 4, 1);
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/dragon_vrip_res3.ply.gz");
    let (mesh, _) = prepare(scene::load(&path).expect("dragon")).expect("prepare");

    let lattice = cosine_hemisphere_lattice_order(samples, seed);
    let morton_3d = SampleSet::new(
        morton_order(&lattice.directions)
            .into_iter()
            .map(|i| lattice.directions[i as usize])
            .collect(),
        lattice.weight,
        lattice.frame,
    );
    let orders = [
        ("lattice", lattice),
        ("morton 3d", morton_3d),
        ("morton disk", cosine_hemisphere(samples, seed)),
    ];
    let inputs: Vec<(&str, BakeInputs)> = orders
        .into_iter()
        .map(|(name, set)| {
            let mut owned =
                BakeInputs::with_sampling(&mesh, bands, samples, seed, Sampling::Cosine);
            owned.table = ShTable::new(bands, &set.directions);
            owned.samples = set;
            (name, owned)
        })
        .collect();

    let baker = prt_gpu::device::open(DeviceChoice::Gpu, None)
        .ok()
        .flatten()
        .map(|context| GpuBaker::new(context).expect("compile kernels"));
    match &baker {
        Some(b) => eprintln!("adapter: {}", b.context.adapter.label()),
        None => eprintln!("no adapter: CPU only"),
    }

    for round in 1..=rounds {
        for (name, owned) in &inputs {
            let view = owned.view();
            let start = Instant::now();
            let (_, rays) = cpu::direct_transfer(&view, Mode::Shadowed, &NoProgress);
            let cpu_wall = start.elapsed().as_secs_f64();
            let mut line = format!(
                "round {round} {name:>11}: cpu {:.2} M rays/s",
                rays as f64 / cpu_wall / 1e6
            );
            if let Some(baker) = &baker {
                let (start, cpu_start) = (Instant::now(), cpu_seconds());
                gpu::direct_transfer(
                    baker,
                    &view,
                    Mode::Shadowed,
                    Chunking::default(),
                    &NoProgress,
                )
                .expect("gpu bake");
                let (wall, cpu) = (start.elapsed().as_secs_f64(), cpu_seconds() - cpu_start);
                line += &format!(
                    ", gpu {:.2} M rays/s ({:.2} M per CPU-second)",
                    rays as f64 / wall / 1e6,
                    rays as f64 / cpu / 1e6
                );
            }
            println!("{line}");
        }
    }
}
