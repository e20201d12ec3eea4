//! `prt-gpu bake`: one mesh or a batch, distant-light transfer; checks, the device, the report.

use std::path::{Path, PathBuf};

use glam::Vec3;

use super::args::{
    parse_compression, parse_cpca_shape, parse_rgb, parse_shard, parse_size, Bands, TransferArgs,
};
use super::progress::{batch_bar, BarProgress};
use prt_gpu::bake::adaptive::TargetError;
use prt_gpu::bake::gpu::{Chunking, GpuBaker};
use prt_gpu::bake::{self, Backend, BakeOptions, BakeReport, Fit, Storage};
use prt_gpu::device::{self, DeviceChoice, GpuContext};
use prt_gpu::local::LocalOptions;
use prt_gpu::precision::Precision;
use prt_gpu::receivers::PointDensity;
use prt_gpu::render::{self, ToneMap};
use prt_gpu::shard::{self, PartHeader};
use prt_gpu::spec::{
    self, BakeSpec, Compression, Container, Layout, ReceiverSpec, StorageSpec, TransferSpec,
};
use prt_gpu::{fs, glb, light, pipeline, scene, Error, Result};

#[derive(clap::Args)]
pub(crate) struct BakeArgs {
    /// Mesh to bake: a glTF scene (.gltf, .glb: written back with its transfer added), .obj,
    /// .ply or .ply.gz. Without it, the built-in scene (a sphere and a box on a ground plane
    /// beside a wall). Several meshes, directories (their mesh files) or quoted glob patterns
    /// bake as a batch into --out-dir, one device for all.
    #[arg(value_name = "MESH")]
    pub(crate) meshes: Vec<PathBuf>,
    /// Batch: the directory each <mesh name>.prt.glb is written to (created if missing).
    #[arg(long, value_name = "DIR")]
    pub(crate) out_dir: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) transfer: TransferArgs,
    /// Interreflected mode: bounces of light between surfaces added to the direct transfer.
    #[arg(long, default_value_t = 3)]
    pub(crate) bounces: u32,
    /// Interreflected mode: stop early once a bounce adds less than this fraction of the
    /// energy so far (0 runs every bounce).
    #[arg(long, default_value_t = 0.0)]
    pub(crate) bounce_tolerance: f64,
    /// Seed of the sample directions: the same seed gives the same file.
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// How vertex values are made: `point` bakes at the vertices (exact there); `least-squares`
    /// bakes at points spread over every triangle and fits the vertex values whose
    /// interpolation matches them best over the surface (Kavan et al. 2011), at the cost of
    /// `--fit-points` times the vertices' rays per sample.
    #[arg(long, value_enum, default_value_t = Fit::Point)]
    pub(crate) fit: Fit,
    /// Least-squares fit: surface points baked per vertex of the mesh, on average (every
    /// triangle gets at least three).
    #[arg(long, default_value_t = PointDensity::default().per_vertex)]
    pub(crate) fit_points: f32,
    /// Bake to an error target instead of a fixed sample count: each receiver casts batches of
    /// 32 samples (at least 8) until the standard error of its transfer, relative to unoccluded
    /// transfer's norm, is below E. Shadowed and unshadowed modes; runs on the CPU backend.
    #[arg(long, value_name = "E")]
    pub(crate) target_error: Option<f64>,
    /// With --target-error: the most samples one receiver casts.
    #[arg(long, default_value_t = 4096)]
    pub(crate) max_samples: u32,
    /// With --bands auto: the largest fraction of the transfer's energy (squared coefficients
    /// over vertices and channels) the bands left out may hold.
    #[arg(long, default_value_t = 0.05)]
    pub(crate) bands_threshold: f64,
    /// How to store the transfer: `rgb`, or `lean` — one channel where one suffices
    /// (shadowed and unshadowed transfer albedo-free, the albedo applied at relighting from
    /// COLOR_0; interreflected transfer when every albedo is grey), a third of the size.
    #[arg(long, value_enum, default_value_t = Storage::Rgb)]
    pub(crate) storage: Storage,
    /// Precision of the stored transfer: `f32`, or `f16` (IEEE half floats: half the bytes,
    /// each value within 2^-11 of itself relative; the added relit error is reported). glTF has
    /// no half-float attributes, so an f16 file names its transfer view in extras.prt instead of
    /// the _PRT_* attributes. With --compress, the means, bases and weights are half floats and
    /// each cluster index takes the fewest bytes that hold it (1 up to 256 clusters).
    #[arg(long, value_enum, default_value_t = Precision::F32)]
    pub(crate) precision: Precision,
    /// Store the transfer compressed by clustered PCA (Sloan et al. 2003): CLUSTERSxCOMPONENTS,
    /// e.g. 64x8 — per vertex a cluster and COMPONENTS weights, per cluster a mean and a basis —
    /// or auto:E, the smallest shape (of a grid of them) whose coefficient error is below E.
    /// Sizes and the error against the uncompressed transfer are reported.
    #[arg(long, value_name = "CLUSTERSxCOMPONENTS|auto:E", value_parser = parse_compression)]
    pub(crate) compress: Option<Compression>,
    /// Also bake per-texel transfer into a lightmap about SIZE texels on its longer side,
    /// written as <output stem>.lightmap.exr beside the .glb. An OBJ, a PLY or the built-in
    /// scene gets a generated atlas, and the .glb holds its coordinates as TEXCOORD_0 (every
    /// triangle corner its own vertex); a glTF scene keeps its vertices, and its lightmap (SIZE
    /// texels square) lies on its own UV set: TEXCOORD_1, or TEXCOORD_0 where that does not
    /// overlap.
    #[arg(long, value_name = "SIZE")]
    pub(crate) lightmap: Option<u32>,
    /// With --lightmap on a glTF scene: the TEXCOORD_n set to bake it on.
    #[arg(long, value_name = "N")]
    pub(crate) lightmap_uv: Option<u32>,
    /// Override every material's albedo, as linear R,G,B in [0, 1].
    #[arg(long, value_parser = parse_rgb)]
    pub(crate) albedo: Option<Vec3>,
    /// Output file (.glb). Default: <mesh name>.prt.glb in the current directory.
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
    /// Where to bake: `auto` takes a hardware GPU and otherwise the CPU backend (faster than
    /// a software rasterizer on the same cores); `gpu` takes any adapter, lavapipe included.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto)]
    pub(crate) device: DeviceChoice,
    /// Use the adapter whose name contains this text (see `prt-gpu devices`).
    #[arg(long)]
    pub(crate) adapter: Option<String>,
    /// Also render a preview of the result under a default sky and sun (.png or .exr).
    #[arg(long)]
    pub(crate) preview: Option<PathBuf>,
    /// Most memory the bake may use, e.g. 512M or 8G (binary units). A shadowed or unshadowed
    /// bake of OBJ, PLY or the built-in scene that would need more streams its transfer to the
    /// file in chunks that fit; one that cannot fit says so before it starts. Default: the
    /// memory this machine has available (when that is too little, a warning).
    #[arg(long, value_name = "SIZE", value_parser = parse_size)]
    pub(crate) memory_limit: Option<u64>,
    /// Bake only shard I of N (counted from 0): a contiguous run of about 1/N of the receivers,
    /// written as a part file (default <mesh name>.prt.I-of-N.part); `prt-gpu merge` joins
    /// the N parts into the file this bake without --shard writes, byte for byte.
    #[arg(long, value_name = "I/N", value_parser = parse_shard)]
    pub(crate) shard: Option<bake::Shard>,
    /// GPU: at most this many vertices per chunk (for testing chunking; default from limits).
    #[arg(long, hide_short_help = true)]
    pub(crate) chunk_vertices: Option<u32>,
    /// GPU: at most this many samples per chunk, rounded up to a multiple of 32.
    #[arg(long, hide_short_help = true)]
    pub(crate) chunk_samples: Option<u32>,
    #[command(flatten)]
    pub(crate) local: LocalArgs,
}

/// `bake --mode local`: the depth maps and the compressed operator.
#[derive(clap::Args)]
pub(crate) struct LocalArgs {
    /// Local mode: depth-map directions per side of the hemi-octahedral grid (N^2 per receiver).
    #[arg(long, value_name = "N", default_value_t = LocalOptions::default().grid_side)]
    pub(crate) depth_grid: u32,
    /// Local mode: the depth maps compressed by clustered PCA, CLUSTERSxCOMPONENTS.
    #[arg(long, value_name = "CxM", default_value = "128x24", value_parser = parse_cpca_shape)]
    pub(crate) depth_compress: (u32, u32),
    /// Local mode: the operator's receiver clusters and basis vectors of example light per
    /// cluster, CLUSTERSxCOMPONENTS.
    #[arg(long, value_name = "CxM", default_value = "64x16", value_parser = parse_cpca_shape)]
    pub(crate) operator_compress: (u32, u32),
    /// Local mode: point lights placed across the scene for the operator's PCA bases.
    #[arg(long, default_value_t = LocalOptions::default().example_lights)]
    pub(crate) example_lights: u32,
    /// Local mode: drop a sender cluster's response in a receiver cluster below this fraction
    /// (RMS) of the receiver cluster's response (0 keeps every non-zero one).
    #[arg(long, default_value_t = LocalOptions::default().operator.sparsity)]
    pub(crate) sparsity: f32,
}

/// How a bake runs, beside what it is (its spec): the preview rendered beside it, the memory
/// it may use, the GPU's chunks.
pub(crate) struct Execution {
    pub(crate) preview: Option<PathBuf>,
    pub(crate) memory_limit: Option<u64>,
    pub(crate) chunking: Chunking,
}

impl Execution {
    pub(crate) fn of(args: &BakeArgs) -> Execution {
        Execution {
            preview: args.preview.clone(),
            memory_limit: args.memory_limit,
            chunking: Chunking {
                max_vertices: args.chunk_vertices,
                max_samples: args.chunk_samples,
                max_steps: None,
            },
        }
    }
}

/// One mesh (or the built-in scene) baked to one file.
pub(crate) fn run_one(args: &BakeArgs, mesh: Option<PathBuf>) -> Result<()> {
    let spec = bake_spec(args, &mesh)?;
    spec.validate()?;
    check_chunking(args)?;
    let device = Device::new(|| bake_backend(&spec, args.device, args.adapter.as_deref()));
    let progress = BarProgress::default();
    let execution = Execution::of(args);
    bake_one(
        &spec,
        &execution,
        &mesh,
        args.output.clone(),
        &device,
        None,
        &progress,
    )
}

/// What `bake`'s arguments ask of the bake of `mesh` (whose kind decides the container).
pub(crate) fn bake_spec(args: &BakeArgs, mesh: &Option<PathBuf>) -> Result<BakeSpec> {
    // Checked even where the bands are fixed: a nonsense option is refused, not ignored.
    spec::check_bands_threshold(args.bands_threshold)?;
    let defaults = BakeSpec::default();
    let options = args.transfer.options();
    Ok(BakeSpec {
        receivers: ReceiverSpec {
            fit: args.fit,
            fit_points: args.fit_points,
            lightmap: args.lightmap,
            lightmap_uv: args.lightmap_uv,
        },
        transfer: TransferSpec {
            bands: match args.transfer.bands {
                Bands::Fixed(bands) => spec::Bands::Fixed(bands),
                Bands::Auto => spec::Bands::Auto {
                    threshold: args.bands_threshold,
                },
            },
            samples: options.samples,
            sampling: options.sampling,
            seed: args.seed,
            mode: options.mode,
            albedo: args.albedo.map(|albedo| albedo.to_array()),
            bounces: args.bounces,
            bounce_tolerance: args.bounce_tolerance,
            target_error: args.target_error.map(|relative| TargetError {
                relative,
                max_samples: args.max_samples,
            }),
        },
        storage: StorageSpec {
            channels: args.storage,
            precision: args.precision,
            layout: args.compress.map_or(Layout::PerVertex, Layout::Cpca),
        },
        container: match mesh {
            Some(path) if scene::is_gltf(path) => Container::GltfInPlace,
            _ => Container::Mesh,
        },
        ..defaults
    })
}

/// Where the direct pass comes from: computed here, or the merged parts' (whose fingerprint
/// must be this mesh's and spec's).
fn direct_source(
    spec: &BakeSpec,
    scene: &scene::Scene,
    mesh: &Option<PathBuf>,
    merged: Option<(PartHeader, bake::DirectPass)>,
) -> Result<bake::DirectSource> {
    let Some((header, direct)) = merged else {
        return Ok(bake::DirectSource::Compute);
    };
    if shard::fingerprint(scene, &spec.fingerprint_text()) != header.fingerprint {
        return Err(Error::Merge(format!(
            "{} is not the mesh the parts were baked from (it changed since)",
            mesh_shown(mesh)
        )));
    }
    let ran_on = header.backend;
    Ok(bake::DirectSource::Given { direct, ran_on })
}

/// Writes the preview; if it cannot be written, removes the bake just written (and its
/// lightmap), since a bake is whole or not at all.
fn write_preview_or_undo(
    path: &Path,
    image: &Preview,
    output: &Path,
    lightmap: bool,
) -> Result<()> {
    let written = image.write(path);
    if written.is_err() {
        let _ = std::fs::remove_file(output);
        if lightmap {
            let _ = std::fs::remove_file(lightmap_beside(output));
        }
    }
    written
}

/// A bake's device, opened on first use — after the input and options are checked, so that
/// their errors come first — and then shared by every bake of a batch.
pub(crate) struct Device<'a> {
    opened: std::cell::OnceCell<Option<GpuBaker>>,
    open: Box<dyn Fn() -> Result<Option<GpuBaker>> + 'a>,
}

impl<'a> Device<'a> {
    pub(crate) fn new(open: impl Fn() -> Result<Option<GpuBaker>> + 'a) -> Device<'a> {
        Device {
            opened: std::cell::OnceCell::new(),
            open: Box::new(open),
        }
    }

    /// The GPU baker, or `None` for the CPU backend.
    pub(crate) fn get(&self) -> Result<&Option<GpuBaker>> {
        if let Some(baker) = self.opened.get() {
            return Ok(baker);
        }
        let baker = (self.open)()?;
        Ok(self.opened.get_or_init(|| baker))
    }
}

/// `bake` of several meshes: one device, one line per mesh and a total; a mesh that fails is
/// reported and the others still bake, the exit failing at the end.
pub(crate) fn run_batch(args: &BakeArgs, meshes: &[PathBuf]) -> Result<()> {
    for (given, flag) in [
        (
            args.output.is_some(),
            "-o names one output; a batch writes into --out-dir",
        ),
        (
            args.preview.is_some(),
            "--preview renders one bake, not a batch",
        ),
    ] {
        if given {
            return Err(Error::Options(flag.into()));
        }
    }
    if meshes.is_empty() {
        return Err(Error::Options(
            "--out-dir: no mesh to bake was given".into(),
        ));
    }
    let out_dir = args.out_dir.clone().unwrap_or_else(|| PathBuf::from("."));
    let outputs = scene::batch::output_paths(meshes, &out_dir)?;
    let inputs: Vec<&Path> = meshes.iter().map(PathBuf::as_path).collect();
    for output in &outputs {
        let output = fs::Output {
            option: "--out-dir",
            path: output,
        };
        fs::check_outputs(&[output], &inputs)?;
    }
    // The rules that hold for any mesh, checked once; each mesh's container is checked as it
    // bakes.
    let spec = bake_spec(args, &None)?;
    spec.validate()?;
    check_chunking(args)?;
    std::fs::create_dir_all(&out_dir).map_err(|e| Error::io(&out_dir, e))?;
    let device = Device::new(|| bake_backend(&spec, args.device, args.adapter.as_deref()));
    let execution = Execution::of(args);
    let started = std::time::Instant::now();
    let mut failed = Vec::new();
    let weights = scene::batch::work_weights(meshes);
    let overall = batch_bar(weights.iter().sum());
    for (k, (mesh, output)) in meshes.iter().zip(outputs).enumerate() {
        overall.set_message(format!("batch {}/{}", k + 1, meshes.len()));
        let progress = BarProgress::in_batch(k + 1, meshes.len(), &stem(mesh));
        let mesh = Some(mesh.clone());
        let baked = bake_spec(args, &mesh).and_then(|spec| {
            bake_one(
                &spec,
                &execution,
                &mesh,
                Some(output),
                &device,
                None,
                &progress,
            )
        });
        if let Err(error) = baked {
            progress.finish();
            eprintln!("error: {error}");
            failed.push(mesh_shown(&mesh));
        }
        overall.inc(weights[k]);
    }
    overall.finish_and_clear();
    println!(
        "batch: {} of {} meshes baked in {:.2} s -> {}",
        meshes.len() - failed.len(),
        meshes.len(),
        started.elapsed().as_secs_f64(),
        out_dir.display()
    );
    match failed.len() {
        0 => Ok(()),
        n => Err(Error::Batch(format!(
            "{n} of {} meshes failed: {}",
            meshes.len(),
            failed.join(", ")
        ))),
    }
}

/// One bake of `mesh` to `output` as `spec` says, its direct pass computed on the device
/// (the CPU without one) or, merging, joined from the parts of a sharded bake of the same mesh
/// and spec.
pub(crate) fn bake_one(
    spec: &BakeSpec,
    execution: &Execution,
    mesh: &Option<PathBuf>,
    output: Option<PathBuf>,
    device: &Device,
    merged: Option<(PartHeader, bake::DirectPass)>,
    progress: &BarProgress,
) -> Result<()> {
    spec.validate()?;
    let output_path = output.unwrap_or_else(|| default_output(mesh));
    // Fail before the long part (and before reading the mesh), not after it.
    check_bake_outputs(spec, execution.preview.as_deref(), mesh, &output_path, &[])?;
    let loading = std::time::Instant::now();
    let (scene, gltf, name) = load_bake_input(mesh)?;
    let seconds_load = loading.elapsed().as_secs_f64();
    let naming = |e| naming_the_mesh(e, &mesh_shown(mesh));
    let planned = pipeline::plan(spec, scene, gltf.as_ref()).map_err(naming)?;
    let options = spec.options();
    note_samples_rounded(&options);
    let baker = device.get()?;
    let backend = backend_of(baker, &execution.chunking);
    if merged.is_none() {
        let available = device::available_memory();
        let preview = execution.preview.is_some();
        let plan = pipeline::plan_memory(
            spec,
            planned.scene(),
            execution.memory_limit,
            available,
            preview,
        )?;
        if let Some(message) = plan.message {
            eprintln!("{message}");
        }
        if let Some(chunk) = plan.chunk {
            let report = planned
                .run_streamed(&backend, chunk, &output_path, progress)
                .map_err(naming)?;
            progress.finish();
            print_bake_report(&name, spec, options.bands, &report, &output_path, None);
            return Ok(());
        }
    }
    let merged_from = merged
        .as_ref()
        .map(|(header, _)| (header.shard_count, header.backend.clone()));
    let source = direct_source(spec, planned.scene(), mesh, merged)?;
    let baked = planned.run(&backend, source, progress).map_err(naming)?;
    progress.finish();
    print_shaping_lines(&baked);
    // Rendered before the .glb is written, so that a preview that cannot be made leaves no bake.
    let preview = match &execution.preview {
        Some(path) => Some((
            path,
            match baker {
                Some(baker) => render_preview(&baker.context, &baked.mesh)?,
                None => render_preview(&open_render_device(None)?, &baked.mesh)?,
            },
        )),
        None => None,
    };
    let writing = std::time::Instant::now();
    let written = pipeline::write(spec, &baked, gltf.as_ref(), &output_path)?;
    if let Some(cost) = &baked.half_float {
        eprintln!("{cost}");
    }
    let seconds_write = writing.elapsed().as_secs_f64();
    if let Some((path, image)) = preview {
        write_preview_or_undo(path, &image, &output_path, baked.mesh.lightmap.is_some())?;
    }
    if let Some(written) = written {
        print_in_place_report(&written, seconds_load, seconds_write);
    }
    let bands = baked.mesh.transfer.bands;
    print_bake_report(&name, spec, bands, &baked.report, &output_path, merged_from);
    Ok(())
}

/// What the stages after the transfer did: the bands chosen, where compression ran, what it
/// made.
fn print_shaping_lines(baked: &pipeline::Baked) {
    if let Some(chosen) = &baked.bands_chosen {
        eprintln!("{chosen}");
    }
    for note in &baked.notes {
        eprintln!("note: {note}");
    }
    if let Some(compressed) = &baked.compressed {
        eprintln!("{compressed}");
    }
}

pub(crate) fn mesh_shown(mesh: &Option<PathBuf>) -> String {
    mesh.as_ref()
        .map_or_else(|| "built-in scene".to_string(), |p| p.display().to_string())
}

pub(crate) fn note_samples_rounded(options: &BakeOptions) {
    if options.samples_used() != options.samples {
        let side = (options.samples_used() as f64).sqrt() as u32;
        eprintln!(
            "note: --samples {} is not a square; {} sampling uses {} ({side} x {side} strata)",
            options.samples,
            options.sampling.name(),
            options.samples_used()
        );
    }
}

pub(crate) fn check_chunking(args: &BakeArgs) -> Result<()> {
    for (flag, value) in [
        ("--chunk-vertices", args.chunk_vertices),
        ("--chunk-samples", args.chunk_samples),
    ] {
        if value == Some(0) {
            return Err(Error::Options(format!("{flag} must be at least 1")));
        }
    }
    Ok(())
}

/// The backend of `baker` (the CPU's without one), in `chunking`'s chunks.
pub(crate) fn backend_of<'a>(baker: &'a Option<GpuBaker>, chunking: &Chunking) -> Backend<'a> {
    match baker {
        Some(baker) => Backend::Gpu {
            baker,
            chunking: *chunking,
        },
        None => Backend::Cpu,
    }
}

/// The GPU baker a bake of `spec` uses, or `None` for the CPU backend (error-targeted bakes
/// always run there).
pub(crate) fn bake_backend(
    spec: &BakeSpec,
    device: DeviceChoice,
    adapter: Option<&str>,
) -> Result<Option<GpuBaker>> {
    if spec.transfer.target_error.is_some() {
        if device == DeviceChoice::Gpu {
            eprintln!("note: error-targeted bakes run on the CPU backend");
        }
        return Ok(None);
    }
    open_backend(device, adapter)
}

/// What `bake` bakes: the mesh named on the command line (a glTF scene keeps its document,
/// to be written back with its transfer), or the built-in scene; and a name for messages.
pub(crate) fn load_bake_input(
    mesh: &Option<PathBuf>,
) -> Result<(scene::Scene, Option<scene::gltf::GltfScene>, String)> {
    match mesh {
        Some(path) if scene::is_gltf(path) => {
            let (gltf, loaded) = scene::gltf::load(path)?;
            for note in &gltf.notes {
                eprintln!("note: {note}");
            }
            Ok((loaded, Some(gltf), stem(path)))
        }
        _ => {
            let (loaded, name) = load_scene(mesh)?;
            Ok((loaded, None, name))
        }
    }
}

/// Geometry errors come from preparation, which no longer knows the file: name it.
pub(crate) fn naming_the_mesh(error: Error, mesh: &str) -> Error {
    match error {
        Error::Geometry(_) => Error::mesh(mesh, error.to_string()),
        other => other,
    }
}

/// A preview rendered, not yet written.
struct Preview {
    pixels: Vec<[f32; 4]>,
    width: u32,
    height: u32,
}

impl Preview {
    fn write(&self, path: &Path) -> Result<()> {
        render::write_image(
            path,
            &self.pixels,
            self.width,
            self.height,
            ToneMap::Reinhard,
            0.0,
        )?;
        eprintln!("preview -> {}", path.display());
        Ok(())
    }
}

/// `baked` rendered under the default sky and sun.
fn render_preview(context: &GpuContext, baked: &bake::BakedMesh) -> Result<Preview> {
    let (width, height) = (640, 480);
    let light = light::preview_light(baked.metadata.bands)?;
    let pixels = render::preview(context, baked, &light, None, width, height)?;
    Ok(Preview {
        pixels,
        width,
        height,
    })
}

/// The name a bake of `mesh` reports and names its default output by: the mesh file's, or the
/// built-in scene's.
pub(crate) fn bake_name(mesh: &Option<PathBuf>) -> String {
    mesh.as_ref()
        .map_or_else(|| "default-scene".to_string(), |path| stem(path))
}

/// Where a bake of `mesh` goes without `-o`: `<mesh name>.prt.glb` in the current directory.
fn default_output(mesh: &Option<PathBuf>) -> PathBuf {
    PathBuf::from(format!("{}.prt.glb", bake_name(mesh)))
}

/// The lightmap a bake to `glb` writes beside it.
fn lightmap_beside(glb: &Path) -> PathBuf {
    glb.with_file_name(glb::lightmap_file_name(glb))
}

/// The files one bake writes — the .glb at `output`, the lightmap beside it (when `spec` has
/// one), the preview — checked before any work: their names end as their formats need, none is
/// the mesh, one of `inputs` (a merge's parts) or another of them, and their directories exist.
pub(crate) fn check_bake_outputs(
    spec: &BakeSpec,
    preview: Option<&Path>,
    mesh: &Option<PathBuf>,
    output: &Path,
    inputs: &[&Path],
) -> Result<()> {
    let glb_output = fs::Output {
        option: "-o",
        path: output,
    };
    let lightmap = lightmap_beside(output);
    let mut outputs = vec![glb_output];
    if spec.receivers.lightmap.is_some() {
        if fs::is_special_file(output) {
            return Err(Error::Options(format!(
                "--lightmap writes {} beside the .glb; -o {} is not a file to put it beside",
                glb::lightmap_file_name(output),
                output.display()
            )));
        }
        outputs.push(fs::Output {
            option: "-o",
            path: &lightmap,
        });
    }
    if let Some(preview) = preview {
        outputs.push(fs::Output {
            option: "--preview",
            path: preview,
        });
    }
    let mut all_inputs: Vec<&Path> = mesh.iter().map(PathBuf::as_path).collect();
    all_inputs.extend_from_slice(inputs);
    fs::check_outputs(&outputs, &all_inputs)?;
    fs::check_extension(glb_output, &["glb"], "a bake is written as binary glTF")?;
    fs::check_destination(output)?;
    if let Some(preview) = preview {
        check_preview(preview)?;
    }
    Ok(())
}

/// `--preview` names an image (.png or .exr) in a directory that exists.
pub(crate) fn check_preview(preview: &Path) -> Result<()> {
    render::check_image_output("--preview", preview)?;
    fs::check_destination(preview).map(|_| ())
}

/// What baking a glTF scene in place did.
fn print_in_place_report(written: &glb::scene::SceneWrite, seconds_load: f64, seconds_write: f64) {
    for repair in &written.repaired {
        eprintln!("warning: {repair}");
    }
    eprintln!(
        "baked in place: {} primitive(s), read in {seconds_load:.2} s, written in \
         {seconds_write:.2} s{}",
        written.primitives_baked,
        match written.mesh_copies {
            0 => String::new(),
            n => format!(
                "; {n} mesh(es) shown by several nodes copied, one per placement \
                 (each place sees its own occlusion)"
            ),
        }
    );
}

/// The parts a bake was merged from: how many, and the backend they ran on.
type MergedFrom = Option<(u32, String)>;

/// One line for each stage that ran besides the direct pass: bounces, gather matrix, fit,
/// error target, lightmap (written beside `output`).
fn print_stage_lines(report: &BakeReport, output: &Path) {
    for (i, bounce) in report.bounces.iter().enumerate() {
        eprintln!(
            "bounce {}: +{:.2}% energy in {:.2} s",
            i + 1,
            100.0 * bounce.relative_energy,
            bounce.seconds
        );
    }
    if report.gather_entries > 0 {
        // Each entry is a u32 column and an f32 weight.
        eprintln!(
            "gather matrix: {} entries ({:.1} MiB)",
            report.gather_entries,
            (report.gather_entries * 8) as f64 / (1u64 << 20) as f64
        );
    }
    if let Some(fit) = &report.fit {
        eprintln!(
            "least-squares fit: {} surface points, solved in {:.2} s ({} iterations, residual \
             {:.1e}, {} matrix entries)",
            report.receivers,
            report.seconds_fit,
            fit.iterations,
            fit.relative_residual,
            fit.matrix_entries
        );
    }
    if let Some(adaptive) = &report.adaptive {
        eprintln!(
            "target error: samples per receiver {} / {} / {} (min / median / max, mean {:.0}), \
             {} at the cap; estimated error {:.2e} / {:.2e} / {:.2e} (median / 90% / max)",
            adaptive.samples_min,
            adaptive.samples_median,
            adaptive.samples_max,
            adaptive.samples_mean,
            adaptive.at_cap,
            adaptive.error_median,
            adaptive.error_p90,
            adaptive.error_max
        );
    }
    if let Some(texels) = &report.texels {
        eprintln!(
            "lightmap: {}x{} texels, {} covered ({} inside geometry, refilled), {} rays in \
             {:.2} s -> {}",
            texels.width,
            texels.height,
            texels.covered,
            texels.leaking,
            texels.rays_cast,
            texels.seconds,
            output
                .with_file_name(glb::lightmap_file_name(output))
                .display()
        );
    }
}

/// A finished bake's report: what prepare repaired, a line per stage, the one summary line.
fn print_bake_report(
    name: &str,
    spec: &BakeSpec,
    bands: u32,
    report: &BakeReport,
    output: &Path,
    merged_from: MergedFrom,
) {
    if let Some(repairs) = report.prepare.repairs() {
        eprintln!("warning: {name}: {repairs}");
    }
    print_stage_lines(report, output);
    let seconds_bounces: f64 = report.bounces.iter().map(|b| b.seconds).sum();
    let seconds_texels = report.texels.map_or(0.0, |t| t.seconds);
    let seconds = report.seconds_prepare
        + report.seconds_transfer
        + report.seconds_fit
        + seconds_bounces
        + seconds_texels;
    let rays_per_second = report.rays_cast as f64 / report.seconds_transfer.max(1e-9);
    let rays = match merged_from {
        None => format!(
            "{} rays in {:.2} s ({:.2} M rays/s)",
            report.rays_cast,
            report.seconds_transfer,
            rays_per_second / 1e6
        ),
        Some((parts, ran_on)) => format!(
            "{} rays in {parts} shards ({ran_on}), merged",
            report.rays_cast
        ),
    };
    println!(
        "baked {name}: {} vertices, {} triangles, {} bands, {} {} samples, {} mode; {rays}, \
         {:.2} s in all ({}) -> {}",
        report.prepare.vertices,
        report.prepare.triangles,
        bands,
        match &report.adaptive {
            Some(adaptive) => format!("{:.0} (mean)", adaptive.samples_mean),
            None => report.samples_used.to_string(),
        },
        spec.transfer.sampling.name(),
        spec.transfer.mode.name(),
        seconds,
        report.backend,
        output.display()
    );
}

/// The GPU baker for `choice`, or `None` for the CPU backend (saying why when it was not asked
/// for). `bake`, `chart` and `bench` all open their backend here.
pub(crate) fn open_backend(
    choice: DeviceChoice,
    adapter: Option<&str>,
) -> Result<Option<GpuBaker>> {
    let baker = GpuBaker::open(choice, adapter)?;
    if baker.is_none() && choice == DeviceChoice::Auto {
        match device::list_adapters().first() {
            Some(best) => eprintln!(
                "note: only software GPU adapters ({}); the CPU backend is faster on the same \
                 cores and bakes instead (--device gpu forces the adapter)",
                best.name
            ),
            None => eprintln!("note: no GPU adapter found; baking on the CPU backend"),
        }
    }
    Ok(baker)
}

/// The mesh named on the command line, or the built-in scene; and a name for messages.
pub(crate) fn load_scene(mesh: &Option<PathBuf>) -> Result<(scene::Scene, String)> {
    match mesh {
        Some(path) => Ok((load_mesh(path)?, stem(path))),
        None => Ok((scene::builtin::default_scene(), "default-scene".to_string())),
    }
}

/// A mesh file, saying what its reader repaired (one `warning:` line each).
pub(crate) fn load_mesh(path: &Path) -> Result<scene::Scene> {
    let (scene, warnings) = scene::load_with_warnings(path)?;
    for warning in warnings {
        eprintln!("warning: {}: {warning}", stem(path));
    }
    Ok(scene)
}

/// The name a mesh file is reported by.
pub(crate) fn stem(path: &Path) -> String {
    scene::batch::mesh_name(path)
}

/// Any adapter, software ones included: rasterising a preview is cheap anywhere.
pub(crate) fn open_render_device(adapter: Option<&str>) -> Result<GpuContext> {
    device::open(DeviceChoice::Gpu, adapter)?
        .ok_or_else(|| Error::Gpu("no adapter to render with".into()))
}
