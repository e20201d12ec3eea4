//! Speed against accuracy: bakes of one scene over strategies, backends and sample counts,
//! each timed and compared with a high-sample reference bake. `prt-gpu chart` draws the result
//! (crate::chart) and writes it as CSV; `prt-gpu bench` times the backends side by side.

use std::collections::HashMap;
use std::path::Path;
use std::time::Instant;

use crate::bake::adaptive::TargetError;
use crate::bake::bounce::Hit;
use crate::bake::gpu::{Chunking, GpuBaker, GpuRun};
use crate::bake::texels::{bake_atlas, plan_atlas};
use crate::bake::Transfer;
use crate::bake::{
    bake, cpu, gpu, Backend, BakeOptions, CpuBackend, DirectInputs, Fit, Mode, NoProgress, Progress,
};
use crate::chart::{ChartPanel, ChartPoint, ChartSeries};
use crate::error::{Error, Result};
use crate::fs::write_atomically;
use crate::light::ShLight;
use crate::render::relight;
use crate::sampling::Sampling;
use crate::scene::Scene;
use crate::surface::{surface_error, surface_reference, texel_surface_error, SurfaceReference};

/// What to sweep.
#[derive(Clone, Debug)]
pub struct SweepOptions {
    pub bands: u32,
    pub mode: Mode,
    pub strategies: Vec<Sampling>,
    /// Requested sample counts (the grid strategies round them to squares).
    pub counts: Vec<u32>,
    pub reference_samples: u32,
    pub reference_sampling: Sampling,
    pub seed: u64,
    /// How vertex values are made; every strategy and count is baked with each.
    pub fits: Vec<Fit>,
    /// Held-out surface points of the surface error (0: four per vertex, at most 20,000).
    pub surface_points: usize,
    /// Lightmap sizes: every strategy and count of the point fit is also baked per texel at
    /// each.
    pub lightmap_sizes: Vec<u32>,
    /// Each lightmap of a cosine-sampled bake is also baked denoised (`bake --denoise`).
    pub denoise: bool,
    /// Error targets: each strategy is also baked to each (on the CPU backend, point fit).
    pub target_errors: Vec<f64>,
}

impl Default for SweepOptions {
    fn default() -> Self {
        SweepOptions {
            bands: 4,
            mode: Mode::Shadowed,
            strategies: Sampling::ALL.to_vec(),
            counts: vec![64, 256, 1024],
            reference_samples: 16_384,
            reference_sampling: Sampling::ControlVariate,
            seed: 1,
            fits: vec![Fit::Point, Fit::LeastSquares],
            surface_points: 0,
            lightmap_sizes: Vec::new(),
            denoise: false,
            target_errors: Vec::new(),
        }
    }
}

/// One bake of the sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepPoint {
    pub sampling: Sampling,
    pub fit: Fit,
    /// Per-texel bakes: the lightmap's size (the vertex errors are then those of its vertices,
    /// baked with `fit`).
    pub lightmap: Option<u32>,
    /// Per-texel bakes: whether the lightmap was denoised.
    pub denoised: bool,
    /// Error-targeted bakes: the target (`samples` is then the mean over receivers).
    pub target_error: Option<f64>,
    /// "cpu" or "gpu".
    pub backend: String,
    /// Samples actually used.
    pub samples: u32,
    /// Wall time of the whole bake (preparation, BVH, samples, transfer).
    pub seconds: f64,
    pub rays: u64,
    /// RMS over vertices, channels and coefficients of the transfer's difference.
    pub transfer_rms: f64,
    /// RMS over vertices and channels of the relit radiance's difference.
    pub radiance_rms: f64,
    /// RMS over held-out surface points and channels of the relit radiance's difference, the
    /// vertex values interpolated there (crate::surface).
    pub surface_rms: f64,
    /// `surface_rms` as seen: each point weighted by how much of it viewers see
    /// ([`crate::surface::seen_fractions`]).
    pub surface_seen_rms: f64,
}

/// A finished sweep.
#[derive(Clone, Debug)]
pub struct Sweep {
    pub points: Vec<SweepPoint>,
    pub reference_samples: u32,
    pub reference_seconds: f64,
    /// RMS of the reference's relit radiance: the scale the radiance errors compare with.
    pub reference_radiance_rms: f64,
    /// The high-sample bake at held-out surface points.
    pub surface: SurfaceReference,
}

/// Root mean square of the differences of two equally long arrays.
pub fn rms_difference(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len());
    let squares: f64 = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| (x as f64 - y as f64).powi(2))
        .sum();
    (squares / a.len().max(1) as f64).sqrt()
}

/// Relit radiance of every vertex and channel, flattened.
fn radiance(transfer: &Transfer, light: &ShLight) -> Result<Vec<f32>> {
    Ok(relight(transfer, light)?.into_iter().flatten().collect())
}

/// Bakes `scene` once per strategy, backend and count, and once for the reference (on the
/// first backend). `backends` pairs a label with a backend.
pub fn run(
    scene: &Scene,
    options: &SweepOptions,
    backends: &[(String, Box<dyn Backend + '_>)],
    light: &ShLight,
    progress: &dyn Progress,
) -> Result<Sweep> {
    if options.strategies.is_empty() || options.counts.is_empty() || backends.is_empty() {
        return Err(Error::Options(
            "a sweep needs at least one strategy, one sample count and one backend".into(),
        ));
    }
    let base = BakeOptions {
        bands: options.bands,
        mode: options.mode,
        seed: options.seed,
        ..BakeOptions::default()
    };
    let reference_options = BakeOptions {
        samples: options.reference_samples,
        sampling: options.reference_sampling,
        // A seed no point of the sweep uses, so no point shares the reference's directions.
        seed: options.seed.wrapping_add(0x5eed_0000),
        ..base.clone()
    };
    reference_options.validate()?;
    progress.stage("reference", 1);
    let started = Instant::now();
    let (reference, _) = bake(
        scene.clone(),
        &reference_options,
        backends[0].1.as_ref(),
        &NoProgress,
    )?;
    let reference_seconds = started.elapsed().as_secs_f64();
    progress.advance(1);
    let reference_radiance = radiance(&reference.transfer, light)?;
    let zero = vec![0.0f32; reference_radiance.len()];
    progress.stage("surface reference", 1);
    let surface = surface_reference_of(&reference, options, &reference_options, backends, light)?;
    progress.advance(1);

    let fits = if options.fits.is_empty() {
        vec![Fit::Point]
    } else {
        options.fits.clone()
    };
    progress.stage(
        "sweep",
        (options.strategies.len() * options.counts.len() * backends.len() * fits.len()) as u64,
    );
    let references = References {
        transfer: &reference.transfer,
        radiance: &reference_radiance,
        surface: &surface,
        light,
    };
    let mut points = Vec::new();
    for (&sampling, &fit) in options
        .strategies
        .iter()
        .flat_map(|s| fits.iter().map(move |f| (s, f)))
    {
        for (label, backend) in backends {
            for &count in &options.counts {
                let point_options = BakeOptions {
                    samples: count,
                    sampling,
                    fit,
                    ..base.clone()
                };
                let label = label.as_str();
                let lightmaps = (&options.lightmap_sizes[..], options.denoise);
                points.extend(measure(
                    scene,
                    &point_options,
                    (label, backend.as_ref()),
                    lightmaps,
                    &references,
                )?);
                progress.advance(1);
            }
        }
    }
    points.extend(measure_targets(scene, options, &base, &references)?);
    Ok(Sweep {
        points,
        reference_samples: reference_options.samples_used(),
        reference_seconds,
        reference_radiance_rms: rms_difference(&reference_radiance, &zero),
        surface,
    })
}

/// The high-sample bake at held-out surface points, for the reference's (prepared) scene.
fn surface_reference_of(
    reference: &crate::bake::BakedMesh,
    options: &SweepOptions,
    reference_options: &BakeOptions,
    backends: &[(String, Box<dyn Backend + '_>)],
    light: &ShLight,
) -> Result<SurfaceReference> {
    let count = match options.surface_points {
        0 => (4 * reference.scene.vertex_count()).min(20_000),
        n => n,
    };
    surface_reference(
        &reference.scene,
        count,
        options.seed.wrapping_add(0x5eed_0001),
        reference_options,
        backends[0].1.as_ref(),
        light,
        Some(&reference.transfer),
    )
}

/// The error-targeted bakes of the sweep: every strategy to every target, on the CPU.
fn measure_targets(
    scene: &Scene,
    options: &SweepOptions,
    base: &BakeOptions,
    references: &References,
) -> Result<Vec<SweepPoint>> {
    let mut points = Vec::new();
    for &sampling in &options.strategies {
        for &relative in &options.target_errors {
            let target = TargetError {
                relative,
                max_samples: MAX_TARGET_SAMPLES,
            };
            let point_options = BakeOptions {
                sampling,
                target_error: Some(target),
                ..base.clone()
            };
            let cpu: (&str, &dyn Backend) = ("cpu", &CpuBackend);
            points.extend(measure(
                scene,
                &point_options,
                cpu,
                (&[], false),
                references,
            )?);
        }
    }
    Ok(points)
}

/// The sample cap of the sweep's error-targeted bakes.
pub const MAX_TARGET_SAMPLES: u32 = 16_384;

/// What every point of a sweep is compared with.
struct References<'a> {
    transfer: &'a Transfer,
    radiance: &'a [f32],
    surface: &'a SurfaceReference,
    light: &'a ShLight,
}

/// One bake of the sweep with `options` on a labelled backend, measured: its vertices, and a
/// lightmap of each of `lightmap_sizes` baked from them (and denoised too where
/// `also_denoised` and the strategy allows).
fn measure(
    scene: &Scene,
    options: &BakeOptions,
    (label, backend): (&str, &dyn Backend),
    (lightmap_sizes, also_denoised): (&[u32], bool),
    references: &References,
) -> Result<Vec<SweepPoint>> {
    let light = references.light;
    let started = Instant::now();
    let (baked, report) = bake(scene.clone(), options, backend, &NoProgress)?;
    let seconds = started.elapsed().as_secs_f64();
    let surface = surface_error(references.surface, &baked.scene, &baked.transfer, light)?;
    let vertex_point = SweepPoint {
        sampling: options.sampling,
        fit: options.fit,
        lightmap: None,
        denoised: false,
        target_error: options.target_error.map(|t| t.relative),
        backend: label.to_string(),
        samples: report
            .adaptive
            .as_ref()
            .map_or(report.samples_used, |a| a.samples_mean.round() as u32),
        seconds,
        rays: report.rays_cast,
        transfer_rms: rms_difference(baked.transfer.coeffs(), references.transfer.coeffs()),
        radiance_rms: rms_difference(&radiance(&baked.transfer, light)?, references.radiance),
        surface_rms: surface.rms,
        surface_seen_rms: surface.seen_rms,
    };
    let mut points = Vec::new();
    let denoising: &[bool] = if also_denoised && options.sampling == Sampling::Cosine {
        &[false, true]
    } else {
        &[false]
    };
    for &size in lightmap_sizes {
        // One atlas for the plain and the denoised map; each point's time includes planning it.
        let planning = Instant::now();
        let atlas = plan_atlas(&baked.scene, size)?;
        let planned = planning.elapsed().as_secs_f64();
        for &denoise in denoising {
            let started = Instant::now();
            let (texels, texel_report) = bake_atlas(
                &baked.scene,
                &baked.transfer,
                &BakeOptions {
                    lightmap: Some(size),
                    denoise,
                    ..options.clone()
                },
                &atlas,
                backend,
                &NoProgress,
            )?;
            let surface = texel_surface_error(references.surface, &texels, light)?;
            points.push(SweepPoint {
                lightmap: Some(size),
                denoised: denoise,
                seconds: seconds + planned + started.elapsed().as_secs_f64(),
                rays: report.rays_cast + texel_report.rays_cast,
                surface_rms: surface.rms,
                surface_seen_rms: surface.seen_rms,
                ..vertex_point.clone()
            });
        }
    }
    points.push(vertex_point);
    Ok(points)
}

/// The CSV header: one row per point follows.
pub const CSV_HEADER: &str = "sampling,fit,backend,samples,seconds,rays,transfer_rms,\
radiance_rms,surface_rms,surface_seen_rms,target_error";

/// How a point represents the transfer between vertices: the fit's name, or `texels-SIZE`
/// (`-least-squares` where its texels are fitted, `-denoised` where filtered).
pub fn representation(point: &SweepPoint) -> String {
    match point.lightmap {
        Some(size) => {
            let fitted = match point.fit {
                Fit::Point => "",
                Fit::LeastSquares => "-least-squares",
            };
            let denoised = if point.denoised { "-denoised" } else { "" };
            format!("texels-{size}{fitted}{denoised}")
        }
        None => point.fit.name().to_string(),
    }
}

/// The sweep as CSV text, one row per point.
pub fn to_csv(sweep: &Sweep) -> String {
    let mut text = String::from(CSV_HEADER);
    text.push('\n');
    for p in &sweep.points {
        text.push_str(&format!(
            "{},{},{},{},{:.6},{},{:.6e},{:.6e},{:.6e},{:.6e},{}\n",
            p.sampling.name(),
            representation(p),
            p.backend,
            p.samples,
            p.seconds,
            p.rays,
            p.transfer_rms,
            p.radiance_rms,
            p.surface_rms,
            p.surface_seen_rms,
            p.target_error.map_or(String::new(), |e| e.to_string())
        ));
    }
    text
}

/// Writes [`to_csv`] to `path`, whole or not at all.
pub fn write_csv(path: &Path, sweep: &Sweep) -> Result<()> {
    write_atomically(path, to_csv(sweep).as_bytes())
}

/// Three panels: transfer and relit-radiance error at the vertices, and relit-radiance error
/// over the surface; one line per strategy, fit and backend.
pub fn chart_panels(result: &Sweep) -> Vec<ChartPanel> {
    let mut lines: Vec<(String, Vec<&SweepPoint>)> = Vec::new();
    for p in &result.points {
        let label = match (p.fit, p.lightmap, p.target_error) {
            (_, _, Some(_)) => format!("{} target {}", p.sampling.name(), p.backend),
            (Fit::Point, None, None) => format!("{} {}", p.sampling.name(), p.backend),
            _ => format!("{} {} {}", p.sampling.name(), representation(p), p.backend),
        };
        match lines.iter_mut().find(|(l, _)| *l == label) {
            Some((_, points)) => points.push(p),
            None => lines.push((label, vec![p])),
        }
    }
    let panel = |title: &str, y_label: &str, error: fn(&SweepPoint) -> f64| ChartPanel {
        title: title.to_string(),
        y_label: y_label.to_string(),
        series: lines
            .iter()
            .map(|(label, points)| ChartSeries {
                label: label.clone(),
                points: points
                    .iter()
                    .map(|p| ChartPoint {
                        seconds: p.seconds,
                        error: error(p),
                        samples: p.samples,
                    })
                    .collect(),
            })
            .collect(),
    };
    vec![
        panel("transfer", "RMS error of the transfer", |p| p.transfer_rms),
        panel("relit radiance", "RMS error of the relit radiance", |p| {
            p.radiance_rms
        }),
        panel(
            "over the surface",
            "RMS error of the relit radiance at surface points",
            |p| p.surface_rms,
        ),
    ]
}

/// Median timings of the direct-transfer pass on each backend ([`time_backends`]).
#[derive(Clone, Debug, PartialEq)]
pub struct BackendTimes {
    pub rays: u64,
    pub cpu_seconds: f64,
    /// `None` without a GPU.
    pub gpu_seconds: Option<f64>,
    /// What the GPU run of median time said of itself (its host's share); `None` without a GPU.
    pub gpu_run: Option<GpuRun>,
}

/// Times the direct-transfer pass `repeats` times on the CPU and, given a baker, the GPU,
/// alternating so that both see the same machine load; reports the medians. `on_round` is
/// called before each round. In interreflected mode the pass is what a bake runs before its
/// bounces on either backend: the transfer and the gather matrix of the rays' closest hits.
pub fn time_backends(
    inputs: &DirectInputs,
    mode: Mode,
    baker: Option<&GpuBaker>,
    repeats: u32,
    on_round: impl Fn(u32),
) -> Result<BackendTimes> {
    let mut cpu_times = Vec::new();
    let mut gpu_runs = Vec::new();
    let mut rays = 0;
    for round in 0..repeats.max(1) {
        on_round(round);
        let started = Instant::now();
        rays = match mode {
            Mode::Interreflected => {
                crate::bake::bounce::direct_transfer_and_gather_matrix_cpu(inputs, &NoProgress).2
            }
            mode => cpu::direct_transfer(inputs, mode, &NoProgress).1,
        };
        cpu_times.push(started.elapsed().as_secs_f64());
        if let Some(baker) = baker {
            let started = Instant::now();
            let chunking = Chunking::default();
            let run = match mode {
                Mode::Interreflected => {
                    gpu::direct_transfer_and_gather_matrix(baker, inputs, chunking, &NoProgress)?.2
                }
                mode => gpu::direct_transfer(baker, inputs, mode, chunking, &NoProgress)?.1,
            };
            gpu_runs.push((started.elapsed().as_secs_f64(), run));
        }
    }
    gpu_runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let median_gpu = (!gpu_runs.is_empty()).then(|| gpu_runs.swap_remove(gpu_runs.len() / 2));
    Ok(BackendTimes {
        rays,
        cpu_seconds: median(&mut cpu_times),
        gpu_seconds: median_gpu.as_ref().map(|(seconds, _)| *seconds),
        gpu_run: median_gpu.map(|(_, run)| run),
    })
}

/// The standard ray sets of `prt-gpu bench --ray-sets`, timed like [`time_backends`]: the
/// direct pass's rays (every receiver's ray origin along each of its sample directions above
/// the horizon) cast as shadow rays (any hit, the visibility bits) and as diffuse rays (closest
/// hit, the triangle hit), with no projection, so that their rays/s compare with published
/// ray-tracer figures. Each GPU answer is checked against the CPU's.
#[derive(Clone, Debug)]
pub struct RaySetTimes {
    pub rays: u64,
    pub shadow: SetTimes,
    pub diffuse: SetTimes,
}

/// One ray set's median times.
#[derive(Clone, Copy, Debug)]
pub struct SetTimes {
    pub cpu_seconds: f64,
    /// `None` without a GPU.
    pub gpu_seconds: Option<f64>,
    /// Rays whose GPU answer differs from the CPU's (blocked or not; the triangle hit, or a hit
    /// on one backend only), in the last round; `None` without a GPU.
    pub differing_rays: Option<u64>,
}

/// Times both ray sets `repeats` times, CPU and GPU alternating; see [`RaySetTimes`].
pub fn time_ray_sets(
    inputs: &DirectInputs,
    baker: Option<&GpuBaker>,
    repeats: u32,
    on_round: impl Fn(u32),
) -> Result<RaySetTimes> {
    let timed = |work: &mut dyn FnMut() -> Result<()>| -> Result<f64> {
        let started = Instant::now();
        work()?;
        Ok(started.elapsed().as_secs_f64())
    };
    let [mut shadow_cpu, mut shadow_gpu, mut diffuse_cpu, mut diffuse_gpu] =
        [(); 4].map(|_| Vec::new());
    let (mut rays, mut shadow_differ, mut diffuse_differ) = (0, None, None);
    for round in 0..repeats.max(1) {
        on_round(round);
        let mut cpu_bits = Vec::new();
        shadow_cpu.push(timed(&mut || {
            cpu_bits = cpu::visibility_bits(inputs, Mode::Shadowed);
            Ok(())
        })?);
        let mut cpu_hits = Vec::new();
        diffuse_cpu.push(timed(&mut || {
            (cpu_hits, rays) = cpu::closest_hit_triangles(inputs);
            Ok(())
        })?);
        let Some(baker) = baker else { continue };
        let mut gpu_bits = Vec::new();
        shadow_gpu.push(timed(&mut || {
            gpu_bits = gpu::visibility_bits_and_transfer(
                baker,
                inputs,
                Mode::Shadowed,
                Chunking::default(),
            )?
            .0;
            Ok(())
        })?);
        let mut gpu_hits = Vec::new();
        diffuse_gpu.push(timed(&mut || {
            gpu_hits = gpu::closest_hits(baker, inputs, Chunking::default(), &NoProgress)?;
            Ok(())
        })?);
        let differing_bits = cpu_bits.iter().zip(&gpu_bits);
        shadow_differ = Some(
            differing_bits
                .map(|(c, g)| (c ^ g).count_ones() as u64)
                .sum(),
        );
        diffuse_differ = Some(differing_hits(&cpu_hits, &gpu_hits));
    }
    let median_of = |times: &mut Vec<f64>| (!times.is_empty()).then(|| median(times));
    Ok(RaySetTimes {
        rays,
        shadow: SetTimes {
            cpu_seconds: median(&mut shadow_cpu),
            gpu_seconds: median_of(&mut shadow_gpu),
            differing_rays: shadow_differ,
        },
        diffuse: SetTimes {
            cpu_seconds: median(&mut diffuse_cpu),
            gpu_seconds: median_of(&mut diffuse_gpu),
            differing_rays: diffuse_differ,
        },
    })
}

/// Rays whose closest hit differs between `cpu` and `gpu` (`(sample, triangle)` per receiver):
/// another triangle, or a hit on one side only.
fn differing_hits(cpu: &[Vec<(u32, u32)>], gpu: &[Vec<(u32, Hit)>]) -> u64 {
    cpu.iter()
        .zip(gpu)
        .map(|(c, g)| {
            let on_cpu: HashMap<u32, u32> = c.iter().copied().collect();
            let matching = g
                .iter()
                .filter(|(s, hit)| on_cpu.get(s) == Some(&hit.triangle))
                .count();
            let gpu_only = g.iter().filter(|(s, _)| !on_cpu.contains_key(s)).count();
            (c.len() - matching + gpu_only) as u64
        })
        .sum()
}

fn median(times: &mut [f64]) -> f64 {
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_differ_by_triangle_or_by_presence() {
        let hit = |triangle| Hit {
            triangle,
            u: 0.25,
            v: 0.5,
        };
        let cpu = vec![vec![(0, 7), (3, 9), (5, 1)], vec![], vec![(2, 4)]];
        let same: Vec<Vec<(u32, Hit)>> = cpu
            .iter()
            .map(|row| row.iter().map(|&(s, t)| (s, hit(t))).collect())
            .collect();
        assert_eq!(differing_hits(&cpu, &same), 0);
        // Sample 3 hits another triangle, sample 5 misses, sample 1 of receiver 1 hits on the
        // GPU only: three rays.
        let gpu = vec![
            vec![(0, hit(7)), (3, hit(8))],
            vec![(1, hit(2))],
            vec![(2, hit(4))],
        ];
        assert_eq!(differing_hits(&cpu, &gpu), 3);
    }

    fn point(sampling: Sampling, backend: &str, samples: u32) -> SweepPoint {
        SweepPoint {
            sampling,
            fit: Fit::Point,
            lightmap: None,
            denoised: false,
            target_error: None,
            backend: backend.to_string(),
            samples,
            seconds: samples as f64 * 1e-3,
            rays: samples as u64 * 10,
            transfer_rms: 1.0 / samples as f64,
            radiance_rms: 2.0 / samples as f64,
            surface_rms: 3.0 / samples as f64,
            surface_seen_rms: 2.5 / samples as f64,
        }
    }

    fn sweep() -> Sweep {
        let mut points = Vec::new();
        for sampling in [Sampling::Stratified, Sampling::Cosine] {
            for backend in ["cpu", "gpu"] {
                for samples in [64, 256] {
                    points.push(point(sampling, backend, samples));
                }
            }
        }
        Sweep {
            points,
            reference_samples: 4096,
            reference_seconds: 1.0,
            reference_radiance_rms: 1.0,
            surface: SurfaceReference {
                points: Vec::new(),
                hidden: 0,
                radiance: Vec::new(),
                rms: 1.0,
                seen: Vec::new(),
                seen_rms: 1.0,
                rays: 0,
                seconds: 0.0,
            },
        }
    }

    #[test]
    fn panels_hold_one_series_per_strategy_and_backend() {
        let panels = chart_panels(&sweep());
        assert_eq!(panels.len(), 3);
        let labels: Vec<&str> = panels[0].series.iter().map(|s| s.label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "stratified cpu",
                "stratified gpu",
                "cosine cpu",
                "cosine gpu"
            ]
        );
        for series in &panels[1].series {
            let samples: Vec<u32> = series.points.iter().map(|p| p.samples).collect();
            assert_eq!(samples, [64, 256]);
            // The middle panel charts the radiance error.
            assert_eq!(series.points[0].error, 2.0 / 64.0);
        }
        assert_eq!(panels[2].series[0].points[1].error, 3.0 / 256.0);
    }

    #[test]
    fn csv_has_one_row_per_point() {
        let text = to_csv(&sweep());
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], CSV_HEADER);
        assert_eq!(lines.len(), 1 + 8);
        assert!(
            lines[1].starts_with("stratified,point,cpu,64,0.064000,640,"),
            "{}",
            lines[1]
        );
    }

    #[test]
    fn rms_difference_is_the_root_mean_square() {
        assert_eq!(rms_difference(&[1.0, 2.0], &[1.0, 2.0]), 0.0);
        assert!((rms_difference(&[3.0, 0.0], &[0.0, 4.0]) - 12.5f64.sqrt()).abs() < 1e-12);
    }
}
