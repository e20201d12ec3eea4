//! The `prt-gpu` command line: parse, call the library, report. No baking logic lives here.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Mutex;

use clap::{Parser, Subcommand};
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};

use prt_gpu::bake::gpu::{Chunking, GpuBaker};
use prt_gpu::bake::{self, Backend, BakeOptions, Mode, Progress};
use prt_gpu::gpu::{self, DeviceChoice};
use prt_gpu::{output, scene};

#[derive(Parser)]
#[command(
    name = "prt-gpu",
    version,
    about = "Precomputed radiance transfer baker"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Bake per-vertex SH transfer vectors for a mesh (the built-in scene when none is given).
    Bake(BakeArgs),
    /// Print the metadata of a baked file.
    Info {
        /// A .glb written by `prt-gpu bake`.
        file: PathBuf,
    },
    /// List the GPU adapters wgpu can see, best first.
    Devices,
}

#[derive(clap::Args)]
struct BakeArgs {
    /// Mesh to bake: .obj, .ply or .ply.gz. Without it, the built-in scene (a sphere and a box
    /// on a ground plane beside a wall).
    mesh: Option<PathBuf>,
    /// Spherical-harmonic bands (bands^2 coefficients per channel).
    #[arg(long, default_value_t = 4)]
    bands: u32,
    /// Sample directions per vertex; rounded to the nearest square (stratified sampling).
    #[arg(long, default_value_t = 1024)]
    samples: u32,
    /// Light transport to capture.
    #[arg(long, value_enum, default_value_t = Mode::Shadowed)]
    mode: Mode,
    /// Interreflected mode: bounces of light between surfaces added to the direct transfer.
    #[arg(long, default_value_t = 3)]
    bounces: u32,
    /// Interreflected mode: stop early once a bounce adds less than this fraction of the
    /// energy so far (0 runs every bounce).
    #[arg(long, default_value_t = 0.0)]
    bounce_tolerance: f64,
    /// Seed of the sample directions: the same seed gives the same file.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Override every material's albedo, as linear R,G,B in [0, 1].
    #[arg(long, value_parser = parse_rgb)]
    albedo: Option<Vec3>,
    /// Output file (.glb). Default: <mesh name>.prt.glb in the current directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Where to bake: `auto` takes a hardware GPU and otherwise the CPU backend (faster than
    /// a software rasterizer on the same cores); `gpu` takes any adapter, lavapipe included.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto)]
    device: DeviceChoice,
    /// Use the adapter whose name contains this text (see `prt-gpu devices`).
    #[arg(long)]
    adapter: Option<String>,
    /// GPU: at most this many vertices per chunk (for testing chunking; default from limits).
    #[arg(long, hide_short_help = true)]
    chunk_vertices: Option<u32>,
    /// GPU: at most this many samples per chunk, rounded up to a multiple of 32.
    #[arg(long, hide_short_help = true)]
    chunk_samples: Option<u32>,
}

fn parse_rgb(text: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let values: Result<Vec<f32>, _> = match parts.len() {
        1 => parts[0].parse::<f32>().map(|v| vec![v; 3]),
        3 => parts.iter().map(|p| p.parse::<f32>()).collect(),
        _ => return Err("expected R,G,B (or one grey value)".into()),
    };
    let v = values.map_err(|e| format!("expected numbers: {e}"))?;
    Ok(Vec3::new(v[0], v[1], v[2]))
}

fn main() -> ExitCode {
    // Mesa's software drivers probe for a Wayland display and complain on stderr, once per
    // adapter, when XDG_RUNTIME_DIR is unset (typical of CI and containers). Give them one
    // before any thread exists.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir());
    }
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Bake(args) => run_bake(args),
        Command::Info { file } => run_info(&file),
        Command::Devices => run_devices(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn run_bake(args: BakeArgs) -> Result<(), String> {
    let options = BakeOptions {
        bands: args.bands,
        samples: args.samples,
        seed: args.seed,
        mode: args.mode,
        albedo: args.albedo,
        bounces: args.bounces,
        bounce_tolerance: args.bounce_tolerance,
    };
    options.validate().map_err(|e| e.to_string())?;
    let (scene, name) = match &args.mesh {
        Some(path) => (scene::load(path).map_err(|e| e.to_string())?, stem(path)),
        None => (scene::builtin::default_scene(), "default-scene".to_string()),
    };
    let output_path = args
        .output
        .unwrap_or_else(|| PathBuf::from(format!("{name}.prt.glb")));
    // Fail before the long part, not after it.
    output::check_destination(&output_path).map_err(|e| e.to_string())?;
    if options.samples_used() != options.samples {
        let side = (options.samples_used() as f64).sqrt() as u32;
        eprintln!(
            "note: --samples {} is not a square; using {} ({side} x {side} strata)",
            options.samples,
            options.samples_used()
        );
    }

    let name_shown = args
        .mesh
        .as_ref()
        .map_or_else(|| "built-in scene".to_string(), |p| p.display().to_string());
    for (name, value) in [
        ("--chunk-vertices", args.chunk_vertices),
        ("--chunk-samples", args.chunk_samples),
    ] {
        if value == Some(0) {
            return Err(format!("invalid option: {name} must be at least 1"));
        }
    }
    let baker = open_backend(args.device, args.adapter.as_deref())?;
    let backend = match &baker {
        Some(baker) => Backend::Gpu {
            baker,
            chunking: Chunking {
                max_vertices: args.chunk_vertices,
                max_samples: args.chunk_samples,
                max_steps: None,
            },
        },
        None => Backend::Cpu,
    };
    let progress = BarProgress::default();
    let (baked, report) =
        bake::bake(scene, &options, &backend, &progress).map_err(|e| match e {
            // Geometry errors come from preparation, which no longer knows the file: name it.
            prt_gpu::Error::Geometry(_) => format!("{name_shown}: {e}"),
            _ => e.to_string(),
        })?;
    progress.finish();
    output::write_glb(&output_path, &baked).map_err(|e| e.to_string())?;

    for (i, bounce) in report.bounces.iter().enumerate() {
        eprintln!(
            "bounce {}: +{:.2}% energy in {:.2} s",
            i + 1,
            100.0 * bounce.relative_energy,
            bounce.seconds
        );
    }
    let seconds_bounces: f64 = report.bounces.iter().map(|b| b.seconds).sum();
    let seconds = report.seconds_prepare + report.seconds_transfer + seconds_bounces;
    let rays_per_second = report.rays_cast as f64 / report.seconds_transfer.max(1e-9);
    println!(
        "baked {name}: {} vertices, {} triangles, {} bands, {} samples, {} mode; {} rays in {:.2} s \
         ({:.2} M rays/s), {:.2} s in all ({}) -> {}",
        report.prepare.vertices,
        report.prepare.triangles,
        options.bands,
        report.samples_used,
        options.mode.name(),
        report.rays_cast,
        report.seconds_transfer,
        rays_per_second / 1e6,
        seconds,
        report.backend,
        output_path.display()
    );
    Ok(())
}

/// The GPU baker for `choice`, or `None` for the CPU backend (saying why when it was not asked for).
fn open_backend(choice: DeviceChoice, adapter: Option<&str>) -> Result<Option<GpuBaker>, String> {
    match gpu::open(choice, adapter).map_err(|e| e.to_string())? {
        Some(context) => GpuBaker::new(context).map(Some).map_err(|e| e.to_string()),
        None => {
            if choice == DeviceChoice::Auto {
                match gpu::list_adapters().first() {
                    Some(best) => eprintln!(
                        "note: only software GPU adapters ({}); the CPU backend is faster on the same \
                         cores and bakes instead (--device gpu forces the adapter)",
                        best.name
                    ),
                    None => eprintln!("note: no GPU adapter found; baking on the CPU backend"),
                }
            }
            Ok(None)
        }
    }
}

fn run_devices() -> Result<(), String> {
    let adapters = gpu::list_adapters();
    if adapters.is_empty() {
        println!("no GPU adapters (bakes run on the CPU backend)");
        return Ok(());
    }
    for (i, a) in adapters.iter().enumerate() {
        println!("{i}: {}", a.name);
        println!(
            "   backend {:?}, type {:?}{}",
            a.backend,
            a.device_type,
            if a.is_software() { " (software)" } else { "" }
        );
        println!("   driver {}", a.driver);
        println!(
            "   max storage binding {} MiB, max buffer {} MiB, max workgroups per dimension {}, \
             max invocations per workgroup {}",
            a.max_storage_buffer_binding_size >> 20,
            a.max_buffer_size >> 20,
            a.max_compute_workgroups_per_dimension,
            a.max_compute_invocations_per_workgroup
        );
    }
    Ok(())
}

fn run_info(path: &Path) -> Result<(), String> {
    let (metadata, vertices, triangles) = output::read_metadata(path).map_err(|e| e.to_string())?;
    println!("file:         {}", path.display());
    println!("vertices:     {vertices}");
    println!("triangles:    {triangles}");
    println!("mode:         {}", metadata.mode.name());
    println!(
        "bands:        {} ({} coefficients per channel)",
        metadata.bands,
        metadata.bands * metadata.bands
    );
    println!("channels:     {}", metadata.channels);
    println!("samples:      {} ({})", metadata.samples, metadata.sampling);
    println!("seed:         {}", metadata.seed);
    println!("bounces:      {}", metadata.bounces);
    println!("backend:      {}", metadata.backend);
    println!("made by:      {} {}", metadata.tool, metadata.tool_version);
    println!("sh basis:     {}", metadata.sh_convention);
    println!("radiometry:   {}", metadata.radiometry);
    Ok(())
}

fn stem(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mesh".into());
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    match name.rsplit_once('.') {
        Some((stem, _)) if !stem.is_empty() => stem.to_string(),
        _ => name.to_string(),
    }
}

/// A progress bar on stderr; indicatif hides it when stderr is not a terminal.
#[derive(Default)]
struct BarProgress {
    bar: Mutex<Option<ProgressBar>>,
}

impl Progress for BarProgress {
    fn stage(&self, name: &str, total: u64) {
        let bar = ProgressBar::new(total).with_message(name.to_string());
        bar.set_style(
            ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} vertices, eta {eta}")
                .expect("static template")
                .progress_chars("=> "),
        );
        if let Some(old) = self.bar.lock().unwrap().replace(bar) {
            old.finish_and_clear();
        }
    }

    fn advance(&self, done: u64) {
        if let Some(bar) = self.bar.lock().unwrap().as_ref() {
            bar.inc(done);
        }
    }
}

impl BarProgress {
    fn finish(&self) {
        if let Some(bar) = self.bar.lock().unwrap().take() {
            bar.finish_and_clear();
        }
    }
}
