//! How many rays could any per-receiver allocation save? (docs/performance.md, "Error targets")
//!
//! Bakes a mesh's shadowed transfer at a fixed sample count with several seeds and against a
//! high-sample reference, takes each vertex's relit-radiance error (preview light), and from
//! those errors computes what an oracle that knew every vertex's error in advance would need
//! to reach the fixed bake's RMS error, as a fraction of the fixed bake's rays:
//!
//! - **RMS-optimal** (Neyman) allocation, `n_i ~ e_i^(2/(2a+1))`:
//!   `mean(e^p)^(1 + 1/(2a)) / mean(e^2)^(1/(2a))`, `p = 2/(2a+1)`;
//! - **equal error** per vertex (what `--target-error` asks for), `n_i ~ e_i^(1/a)`:
//!   `mean(e^(1/a)) / mean(e^2)^(1/(2a))`;
//!
//! where each vertex's error falls as `n^-a`, `a` measured from the bakes at half and twice
//! the sample count. The per-vertex errors come from few seeds, and their noise makes the
//! vertices look more different than they are, so both bounds are optimistic (lower than
//! the truth). At `a = 1/2` the equal-error bound is exactly 1: giving every vertex the same
//! error never lowers the RMS error per ray, so ray savings at equal RMS error come from
//! better estimators (the control variate, lattices), not from where the rays go.
//!
//! `cargo run --release --example adaptive_bound [MESH]` (default: the built-in scene).

use std::path::Path;

use prt_gpu::bake::{Backend, BakeInputs, CpuBackend, Mode, NoProgress};
use prt_gpu::sampling::{Estimator, Sampling};

const BANDS: u32 = 4;
const SAMPLES: u32 = 1024;
const SEEDS: [u64; 4] = [1, 2, 3, 4];
const REFERENCE_SAMPLES: u32 = 16_384;

fn main() -> prt_gpu::Result<()> {
    let scene = match std::env::args().nth(1) {
        Some(path) => prt_gpu::scene::load(Path::new(&path))?,
        None => prt_gpu::scene::builtin::default_scene(),
    };
    let (scene, _) = prt_gpu::scene::prepare::prepare(scene)?;
    let light = prt_gpu::light::preview_light(BANDS)?;
    let relit = |samples: u32, seed: u64, estimator: Estimator| -> prt_gpu::Result<Vec<[f64; 3]>> {
        let mut inputs = BakeInputs::with_sampling(&scene, BANDS, samples, seed, Sampling::Cosine);
        inputs.estimator = estimator;
        let pass = CpuBackend.direct_pass(&inputs.view(), Mode::Shadowed, &NoProgress)?;
        let n = (BANDS * BANDS) as usize;
        Ok(pass
            .scalar
            .chunks_exact(n)
            .map(|t| {
                std::array::from_fn(|c| {
                    t.iter()
                        .zip(&light.coeffs)
                        .map(|(&t, l)| t as f64 * l[c] as f64)
                        .sum()
                })
            })
            .collect())
    };
    let reference = relit(REFERENCE_SAMPLES, 99, Estimator::Visible)?;
    println!("{} vertices, {BANDS} bands, shadowed, cosine lattice, {} seeds, reference {REFERENCE_SAMPLES} samples", reference.len(), SEEDS.len());
    println!("| estimator | RMS error at {SAMPLES} (relative) | rate a | Neyman oracle | equal-error oracle |");
    println!("|---|---|---|---|---|");
    for (name, estimator) in [
        ("visible (default)", Estimator::Visible),
        ("control variate", Estimator::Blocked),
    ] {
        let errors = |samples: u32| -> prt_gpu::Result<Vec<f64>> {
            per_vertex_errors(&reference, |seed| relit(samples, seed, estimator))
        };
        let at = errors(SAMPLES)?;
        let rms = |e: &[f64]| (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
        let rate = (rms(&errors(SAMPLES / 2)?) / rms(&errors(SAMPLES * 2)?)).log2() / 2.0;
        let reference_rms = rms(&reference
            .iter()
            .map(|r| (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt())
            .collect::<Vec<_>>());
        println!(
            "| {name} | {:.3e} | {rate:.2} | {:.2} | {:.2} |",
            rms(&at) / reference_rms,
            neyman(&at, rate),
            equal_error(&at, rate),
        );
    }
    Ok(())
}

/// Each vertex's RMS relit error over the seeds against `reference`.
fn per_vertex_errors(
    reference: &[[f64; 3]],
    bake: impl Fn(u64) -> prt_gpu::Result<Vec<[f64; 3]>>,
) -> prt_gpu::Result<Vec<f64>> {
    let mut squares = vec![0.0; reference.len()];
    for seed in SEEDS {
        for ((s, got), want) in squares.iter_mut().zip(bake(seed)?).zip(reference) {
            *s += (0..3).map(|c| (got[c] - want[c]).powi(2)).sum::<f64>();
        }
    }
    Ok(squares
        .iter()
        .map(|s| (s / SEEDS.len() as f64).sqrt())
        .collect())
}

fn mean_power(errors: &[f64], power: f64) -> f64 {
    errors.iter().map(|e| e.powf(power)).sum::<f64>() / errors.len() as f64
}

/// Rays of the RMS-optimal allocation at equal RMS error, over a uniform one's.
fn neyman(errors: &[f64], rate: f64) -> f64 {
    let p = 2.0 / (2.0 * rate + 1.0);
    mean_power(errors, p).powf(1.0 + 1.0 / (2.0 * rate))
        / mean_power(errors, 2.0).powf(1.0 / (2.0 * rate))
}

/// Rays of equal per-vertex errors at equal RMS error, over a uniform allocation's.
fn equal_error(errors: &[f64], rate: f64) -> f64 {
    mean_power(errors, 1.0 / rate) / mean_power(errors, 2.0).powf(1.0 / (2.0 * rate))
}
