//! `prt-gpu chart` and `prt-gpu bench`: speed against accuracy, rays per second.

use std::path::{Path, PathBuf};

use super::args::{Bands, TransferArgs};
use super::bake::{load_scene, naming_the_mesh, open_backend};
use super::light::load_light;
use super::progress::BarProgress;
use prt_gpu::bake::adaptive::TargetError;
use prt_gpu::bake::gpu::{Division, GpuRun};
use prt_gpu::bake::{self, Backend, BakeOptions, CpuBackend, Fit, GpuBackend, Mode};
use prt_gpu::device::DeviceChoice;
use prt_gpu::light;
use prt_gpu::sampling::{Sampling, MAX_SAMPLES};
use prt_gpu::sweep::{self, SweepOptions};
use prt_gpu::{chart, fs, scene, Error, Result};

#[derive(clap::Args)]
pub(crate) struct ChartArgs {
    /// Mesh to chart (the built-in scene when none is given).
    mesh: Option<PathBuf>,
    /// Output chart, .svg or .png; the numbers go to the same name with .csv.
    #[arg(short, long, default_value = "chart.svg")]
    output: PathBuf,
    /// Spherical-harmonic bands.
    #[arg(long, default_value_t = 4)]
    bands: u32,
    /// Light transport to bake.
    #[arg(long, value_enum, default_value_t = Mode::Shadowed)]
    mode: Mode,
    /// Sample counts of the sweep, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [64, 256, 1024])]
    samples: Vec<u32>,
    /// Strategies to chart, comma-separated (default: all).
    #[arg(long, value_enum, value_delimiter = ',')]
    sampling: Vec<Sampling>,
    /// Samples of the reference bake every point is compared with.
    #[arg(long, default_value_t = 16_384)]
    reference_samples: u32,
    /// Strategy of the reference bake.
    #[arg(long, value_enum, default_value_t = Sampling::ControlVariate)]
    reference_sampling: Sampling,
    /// Light for the relit-radiance error: light.json or an environment map (default: the
    /// preview's sky and sun).
    #[arg(long)]
    light: Option<PathBuf>,
    /// The CPU backend always runs; this says which GPU joins it: `auto` a hardware GPU if
    /// there is one, `gpu` any adapter (lavapipe included), `cpu` none.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto)]
    device: DeviceChoice,
    /// Use the adapter whose name contains this text.
    #[arg(long)]
    adapter: Option<String>,
    /// Seed of the sweep's sample directions (the reference uses another).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Vertex fits to chart, comma-separated (default: point,least-squares); each is baked
    /// with every strategy and count.
    #[arg(long, value_enum, value_delimiter = ',')]
    fit: Vec<Fit>,
    /// Held-out surface points of the surface error (default: four per vertex, at most 20,000).
    #[arg(long, default_value_t = 0)]
    surface_points: usize,
    /// Lightmap sizes, comma-separated: each strategy, count and fit is also baked per texel
    /// at each (`least-squares`: fitted texels, about five times the rays), for the surface
    /// panel (the vertex errors of these points are their vertices').
    #[arg(long, value_delimiter = ',', value_name = "SIZES")]
    lightmap: Vec<u32>,
    /// With --lightmap: each cosine-sampled lightmap is also baked denoised (`bake --denoise`),
    /// as its own line.
    #[arg(long, requires = "lightmap")]
    denoise: bool,
    /// Error targets, comma-separated: each strategy is also baked to each (`bake
    /// --target-error`, on the CPU backend, at most 16,384 samples a receiver).
    #[arg(long, value_delimiter = ',', value_name = "ERRORS")]
    target_error: Vec<f64>,
}

#[derive(clap::Args)]
pub(crate) struct BenchArgs {
    /// Mesh to bake (the built-in scene when none is given).
    mesh: Option<PathBuf>,
    #[command(flatten)]
    transfer: TransferArgs,
    /// Timed runs per backend, interleaved CPU, GPU, CPU, GPU, ...; the median is reported.
    #[arg(long, default_value_t = 3)]
    repeats: u32,
    /// `gpu` (default) times any adapter, lavapipe included, beside the CPU; `cpu` only the CPU.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Gpu)]
    device: DeviceChoice,
    /// Use the adapter whose name contains this text.
    #[arg(long)]
    adapter: Option<String>,
    /// Also time the bake's rays as two standard ray sets, shadow rays (any hit) and diffuse
    /// rays (closest hit), without the projection, and count the rays on which the GPU's answer
    /// differs from the CPU's.
    #[arg(long)]
    ray_sets: bool,
}

pub(crate) fn run_chart(args: ChartArgs) -> Result<()> {
    let csv_path = args.output.with_extension("csv");
    let outputs = [
        fs::Output {
            option: "-o",
            path: &args.output,
        },
        fs::Output {
            option: "-o",
            path: &csv_path,
        },
    ];
    let inputs: Vec<&Path> = args
        .mesh
        .iter()
        .chain(&args.light)
        .map(PathBuf::as_path)
        .collect();
    fs::check_outputs(&outputs, &inputs)?;
    chart::check_chart_path(&args.output)?;
    fs::check_destination(&args.output)?;
    let options = sweep_options(&args)?;
    let light = match &args.light {
        Some(path) => load_light(path, args.bands, None, false)?.light,
        None => light::preview_light(args.bands)?,
    };
    let (scene, name) = load_scene(&args.mesh)?;
    let baker = open_backend(args.device, args.adapter.as_deref())?;
    let mut backends: Vec<(String, Box<dyn Backend>)> =
        vec![("cpu".to_string(), Box::new(CpuBackend))];
    if let Some(baker) = &baker {
        eprintln!("gpu: {}", baker.context.adapter.label());
        backends.push(("gpu".to_string(), Box::new(GpuBackend::new(baker))));
    }
    let started = std::time::Instant::now();
    let progress = BarProgress::default();
    let result = sweep::run(&scene, &options, &backends, &light, &progress)
        .map_err(|e| naming_the_mesh(e, &name))?;
    progress.finish();
    let panels = sweep::chart_panels(&result);
    let title = format!(
        "{name}: {} bands, {} mode, against {} {} samples",
        options.bands,
        options.mode.name(),
        result.reference_samples,
        options.reference_sampling.name()
    );
    chart::draw_chart(&args.output, &title, "bake time (s)", &panels)?;
    if let Err(error) = sweep::write_csv(&csv_path, &result) {
        // The chart and its numbers are one output: without the numbers, no chart either.
        let _ = std::fs::remove_file(&args.output);
        return Err(error);
    }
    for p in &result.points {
        eprintln!(
            "{:>16} {:>13} {:>3} {:>6} samples: {:>8.3} s, transfer rms {:.3e}, radiance rms \
             {:.3e}, surface {:.2}% ({:.2}% as seen)",
            p.sampling.name(),
            match p.target_error {
                Some(e) => format!("target {e}"),
                None => sweep::representation(p),
            },
            p.backend,
            p.samples,
            p.seconds,
            p.transfer_rms,
            p.radiance_rms,
            100.0 * p.surface_rms / result.surface.rms.max(1e-30),
            100.0 * p.surface_seen_rms / result.surface.seen_rms.max(1e-30)
        );
    }
    println!(
        "charted {name}: {} points, reference {} samples in {:.2} s (and {} surface points, {} \
         inside geometry left out, in {:.2} s), {:.1} s in all -> {}, {}",
        result.points.len(),
        result.reference_samples,
        result.reference_seconds,
        result.surface.points.len(),
        result.surface.hidden,
        result.surface.seconds,
        started.elapsed().as_secs_f64(),
        args.output.display(),
        csv_path.display()
    );
    Ok(())
}

/// The sweep `chart` asks for, every count checked as a bake would check it.
/// The most held-out surface points a chart measures at (each costs a reference bake).
const MAX_SURFACE_POINTS: usize = 1_000_000;

/// The most rounds `bench` times.
const MAX_REPEATS: u32 = 1000;

fn sweep_options(args: &ChartArgs) -> Result<SweepOptions> {
    if args.samples.is_empty() || args.samples.contains(&0) {
        return Err(Error::Options(
            "--samples needs counts of at least 1".into(),
        ));
    }
    let options = SweepOptions {
        bands: args.bands,
        mode: args.mode,
        strategies: if args.sampling.is_empty() {
            Sampling::ALL.to_vec()
        } else {
            args.sampling.clone()
        },
        counts: args.samples.clone(),
        reference_samples: args.reference_samples,
        reference_sampling: args.reference_sampling,
        seed: args.seed,
        fits: if args.fit.is_empty() {
            SweepOptions::default().fits
        } else {
            args.fit.clone()
        },
        surface_points: args.surface_points,
        lightmap_sizes: args.lightmap.clone(),
        denoise: args.denoise,
        target_errors: args.target_error.clone(),
    };
    if options.reference_samples == 0 || options.reference_samples > MAX_SAMPLES {
        return Err(Error::Options(format!(
            "--reference-samples {} is out of range (1 to {MAX_SAMPLES})",
            options.reference_samples
        )));
    }
    if options.surface_points > MAX_SURFACE_POINTS {
        return Err(Error::Options(format!(
            "--surface-points {} is out of range (0 for the default, at most {MAX_SURFACE_POINTS})",
            options.surface_points
        )));
    }
    for &count in options.counts.iter().chain([&options.reference_samples]) {
        BakeOptions {
            bands: options.bands,
            samples: count,
            ..BakeOptions::default()
        }
        .validate()?;
    }
    for &size in &options.lightmap_sizes {
        BakeOptions {
            lightmap: Some(size),
            ..BakeOptions::default()
        }
        .validate()?;
    }
    for &relative in &options.target_errors {
        BakeOptions {
            mode: options.mode,
            target_error: Some(TargetError {
                relative,
                max_samples: sweep::MAX_TARGET_SAMPLES,
            }),
            ..BakeOptions::default()
        }
        .validate()?;
    }
    Ok(options)
}

/// Where a GPU run's time went, as one line: the wait for the kernels, and the rest (the
/// host's setup, uploads and read-backs), each a share of the run; and where the device
/// writes timestamps, each pass's own time on it.
fn gpu_host_share(run: &GpuRun) -> String {
    let share = |seconds: f64| 100.0 * seconds / run.run_seconds.max(f64::MIN_POSITIVE);
    let rest = run.run_seconds - run.kernel_wait_seconds;
    let on_device = match run.kernel_seconds {
        Some([horizon, visibility, projection]) => format!(
            "; timed on the device: horizon {horizon:.3} s, visibility {visibility:.3} s, \
             projection {projection:.3} s"
        ),
        None => "; the device writes no timestamps".to_string(),
    };
    format!(
        "gpu run of median time: {:.3} s in {} submissions: waiting for kernels {:.3} s \
         ({:.0}%), the rest {:.3} s ({:.0}%){on_device}",
        run.run_seconds,
        run.submissions,
        run.kernel_wait_seconds,
        share(run.kernel_wait_seconds),
        rest,
        share(rest),
    )
}

pub(crate) fn run_bench(args: BenchArgs) -> Result<()> {
    if args.transfer.bands == Bands::Auto {
        return Err(Error::Options(
            "--bands auto chooses the bands of a bake; bench needs a number".into(),
        ));
    }
    let options = args.transfer.options();
    options.validate()?;
    if args.repeats == 0 || args.repeats > MAX_REPEATS {
        return Err(Error::Options(format!(
            "--repeats {} is out of range (1 to {MAX_REPEATS})",
            args.repeats
        )));
    }
    let (scene, name) = load_scene(&args.mesh)?;
    let (scene, _) = scene::prepare::prepare(scene).map_err(|e| naming_the_mesh(e, &name))?;
    let owned = bake::BakeInputs::for_options(&scene, &options);
    let inputs = owned.view();
    // Asked for a GPU (--device gpu), a missing one is an error; otherwise the CPU runs alone.
    let baker = match open_backend(args.device, args.adapter.as_deref()) {
        Ok(baker) => baker,
        Err(e) if args.device == DeviceChoice::Gpu => return Err(e),
        Err(e) => {
            eprintln!("note: no GPU entry: {e}");
            None
        }
    };
    let timing = sweep::time_backends(
        &inputs,
        options.mode,
        baker.as_ref(),
        args.repeats,
        |round| eprintln!("round {} of {}", round + 1, args.repeats),
    )?;
    let rays = timing.rays;
    println!(
        "{name}: {} vertices, {} bands, {} {} samples, {} mode, {rays} rays; median of {} runs",
        inputs.origins.len(),
        options.bands,
        inputs.samples.len(),
        options.sampling.name(),
        options.mode.name(),
        args.repeats
    );
    let cpu_seconds = timing.cpu_seconds;
    println!(
        "cpu ({} threads): {cpu_seconds:.3} s, {:.2} M rays/s",
        rayon::current_num_threads(),
        rays as f64 / cpu_seconds / 1e6
    );
    if let (Some(baker), Some(gpu_seconds)) = (&baker, timing.gpu_seconds) {
        println!(
            "gpu ({}): {gpu_seconds:.3} s, {:.2} M rays/s",
            baker.context.adapter.label(),
            rays as f64 / gpu_seconds / 1e6
        );
        if let Some(run) = &timing.gpu_run {
            println!("{}", gpu_host_share(run));
        }
        println!(
            "gpu division: {}",
            match baker.division() {
                Division::Ieee => "the adapter's own, which rounds as IEEE 754 on every probe",
                Division::Emulated => "emulated (the adapter's own is not IEEE 754's)",
            }
        );
        println!("gpu / cpu throughput: {:.2}", cpu_seconds / gpu_seconds);
    }
    if args.ray_sets {
        let sets = sweep::time_ray_sets(&inputs, baker.as_ref(), args.repeats, |round| {
            eprintln!("ray sets: round {} of {}", round + 1, args.repeats)
        })?;
        print_ray_sets(&sets);
    }
    Ok(())
}

/// The ray sets' lines: rays/s per backend, per core on the CPU, and the rays that differ.
fn print_ray_sets(sets: &sweep::RaySetTimes) {
    let threads = rayon::current_num_threads();
    println!(
        "ray sets: the same {} rays, no projection; M rays/s, per core on the CPU ({threads} threads)",
        sets.rays
    );
    let rate = |seconds: f64| sets.rays as f64 / seconds / 1e6;
    for (name, set) in [
        ("shadow (any hit)", &sets.shadow),
        ("diffuse (closest hit)", &sets.diffuse),
    ] {
        let mut line = format!(
            "{name:<22} cpu {:8.2} ({:6.2} per core)",
            rate(set.cpu_seconds),
            rate(set.cpu_seconds) / threads as f64
        );
        if let (Some(seconds), Some(differing)) = (set.gpu_seconds, set.differing_rays) {
            line += &format!(
                "   gpu {:9.2}   gpu / cpu {:.2}   rays whose gpu answer differs: {differing}",
                rate(seconds),
                set.cpu_seconds / seconds
            );
        }
        println!("{line}");
    }
}
