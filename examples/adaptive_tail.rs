//! Rays against the *largest* errors: what an error-targeted bake costs to bound every
//! receiver's error as tightly as today's default bounds most of them (docs/performance.md,
//! "Error targets").
//!
//! `--target-error E` promises each receiver a standard error below E; it does not promise a
//! lower RMS error per ray (`examples/adaptive_bound.rs` shows no allocation can). This example
//! measures the promise it does make. Each receiver's error is the one `--target-error` speaks
//! of: the L2 norm of its transfer's error against a 16,384-sample reference, relative to the
//! norm of unoccluded transfer. For fixed-count bakes (cosine lattice, control variate off, as
//! the default) and for error-targeted bakes it prints the mean samples per receiver and the
//! quantiles of that error over receivers, then, for each quantile, the samples the
//! error-targeted bake needs to reach the default's (1024 samples) value of it, interpolated
//! log-log between the targets measured, as a fraction of 1024.
//!
//! `cargo run --release --example adaptive_tail [MESH]` (default: the built-in scene).

use std::path::Path;

use prt_gpu::bake::adaptive::{adaptive_direct_pass, TargetError};
use prt_gpu::bake::{Backend, BakeInputs, CpuBackend, Mode, NoProgress};
use prt_gpu::sampling::{Estimator, Sampling};

const BANDS: u32 = 4;
const DEFAULT_SAMPLES: u32 = 1024;
const FIXED_SAMPLES: [u32; 4] = [256, 512, 1024, 2048];
const TARGETS: [f64; 7] = [0.03, 0.02, 0.015, 0.01, 0.007, 0.005, 0.0035];
const REFERENCE_SAMPLES: u32 = 16_384;
const SEED: u64 = 1;
const QUANTILES: [(&str, f64); 5] = [
    ("median", 0.5),
    ("p90", 0.9),
    ("p99", 0.99),
    ("p99.9", 0.999),
    ("max", 1.0),
];

/// One bake: mean samples per receiver and the sorted per-receiver errors.
struct Row {
    label: String,
    samples: f64,
    sorted_errors: Vec<f64>,
}

impl Row {
    fn quantile(&self, q: f64) -> f64 {
        let last = self.sorted_errors.len() - 1;
        self.sorted_errors[((q * last as f64).round() as usize).min(last)]
    }
}

fn main() -> prt_gpu::Result<()> {
    let scene = match std::env::args().nth(1) {
        Some(path) => prt_gpu::scene::load(Path::new(&path))?,
        None => prt_gpu::scene::builtin::default_scene(),
    };
    let (scene, _) = prt_gpu::scene::prepare::prepare(scene)?;
    let n = (BANDS * BANDS) as usize;
    let open_norm = prt_gpu::sh::unshadowed_transfer(BANDS, glam::DVec3::Z)
        .iter()
        .map(|t| t * t)
        .sum::<f64>()
        .sqrt();
    let fixed = |samples: u32, seed: u64| -> prt_gpu::Result<Vec<f32>> {
        let mut inputs = BakeInputs::with_sampling(&scene, BANDS, samples, seed, Sampling::Cosine);
        inputs.estimator = Estimator::Visible;
        Ok(CpuBackend
            .direct_pass(&inputs.view(), Mode::Shadowed, &NoProgress)?
            .scalar)
    };
    let reference = fixed(REFERENCE_SAMPLES, 99)?;
    let errors_of = |transfer: &[f32]| -> Vec<f64> {
        let mut errors: Vec<f64> = transfer
            .chunks_exact(n)
            .zip(reference.chunks_exact(n))
            .map(|(got, want)| {
                let square: f64 = got
                    .iter()
                    .zip(want)
                    .map(|(&g, &w)| (g as f64 - w as f64).powi(2))
                    .sum();
                square.sqrt() / open_norm
            })
            .collect();
        errors.sort_by(f64::total_cmp);
        errors
    };
    let mut rows = Vec::new();
    for samples in FIXED_SAMPLES {
        rows.push(Row {
            label: format!("cosine, {samples} fixed"),
            samples: samples as f64,
            sorted_errors: errors_of(&fixed(samples, SEED)?),
        });
    }
    let base = BakeInputs::with_sampling(&scene, BANDS, 1, SEED, Sampling::Cosine);
    let receivers = base.origins.len();
    for relative in TARGETS {
        let target = TargetError {
            relative,
            max_samples: REFERENCE_SAMPLES / 2,
        };
        let pass = adaptive_direct_pass(
            &CpuBackend,
            &base,
            0..receivers,
            (Sampling::Cosine, SEED, Mode::Shadowed),
            &target,
            &NoProgress,
        )?;
        let (transfer, report) = (pass.scalar, pass.adaptive.expect("a target's receivers"));
        let mean = report.samples.iter().map(|&s| s as f64).sum::<f64>() / receivers as f64;
        rows.push(Row {
            label: format!("target {relative}"),
            samples: mean,
            sorted_errors: errors_of(&transfer),
        });
    }

    println!(
        "{receivers} receivers, {BANDS} bands, shadowed; error: transfer L2 vs {REFERENCE_SAMPLES} samples, relative to unoccluded norm"
    );
    let names: Vec<&str> = QUANTILES.iter().map(|(name, _)| *name).collect();
    println!("| bake | mean samples | {} |", names.join(" | "));
    println!("|---|---:|{}", "---:|".repeat(QUANTILES.len()));
    for row in &rows {
        let values: Vec<String> = QUANTILES
            .iter()
            .map(|&(_, q)| format!("{:.2e}", row.quantile(q)))
            .collect();
        println!(
            "| {} | {:.0} | {} |",
            row.label,
            row.samples,
            values.join(" | ")
        );
    }
    let default = rows
        .iter()
        .find(|r| r.samples == DEFAULT_SAMPLES as f64)
        .expect("the default is among the fixed bakes");
    let targeted = &rows[FIXED_SAMPLES.len()..];
    println!();
    println!(
        "samples an error-targeted bake needs for the default's value, over {DEFAULT_SAMPLES}:"
    );
    for &(name, q) in &QUANTILES {
        let want = default.quantile(q);
        let needed = interpolate_samples(targeted, q, want);
        println!(
            "  {name}: {want:.2e} -> {}",
            needed.map_or("outside the targets measured".into(), |s| format!(
                "{:.0} samples, {:.2}",
                s,
                s / DEFAULT_SAMPLES as f64
            ))
        );
    }
    Ok(())
}

/// Mean samples at which the error-targeted rows (ordered by falling target) reach `want` at
/// quantile `q`, interpolated log-log between the two rows that bracket it.
fn interpolate_samples(rows: &[Row], q: f64, want: f64) -> Option<f64> {
    rows.windows(2).find_map(|pair| {
        let (a, b) = (&pair[0], &pair[1]);
        let (ea, eb) = (a.quantile(q), b.quantile(q));
        if !(ea >= want && want >= eb) || ea == eb {
            return None;
        }
        let t = (ea.ln() - want.ln()) / (ea.ln() - eb.ln());
        Some((a.samples.ln() + t * (b.samples.ln() - a.samples.ln())).exp())
    })
}
