//! The `prt-gpu` command line: parse, call the library, report. No baking logic lives here.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Mutex;

use clap::{Parser, Subcommand};
use glam::Vec3;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

use prt_gpu::bake::adaptive::TargetError;
use prt_gpu::bake::gpu::{Chunking, GpuBaker};
use prt_gpu::bake::{
    self, Backend, BakeOptions, BakeReport, Fit, Mode, Progress, Storage, DEFAULT_SAMPLES,
    DEFAULT_SAMPLING,
};
use prt_gpu::compress::{self, Cpca, CpcaOptions};
use prt_gpu::device::{self, DeviceChoice, GpuContext};
use prt_gpu::glb::Precision;
use prt_gpu::light::{self, analytic, EnvImage, Mapping, ShLight};
use prt_gpu::local::build::OperatorShape;
use prt_gpu::local::lights::{self as local_lights, LocalLight};
use prt_gpu::local::{self, LocalOptions, OperatorForm};
use prt_gpu::receivers::PointDensity;
use prt_gpu::render::{self, Camera, ToneMap};
use prt_gpu::sampling::Sampling;
use prt_gpu::sh::window::Window;
use prt_gpu::sh::MAX_BANDS;
use prt_gpu::shard::{self, Part, PartHeader};
use prt_gpu::sweep::{self, SweepOptions};
use prt_gpu::{chart, fs, glb, scene, view, x3d, Error, Result};

/// `println!` that ends quietly when the reader of stdout has gone (`prt-gpu bake | head -1`),
/// where the standard one panics: every report line of the CLI goes through it. The progress
/// bars step aside while it prints, so a line never lands inside a bar.
macro_rules! println {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let line = format!($($arg)*);
        bars().suspend(|| {
            let _ = writeln!(std::io::stdout(), "{line}");
        });
    }};
}

/// `eprintln!` with the progress bars stepped aside, as [`println!`].
macro_rules! eprintln {
    ($($arg:tt)*) => {{
        let line = format!($($arg)*);
        bars().suspend(|| std::eprintln!("{line}"));
    }};
}

/// Every progress bar of the run, drawn together on stderr (hidden when stderr is not a
/// terminal): a batch's bar over all its meshes, and the bar of the stage running.
fn bars() -> &'static MultiProgress {
    static BARS: std::sync::OnceLock<MultiProgress> = std::sync::OnceLock::new();
    BARS.get_or_init(MultiProgress::new)
}

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
    /// Project lighting onto SH: an environment map and/or analytic lights (they add up).
    Light(LightArgs),
    /// Relight baked files under a light and render them side by side to PNG or EXR.
    Render(RenderArgs),
    /// Write a self-contained web viewer (one HTML file, WebGL2) of baked files and a light.
    View(ViewArgs),
    /// Export a baked file for other run-times.
    #[command(subcommand)]
    Export(ExportCommand),
    /// Chart speed against accuracy: every sampling strategy and backend over a sweep of
    /// sample counts, against a high-sample reference bake (SVG or PNG, plus a CSV beside it).
    Chart(ChartArgs),
    /// Time the direct-transfer pass on the CPU and GPU backends side by side (rays/s).
    Bench(BenchArgs),
    /// Join the parts of a sharded bake (`bake … --shard I/N`) into the file the unsharded bake
    /// writes, byte for byte; bounces, fits and lightmaps run here.
    Merge(MergeArgs),
}

#[derive(clap::Args)]
struct MergeArgs {
    /// Part files written by `prt-gpu bake … --shard I/N`, in any order, one per shard.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output file (.glb). Default: <mesh name>.prt.glb in the current directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Also render a preview of the result under a default sky and sun (.png or .exr).
    #[arg(long)]
    preview: Option<PathBuf>,
}

#[derive(clap::Args)]
struct ChartArgs {
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
    /// Lightmap sizes, comma-separated: each strategy and count is also baked per texel at
    /// each, for the surface panel (the vertex errors of these points are their vertices').
    #[arg(long, value_delimiter = ',', value_name = "SIZES")]
    lightmap: Vec<u32>,
    /// Error targets, comma-separated: each strategy is also baked to each (`bake
    /// --target-error`, on the CPU backend, at most 16,384 samples a receiver).
    #[arg(long, value_delimiter = ',', value_name = "ERRORS")]
    target_error: Vec<f64>,
}

/// What `bake` and `bench` compute per vertex.
#[derive(clap::Args)]
struct TransferArgs {
    /// Spherical-harmonic bands (bands^2 coefficients per channel), or `auto` (bake only): the
    /// fewest bands, up to 8, that leave less than --bands-threshold of the transfer's energy
    /// above them.
    #[arg(long, default_value = "4", value_parser = parse_bands)]
    bands: Bands,
    /// Sample directions per vertex (rounded to the nearest square for stratified sampling).
    /// Default 1024; 256 gather rays per receiver with --mode local.
    #[arg(long)]
    samples: Option<u32>,
    /// How sample directions are drawn and weighted. cosine (the default) casts every ray above
    /// the horizon, with the cosine in its density; see `prt-gpu chart`.
    #[arg(long, value_enum, default_value_t = DEFAULT_SAMPLING)]
    sampling: Sampling,
    /// Light transport to capture.
    #[arg(long, value_enum, default_value_t = Mode::Shadowed)]
    mode: Mode,
}

/// `--bands`: a count, or chosen from the transfer.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Bands {
    Fixed(u32),
    Auto,
}

/// The most bands `--bands auto` bakes and chooses among.
const AUTO_MAX_BANDS: u32 = 8;

fn parse_bands(text: &str) -> std::result::Result<Bands, String> {
    if text.eq_ignore_ascii_case("auto") {
        return Ok(Bands::Auto);
    }
    text.parse::<u32>()
        .map(Bands::Fixed)
        .map_err(|e| format!("expected a number of bands or auto: {e}"))
}

impl TransferArgs {
    /// Bake options with these settings and defaults for the rest (`auto` bands bake the most
    /// it chooses among).
    fn options(&self) -> BakeOptions {
        BakeOptions {
            bands: match self.bands {
                Bands::Fixed(bands) => bands,
                Bands::Auto => AUTO_MAX_BANDS,
            },
            samples: self.samples.unwrap_or(DEFAULT_SAMPLES),
            sampling: self.sampling,
            mode: self.mode,
            ..BakeOptions::default()
        }
    }
}

#[derive(clap::Args)]
struct BenchArgs {
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
}

/// How a light is post-processed, shared by `light` and `render`.
#[derive(clap::Args)]
struct LightShaping {
    /// Ringing control: none, hanning, lanczos, or non-negative (the least smoothing that
    /// leaves no negative radiance anywhere).
    #[arg(long, value_enum, default_value_t = Window::None)]
    window: Window,
    /// Rotate the light: yaw (about +Y), pitch (about +X), roll (about +Z), in degrees.
    #[arg(long, value_parser = parse_rgb, allow_hyphen_values = true)]
    rotate: Option<Vec3>,
}

#[derive(clap::Args)]
struct LightArgs {
    /// Environment map: OpenEXR, Radiance .hdr, PNG or JPEG.
    envmap: Option<PathBuf>,
    /// SH bands of the light.
    #[arg(long, default_value_t = 4)]
    bands: u32,
    /// How the map's pixels map to directions (auto-detected from the aspect ratio when it
    /// is unambiguous: 2:1 lat-long, 4:3 and 3:4 cube crosses).
    #[arg(long, value_enum)]
    mapping: Option<Mapping>,
    /// Give NaN or infinite pixels zero weight instead of failing.
    #[arg(long)]
    skip_invalid: bool,
    /// A cube map as six separate faces: +X,-X,+Y,-Y,+Z,-Z image paths, comma-separated.
    #[arg(long, value_delimiter = ',', conflicts_with = "envmap")]
    faces: Vec<PathBuf>,
    /// Add a directional light (a delta): direction X,Y,Z towards the light.
    #[arg(long, value_parser = parse_rgb, allow_hyphen_values = true)]
    directional: Option<Vec3>,
    /// Irradiance of --directional (R,G,B or one value).
    #[arg(long, value_parser = parse_rgb, default_value = "1")]
    directional_intensity: Vec3,
    /// Add a sun: direction X,Y,Z (towards the sun).
    #[arg(long, value_parser = parse_rgb, allow_hyphen_values = true)]
    sun: Option<Vec3>,
    /// Sun disk half-angle in degrees.
    #[arg(long, default_value_t = 0.27)]
    sun_angle: f64,
    /// Sun irradiance (R,G,B or one value).
    #[arg(long, value_parser = parse_rgb, default_value = "3")]
    sun_irradiance: Vec3,
    /// Add a sky of this radiance above the horizon (R,G,B).
    #[arg(long, value_parser = parse_rgb)]
    sky: Option<Vec3>,
    /// Ground radiance below the horizon, with --sky.
    #[arg(long, value_parser = parse_rgb, default_value = "0")]
    ground: Vec3,
    /// Add constant ambient radiance (R,G,B).
    #[arg(long, value_parser = parse_rgb)]
    ambient: Option<Vec3>,
    /// Add the tutorial's two-light test function.
    #[arg(long)]
    tutorial: bool,
    #[command(flatten)]
    shaping: LightShaping,
    /// Output light.json.
    #[arg(short, long, default_value = "light.json")]
    output: PathBuf,
}

#[derive(clap::Args)]
struct RenderArgs {
    /// Baked .glb files; several are rendered side by side, left to right.
    #[arg(required = true)]
    baked: Vec<PathBuf>,
    /// The light: light.json, or an environment map projected at each file's bands.
    #[arg(long)]
    light: Option<PathBuf>,
    /// Environment-map parameterization (with --light ENVMAP).
    #[arg(long, value_enum)]
    mapping: Option<Mapping>,
    #[command(flatten)]
    shaping: LightShaping,
    /// Camera: eye x,y,z, target x,y,z [, vertical field of view in degrees]. Default: a
    /// three-quarter view that frames the mesh.
    #[arg(long, allow_hyphen_values = true)]
    camera: Option<Camera>,
    /// Draw the light behind the model as a sky dome (the SH light the model is lit by, so
    /// as smooth as its band count); without it the background is transparent black.
    #[arg(long)]
    sky: bool,
    /// Exposure in stops (PNG only).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    exposure: f32,
    /// Tone mapping for PNG; EXR keeps linear radiance.
    #[arg(long, value_enum, default_value_t = ToneMap::Reinhard)]
    tone_map: ToneMap,
    /// Size of each panel in pixels.
    #[arg(long, default_value_t = 640)]
    width: u32,
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Use the adapter whose name contains this text.
    #[arg(long)]
    adapter: Option<String>,
    /// Local-lights bakes: a point light at X,Y,Z of radiant intensity I (W/sr, default 1;
    /// irradiance I cos(theta) / r^2). Repeatable.
    #[arg(long, value_name = "X,Y,Z[,I]", allow_hyphen_values = true)]
    point_light: Vec<String>,
    /// Local-lights bakes: a spot light at X,Y,Z opening towards DX,DY,DZ with a hard cone of
    /// half angle A degrees, intensity I inside it (default 1). Repeatable.
    #[arg(long, value_name = "X,Y,Z,DX,DY,DZ,A[,I]", allow_hyphen_values = true)]
    spot_light: Vec<String>,
    /// Local-lights bakes: render N frames with the lights carried once round a circle about
    /// the vertical axis through the scene's centre (images OUTPUT_000.png, ...), and report
    /// the per-frame relighting time of each operator on the CPU and on the GPU (--device).
    #[arg(long, value_name = "N")]
    frames: Option<u32>,
    /// Local-lights bakes: where the relighting runs besides the CPU. `gpu`: both operators on
    /// any adapter (lavapipe included), an error without one; `cpu`: the CPU only; `auto`: a
    /// hardware GPU too where there is one.
    #[arg(long, value_enum, default_value_t = DeviceChoice::Auto)]
    device: DeviceChoice,
    /// With --frames: the circle's axis passes through X,Y,Z instead of the scene's centre.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true)]
    orbit: Option<Vec3>,
    /// Local-lights bakes: the direct-to-indirect operator the images use.
    #[arg(long, value_enum, default_value_t = OperatorForm::Compressed)]
    operator: OperatorForm,
    /// Output: an image, .png (tone-mapped sRGB) or .exr (linear HDR); or .glb: a copy of the
    /// (one) baked file with each vertex's relit radiance as its COLOR_0.
    #[arg(short, long, default_value = "preview.png")]
    output: PathBuf,
}

#[derive(Subcommand)]
enum ExportCommand {
    /// An X3D scene (XML): the transfer as per-vertex FloatVertexAttribute nodes and a
    /// ComposedShader that dots them with the light, a field of the shader.
    X3d(X3dArgs),
}

#[derive(clap::Args)]
struct X3dArgs {
    /// A baked .glb (per vertex).
    baked: PathBuf,
    /// The light: light.json (at least the file's bands), or an environment map projected at
    /// the file's bands. Default: the preview's sky and sun.
    #[arg(long)]
    light: Option<PathBuf>,
    /// Environment-map parameterization (with --light ENVMAP).
    #[arg(long, value_enum)]
    mapping: Option<Mapping>,
    #[command(flatten)]
    shaping: LightShaping,
    /// The viewpoint: eye x,y,z, target x,y,z [, field of view in degrees]. Default: render's
    /// framing.
    #[arg(long, allow_hyphen_values = true)]
    camera: Option<Camera>,
    /// Exposure in stops, a field of the shader.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    exposure: f32,
    /// Tone mapping in the shader.
    #[arg(long, value_enum, default_value_t = ToneMap::Reinhard)]
    tone_map: ToneMap,
    /// Output scene.
    #[arg(short, long, default_value = "scene.x3d")]
    output: PathBuf,
}

#[derive(clap::Args)]
struct ViewArgs {
    /// Baked .glb files (per vertex); the page switches between them.
    #[arg(required = true)]
    baked: Vec<PathBuf>,
    /// The light: light.json (at least as many bands as every file), or an environment map
    /// projected at the most bands of the files. Default: the preview's sky and sun.
    #[arg(long)]
    light: Option<PathBuf>,
    /// Environment-map parameterization (with --light ENVMAP).
    #[arg(long, value_enum)]
    mapping: Option<Mapping>,
    /// Windowing and a starting rotation of the light (the page turns it further).
    #[command(flatten)]
    shaping: LightShaping,
    /// Output page.
    #[arg(short, long, default_value = "viewer.html")]
    output: PathBuf,
}

#[derive(clap::Args)]
struct BakeArgs {
    /// Mesh to bake: a glTF scene (.gltf, .glb: written back with its transfer added), .obj,
    /// .ply or .ply.gz. Without it, the built-in scene (a sphere and a box on a ground plane
    /// beside a wall). Several meshes, directories (their mesh files) or quoted glob patterns
    /// bake as a batch into --out-dir, one device for all.
    #[arg(value_name = "MESH")]
    meshes: Vec<PathBuf>,
    /// Batch: the directory each <mesh name>.prt.glb is written to (created if missing).
    #[arg(long, value_name = "DIR")]
    out_dir: Option<PathBuf>,
    #[command(flatten)]
    transfer: TransferArgs,
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
    /// How vertex values are made: `point` bakes at the vertices (exact there); `least-squares`
    /// bakes at points spread over every triangle and fits the vertex values whose
    /// interpolation matches them best over the surface (Kavan et al. 2011), at the cost of
    /// `--fit-points` times the vertices' rays per sample.
    #[arg(long, value_enum, default_value_t = Fit::Point)]
    fit: Fit,
    /// Least-squares fit: surface points baked per vertex of the mesh, on average (every
    /// triangle gets at least three).
    #[arg(long, default_value_t = PointDensity::default().per_vertex)]
    fit_points: f32,
    /// Bake to an error target instead of a fixed sample count: each receiver casts batches of
    /// 32 samples (at least 8) until the standard error of its transfer, relative to unoccluded
    /// transfer's norm, is below E. Shadowed and unshadowed modes; runs on the CPU backend.
    #[arg(long, value_name = "E")]
    target_error: Option<f64>,
    /// With --target-error: the most samples one receiver casts.
    #[arg(long, default_value_t = 4096)]
    max_samples: u32,
    /// With --bands auto: the largest fraction of the transfer's energy (squared coefficients
    /// over vertices and channels) the bands left out may hold.
    #[arg(long, default_value_t = 0.05)]
    bands_threshold: f64,
    /// How to store the transfer: `rgb`, or `lean` — one channel where one suffices
    /// (shadowed and unshadowed transfer albedo-free, the albedo applied at relighting from
    /// COLOR_0; interreflected transfer when every albedo is grey), a third of the size.
    #[arg(long, value_enum, default_value_t = Storage::Rgb)]
    storage: Storage,
    /// Precision of the stored transfer: `f32`, or `f16` (IEEE half floats: half the bytes,
    /// each value within 2^-11 of itself relative; the added relit error is reported). glTF has
    /// no half-float attributes, so an f16 file names its transfer view in extras.prt instead of
    /// the _PRT_* attributes. With --compress, the means, bases and weights are half floats and
    /// each cluster index takes the fewest bytes that hold it (1 up to 256 clusters).
    #[arg(long, value_enum, default_value_t = Precision::F32)]
    precision: Precision,
    /// Store the transfer compressed by clustered PCA (Sloan et al. 2003): CLUSTERSxCOMPONENTS,
    /// e.g. 64x8 — per vertex a cluster and COMPONENTS weights, per cluster a mean and a basis —
    /// or auto:E, the smallest shape (of a grid of them) whose coefficient error is below E.
    /// Sizes and the error against the uncompressed transfer are reported.
    #[arg(long, value_name = "CLUSTERSxCOMPONENTS|auto:E", value_parser = parse_compression)]
    compress: Option<Compression>,
    /// Also bake per-texel transfer into a lightmap about SIZE texels on its longer side (a
    /// generated atlas): written as <output stem>.lightmap.exr beside the .glb, which then
    /// holds the lightmap coordinates as TEXCOORD_0 (every triangle corner its own vertex).
    #[arg(long, value_name = "SIZE")]
    lightmap: Option<u32>,
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
    /// Also render a preview of the result under a default sky and sun (.png or .exr).
    #[arg(long)]
    preview: Option<PathBuf>,
    /// Most memory the bake may use, e.g. 512M or 8G (binary units). A shadowed or unshadowed
    /// bake of OBJ, PLY or the built-in scene that would need more streams its transfer to the
    /// file in chunks that fit; one that cannot fit says so before it starts. Default: the
    /// memory this machine has available (when that is too little, a warning).
    #[arg(long, value_name = "SIZE", value_parser = parse_size)]
    memory_limit: Option<u64>,
    /// Bake only shard I of N (counted from 0): a contiguous run of about 1/N of the receivers,
    /// written as a part file (default <mesh name>.prt.I-of-N.part); `prt-gpu merge` joins
    /// the N parts into the file this bake without --shard writes, byte for byte.
    #[arg(long, value_name = "I/N", value_parser = parse_shard)]
    shard: Option<bake::Shard>,
    /// GPU: at most this many vertices per chunk (for testing chunking; default from limits).
    #[arg(long, hide_short_help = true)]
    chunk_vertices: Option<u32>,
    /// GPU: at most this many samples per chunk, rounded up to a multiple of 32.
    #[arg(long, hide_short_help = true)]
    chunk_samples: Option<u32>,
    #[command(flatten)]
    local: LocalArgs,
}

/// `bake --mode local`: the depth maps and the compressed operator.
#[derive(clap::Args)]
struct LocalArgs {
    /// Local mode: depth-map directions per side of the hemi-octahedral grid (N^2 per receiver).
    #[arg(long, value_name = "N", default_value_t = LocalOptions::default().grid_side)]
    depth_grid: u32,
    /// Local mode: the depth maps compressed by clustered PCA, CLUSTERSxCOMPONENTS.
    #[arg(long, value_name = "CxM", default_value = "64x24", value_parser = parse_cpca_shape)]
    depth_compress: (u32, u32),
    /// Local mode: the operator's receiver clusters and basis vectors of example light per
    /// cluster, CLUSTERSxCOMPONENTS.
    #[arg(long, value_name = "CxM", default_value = "64x16", value_parser = parse_cpca_shape)]
    operator_compress: (u32, u32),
    /// Local mode: point lights placed across the scene for the operator's PCA bases.
    #[arg(long, default_value_t = LocalOptions::default().example_lights)]
    example_lights: u32,
    /// Local mode: drop a sender cluster's response in a receiver cluster below this fraction
    /// (RMS) of the receiver cluster's response (0 keeps every non-zero one).
    #[arg(long, default_value_t = LocalOptions::default().operator.sparsity)]
    sparsity: f32,
}

/// `--compress`: a shape, or an error target to choose one by.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Compression {
    Shape(u32, u32),
    Target(f64),
}

fn parse_compression(text: &str) -> std::result::Result<Compression, String> {
    match text.strip_prefix("auto:") {
        Some(target) => target
            .trim()
            .parse::<f64>()
            .map(Compression::Target)
            .map_err(|e| format!("expected auto:ERROR, such as auto:0.02: {e}")),
        None => parse_cpca_shape(text).map(|(k, m)| Compression::Shape(k, m)),
    }
}

fn parse_size(text: &str) -> std::result::Result<u64, String> {
    let text = text.trim();
    let split = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(split);
    let shift = match unit
        .trim()
        .to_ascii_uppercase()
        .trim_end_matches("IB")
        .trim_end_matches('B')
    {
        "" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return Err(format!("expected a size such as 512M or 8G, not {text}")),
    };
    match number.parse::<f64>() {
        Ok(value) if value > 0.0 && value.is_finite() => {
            Ok((value * (1u64 << shift) as f64) as u64)
        }
        _ => Err(format!("expected a size such as 512M or 8G, not {text}")),
    }
}

fn parse_shard(text: &str) -> std::result::Result<bake::Shard, String> {
    let numbers = text
        .split_once('/')
        .and_then(|(i, n)| Some((i.trim().parse::<u32>().ok()?, n.trim().parse::<u32>().ok()?)));
    let Some((index, count)) = numbers else {
        return Err("expected I/N, shard I of N counted from 0 (e.g. 0/4)".into());
    };
    bake::Shard::new(index, count).map_err(|e| e.to_string())
}

fn parse_cpca_shape(text: &str) -> std::result::Result<(u32, u32), String> {
    let (clusters, components) = text
        .split_once(['x', 'X'])
        .ok_or("expected CLUSTERSxCOMPONENTS, such as 64x8")?;
    let number = |t: &str| {
        t.trim()
            .parse::<u32>()
            .map_err(|e| format!("expected CLUSTERSxCOMPONENTS, such as 64x8: {e}"))
    };
    Ok((number(clusters)?, number(components)?))
}

fn parse_point(text: &str) -> std::result::Result<Vec3, String> {
    let v = text
        .split(',')
        .map(|part| part.trim().parse::<f32>())
        .collect::<std::result::Result<Vec<f32>, _>>()
        .map_err(|e| format!("expected X,Y,Z: {e}"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3::new(x, y, z)),
        _ => Err("expected three finite numbers X,Y,Z".into()),
    }
}

fn parse_rgb(text: &str) -> std::result::Result<Vec3, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let values: std::result::Result<Vec<f32>, _> = match parts.len() {
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
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => e.exit(),
        Err(e) => {
            eprintln!("{}", usage_error_line(&e.to_string()));
            return ExitCode::from(2);
        }
    };
    let result = match cli.command {
        Command::Bake(args) => run_bake(args),
        Command::Info { file } => run_info(&file),
        Command::Devices => run_devices(),
        Command::Light(args) => run_light(args),
        Command::Render(args) => run_render(args),
        Command::View(args) => run_view(args),
        Command::Export(ExportCommand::X3d(args)) => run_export_x3d(args),
        Command::Chart(args) => run_chart(args),
        Command::Bench(args) => run_bench(args),
        Command::Merge(args) => run_merge(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::FAILURE
        }
    }
}

/// clap's multi-line usage error as one line: the error, and the possible values if listed.
fn usage_error_line(message: &str) -> String {
    let mut lines = message.lines().map(str::trim).filter(|l| !l.is_empty());
    let mut line = lines
        .next()
        .unwrap_or("error: invalid arguments")
        .to_string();
    if let Some(values) = lines.find(|l| l.starts_with("[possible values")) {
        line.push(' ');
        line.push_str(values);
    }
    line
}

fn run_bake(args: BakeArgs) -> Result<()> {
    if args.transfer.mode == Mode::Local {
        return run_local_bake(args);
    }
    let meshes = scene::batch::mesh_files(&args.meshes)?;
    if let Some(shard) = args.shard {
        return match meshes.as_slice() {
            [_, _, ..] => Err(Error::Options("--shard bakes one mesh, not a batch".into())),
            _ => run_shard(&args, &meshes.first().cloned(), shard),
        };
    }
    if meshes.len() > 1 || args.out_dir.is_some() {
        return run_batch(&args, &meshes);
    }
    let options = bake_options(&args)?;
    options.validate()?;
    check_chunking(&args)?;
    let device = Device::new(|| bake_backend(&options, args.device, args.adapter.as_deref()));
    let progress = BarProgress::default();
    let mesh = meshes.first().cloned();
    bake_one(&args, &mesh, args.output.clone(), &device, None, &progress)
}

/// A bake's device, opened on first use — after the input and options are checked, so that
/// their errors come first — and then shared by every bake of a batch.
struct Device<'a> {
    opened: std::cell::OnceCell<Option<GpuBaker>>,
    open: Box<dyn Fn() -> Result<Option<GpuBaker>> + 'a>,
}

impl<'a> Device<'a> {
    fn new(open: impl Fn() -> Result<Option<GpuBaker>> + 'a) -> Device<'a> {
        Device {
            opened: std::cell::OnceCell::new(),
            open: Box::new(open),
        }
    }

    /// The GPU baker, or `None` for the CPU backend.
    fn get(&self) -> Result<&Option<GpuBaker>> {
        if let Some(baker) = self.opened.get() {
            return Ok(baker);
        }
        let baker = (self.open)()?;
        Ok(self.opened.get_or_init(|| baker))
    }
}

/// `bake` of several meshes: one device, one line per mesh and a total; a mesh that fails is
/// reported and the others still bake, the exit failing at the end.
fn run_batch(args: &BakeArgs, meshes: &[PathBuf]) -> Result<()> {
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
    let options = bake_options(args)?;
    options.validate()?;
    check_chunking(args)?;
    std::fs::create_dir_all(&out_dir).map_err(|e| Error::io(&out_dir, e))?;
    let device = Device::new(|| bake_backend(&options, args.device, args.adapter.as_deref()));
    let started = std::time::Instant::now();
    let mut failed = Vec::new();
    let weights = scene::batch::work_weights(meshes);
    let overall = batch_bar(weights.iter().sum());
    for (k, (mesh, output)) in meshes.iter().zip(outputs).enumerate() {
        overall.set_message(format!("batch {}/{}", k + 1, meshes.len()));
        let progress = BarProgress::in_batch(k + 1, meshes.len(), &stem(mesh));
        let mesh = Some(mesh.clone());
        if let Err(error) = bake_one(args, &mesh, Some(output), &device, None, &progress) {
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

/// One bake of `mesh` to `output`, its direct pass computed on `baker` (the CPU without one)
/// or, merging, joined from the parts of a sharded bake of the same mesh and options.
fn bake_one(
    args: &BakeArgs,
    mesh: &Option<PathBuf>,
    output: Option<PathBuf>,
    device: &Device,
    merged: Option<(PartHeader, bake::DirectPass)>,
    progress: &BarProgress,
) -> Result<()> {
    let options = bake_options(args)?;
    let loading = std::time::Instant::now();
    let (scene, gltf, name) = load_bake_input(mesh)?;
    check_output_forms(args, &options, gltf.is_some())?;
    let seconds_load = loading.elapsed().as_secs_f64();
    let output_path = output.unwrap_or_else(|| PathBuf::from(format!("{name}.prt.glb")));
    // Fail before the long part, not after it.
    fs::check_destination(&output_path)?;
    if let Some(preview) = &args.preview {
        fs::check_destination(preview)?;
    }
    note_samples_rounded(&options);
    let baker = device.get()?;
    if merged.is_none() {
        if let Some(chunk) = memory_plan(args, &options, &scene, gltf.is_some())? {
            let planned = bake::stream::StreamedBake::plan(scene, &options)
                .map_err(|e| naming_the_mesh(e, &mesh_shown(mesh)))?;
            let backend = backend_of(baker, args);
            let report =
                glb::stream::bake_streamed(&planned, &backend, chunk, &output_path, progress)?;
            progress.finish();
            print_bake_report(&name, &options, &report, &output_path, None);
            return Ok(());
        }
    }
    let merged_from = merged
        .as_ref()
        .map(|(header, _)| (header.shard_count, header.backend.clone()));
    let source = match merged {
        None => bake::DirectSource::Compute,
        Some((header, direct)) => {
            if shard::fingerprint(&scene, &fingerprinted_options(args, &options))
                != header.fingerprint
            {
                return Err(Error::Merge(format!(
                    "{} is not the mesh the parts were baked from (it changed since)",
                    mesh_shown(mesh)
                )));
            }
            let ran_on = header.backend;
            bake::DirectSource::Given { direct, ran_on }
        }
    };
    let backend = backend_of(baker, args);
    let (mut baked, report) = bake::bake_from(scene, &options, &backend, source, progress)
        .map_err(|e| naming_the_mesh(e, &mesh_shown(mesh)))?;
    progress.finish();
    let mut options = options;
    if args.transfer.bands == Bands::Auto {
        options.bands = choose_auto_bands(&mut baked, args.bands_threshold);
    }
    let cpca = match args.compress {
        Some(shape) => Some(compress_transfer(
            &baked,
            shape,
            args.precision,
            baker.as_ref().map(|b| &b.context),
        )?),
        None => None,
    };
    let writing = std::time::Instant::now();
    let written = match &gltf {
        Some(gltf) => Some(glb::scene::write_scene_glb(
            &output_path,
            gltf,
            &baked,
            &report.vertex_map,
        )?),
        None => {
            glb::write_glb_as(&output_path, &baked, cpca.as_ref(), args.precision)?;
            None
        }
    };
    if args.precision == Precision::F16 && cpca.is_none() {
        report_f16_error(&baked)?;
    }
    let seconds_write = writing.elapsed().as_secs_f64();
    if let Some(preview) = &args.preview {
        match baker {
            Some(baker) => write_preview(&baker.context, &baked, preview)?,
            None => write_preview(&open_render_device(None)?, &baked, preview)?,
        }
    }
    if let Some(written) = written {
        print_in_place_report(&written, seconds_load, seconds_write);
    }
    print_bake_report(&name, &options, &report, &output_path, merged_from);
    Ok(())
}

/// `bake … --shard I/N`: the direct pass of one shard's receivers, written as a part file.
fn run_shard(args: &BakeArgs, mesh: &Option<PathBuf>, shard: bake::Shard) -> Result<()> {
    let options = bake_options(args)?;
    options.validate()?;
    let (scene, gltf, name) = load_bake_input(mesh)?;
    check_output_forms(args, &options, gltf.is_some())?;
    if args.preview.is_some() {
        return Err(Error::Options(
            "--preview renders a whole bake: give it to `prt-gpu merge`, not to a shard".into(),
        ));
    }
    let output = args.output.clone().unwrap_or_else(|| {
        PathBuf::from(format!(
            "{name}.prt.{}-of-{}.part",
            shard.index, shard.count
        ))
    });
    fs::check_destination(&output)?;
    check_shard_memory(args, &options, &scene, shard)?;
    note_samples_rounded(&options);
    check_chunking(args)?;
    let fingerprint = shard::fingerprint(&scene, &fingerprinted_options(args, &options));
    let baker = bake_backend(&options, args.device, args.adapter.as_deref())?;
    let backend = backend_of(&baker, args);
    let progress = BarProgress::default();
    let started = std::time::Instant::now();
    let pass = bake::bake_shard(scene, &options, &backend, shard, &progress)
        .map_err(|e| naming_the_mesh(e, &mesh_shown(mesh)))?;
    progress.finish();
    let (range, total, rays) = (
        pass.receivers.clone(),
        pass.receivers_total,
        pass.direct.rays_cast,
    );
    let directory = std::env::current_dir().map_err(|e| Error::io(Path::new("."), e))?;
    let command = std::env::args().skip(1).collect();
    let part = Part::new(
        pass,
        (shard.index, shard.count),
        fingerprint,
        command,
        directory,
    );
    shard::write_part(&output, &part)?;
    println!(
        "baked {name} shard {}/{}: receivers {}..{} of {total}, {rays} rays, {:.2} s ({}) -> {}",
        shard.index,
        shard.count,
        range.start,
        range.end,
        started.elapsed().as_secs_f64(),
        backend.describe(),
        output.display()
    );
    Ok(())
}

/// `merge`: the parts checked and joined, then the rest of the bake their command asks for.
fn run_merge(args: MergeArgs) -> Result<()> {
    let parts = args
        .parts
        .iter()
        .map(|path| Ok((path.clone(), shard::read_part(path)?)))
        .collect::<Result<Vec<_>>>()?;
    let (header, direct) = shard::assemble(parts)?;
    let command = std::iter::once("prt-gpu".to_string()).chain(header.command.iter().cloned());
    let bake_args = match Cli::try_parse_from(command).map(|cli| cli.command) {
        Ok(Command::Bake(bake_args)) => bake_args,
        _ => {
            return Err(Error::Merge(format!(
                "the parts' command is not a bake: {}",
                header.command.join(" ")
            )))
        }
    };
    let bake_args = BakeArgs {
        preview: args.preview,
        ..bake_args
    };
    let given: Vec<PathBuf> = bake_args
        .meshes
        .iter()
        .map(|m| header.directory.join(m))
        .collect();
    let mesh = match scene::batch::mesh_files(&given)?.as_slice() {
        [] => None,
        [mesh] => Some(mesh.clone()),
        _ => {
            return Err(Error::Merge(format!(
                "the parts' command bakes several meshes: {}",
                header.command.join(" ")
            )))
        }
    };
    let options = bake_options(&bake_args)?;
    let backend = header.backend.clone();
    let device = Device::new(|| merge_backend(&options, &backend));
    let progress = BarProgress::default();
    let merged = Some((header, direct));
    bake_one(&bake_args, &mesh, args.output, &device, merged, &progress)
}

/// How the bake of `scene` fits the memory limit: `None` whole, or streamed in chunks of that
/// many receivers. A bake that cannot fit an explicit limit fails before it starts, saying what
/// it needs; over the machine's available memory, a warning.
fn memory_plan(
    args: &BakeArgs,
    options: &BakeOptions,
    scene: &scene::Scene,
    gltf: bool,
) -> Result<Option<usize>> {
    use bake::stream::{format_bytes, MemoryNeed};
    let need = MemoryNeed::estimate(scene.vertex_count(), scene.triangle_count(), options);
    let Some(limit) = args.memory_limit.or_else(device::available_memory) else {
        return Ok(None);
    };
    if need.whole() <= limit {
        return Ok(None);
    }
    let streamable = bake::stream::streams(options)
        && !gltf
        && args.compress.is_none()
        && args.precision == Precision::F32
        && args.transfer.bands != Bands::Auto
        && args.preview.is_none();
    let cannot = match streamable {
        true => None,
        false => Some(
            "only shadowed and unshadowed per-vertex bakes of OBJ, PLY and the built-in scene, \
             without --compress, --precision f16, --bands auto or --preview, stream in chunks",
        ),
    };
    match (cannot, args.memory_limit) {
        (None, _) => {
            let chunk = need.chunk_within(limit)?;
            eprintln!(
                "note: streaming the transfer in chunks of {chunk} receivers to stay within {} \
                 (about {} whole, {} streamed)",
                format_bytes(limit),
                format_bytes(need.whole()),
                format_bytes(need.streamed(chunk))
            );
            Ok(Some(chunk))
        }
        (Some(why), Some(_)) => Err(Error::Options(format!(
            "--memory-limit {}: this bake needs about {}, and {why}",
            format_bytes(limit),
            format_bytes(need.whole())
        ))),
        (Some(why), None) => {
            eprintln!(
                "warning: this bake needs about {}, more than the {} this machine has available, \
                 and {why}",
                format_bytes(need.whole()),
                format_bytes(limit)
            );
            Ok(None)
        }
    }
}

/// A shard is not streamed: its share of the receivers and the mesh must fit at once. Over an
/// explicit `--memory-limit` it is refused, naming the fewest shards that would fit; over the
/// memory this machine has, it goes ahead with a warning.
fn check_shard_memory(
    args: &BakeArgs,
    options: &BakeOptions,
    scene: &scene::Scene,
    shard: bake::Shard,
) -> Result<()> {
    use bake::stream::{format_bytes, MemoryNeed};
    let need = MemoryNeed::estimate(scene.vertex_count(), scene.triangle_count(), options);
    let Some(limit) = args.memory_limit.or_else(device::available_memory) else {
        return Ok(());
    };
    let shard_need = need.shard(shard.count, options);
    if shard_need <= limit {
        return Ok(());
    }
    let advice = match need.shards_within(limit, options) {
        Some(count) => format!("{count} or more shards would each fit"),
        None => format!(
            "the mesh and its BVH alone need about {}, so no shard count fits",
            format_bytes(need.fixed)
        ),
    };
    let message = format!(
        "shard {}/{} needs about {}; {advice}",
        shard.index,
        shard.count,
        format_bytes(shard_need)
    );
    match args.memory_limit {
        Some(_) => Err(Error::Options(format!(
            "--memory-limit {}: {message}",
            format_bytes(limit)
        ))),
        None => {
            eprintln!(
                "warning: {message} within the {} this machine has available",
                format_bytes(limit)
            );
            Ok(())
        }
    }
}

/// What besides the mesh decides a bake's output, as text for its fingerprint.
fn fingerprinted_options(args: &BakeArgs, options: &BakeOptions) -> String {
    format!(
        "{options:?} bands {:?} threshold {} compress {:?} precision {:?}",
        args.transfer.bands, args.bands_threshold, args.compress, args.precision
    )
}

/// The device a merge runs the rest of the bake on: the CPU for parts baked there; a GPU for
/// parts baked on one, where bounces or texels run on it (so that the bytes match).
fn merge_backend(options: &BakeOptions, parts_backend: &str) -> Result<Option<GpuBaker>> {
    let needs_device = options.mode == Mode::Interreflected || options.lightmap.is_some();
    if parts_backend == Backend::Cpu.describe() || !needs_device {
        return Ok(None);
    }
    match GpuBaker::open(DeviceChoice::Gpu, None)? {
        Some(baker) => Ok(Some(baker)),
        None => Err(Error::Merge(format!(
            "the parts were baked on {parts_backend}, and their bounces need a GPU adapter, \
             which this machine lacks"
        ))),
    }
}

fn mesh_shown(mesh: &Option<PathBuf>) -> String {
    mesh.as_ref()
        .map_or_else(|| "built-in scene".to_string(), |p| p.display().to_string())
}

fn note_samples_rounded(options: &BakeOptions) {
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

fn check_chunking(args: &BakeArgs) -> Result<()> {
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

/// The backend of `baker` (the CPU's without one), chunked as `args` ask.
fn backend_of<'a>(baker: &'a Option<GpuBaker>, args: &BakeArgs) -> Backend<'a> {
    match baker {
        Some(baker) => Backend::Gpu {
            baker,
            chunking: Chunking {
                max_vertices: args.chunk_vertices,
                max_samples: args.chunk_samples,
                max_steps: None,
            },
        },
        None => Backend::Cpu,
    }
}

/// Refuses output forms a bake cannot give: compressed, lean or lightmapped glTF scenes baked
/// in place, compressed lightmaps.
fn check_output_forms(args: &BakeArgs, options: &BakeOptions, gltf: bool) -> Result<()> {
    let refuse = |message: &str| Err(Error::Options(message.to_string()));
    if let Some(Compression::Target(error)) = args.compress {
        if !(error > 0.0 && error < 1.0) {
            return Err(Error::Options(format!(
                "--compress auto:{error}: the error target must lie in (0, 1)"
            )));
        }
    }
    if args.compress.is_some() && (gltf || options.lightmap.is_some()) {
        return refuse(
            "--compress stores the transfer of OBJ, PLY and the built-in scene per vertex; \
             glTF scenes baked in place and lightmaps are not compressed",
        );
    }
    if args.precision == Precision::F16 && (gltf || options.lightmap.is_some()) {
        return refuse(
            "--precision f16 stores the per-vertex or compressed transfer of OBJ, PLY and the \
             built-in scene; glTF scenes baked in place and lightmaps keep their own storage",
        );
    }
    if gltf && options.storage == Storage::Lean {
        return refuse(
            "--storage lean stores OBJ, PLY and the built-in scene; a glTF scene baked in place \
             keeps RGB transfer",
        );
    }
    if gltf && options.lightmap.is_some() {
        return refuse(
            "--lightmap bakes OBJ, PLY and the built-in scene; a glTF scene is baked in place \
             per vertex (lightmaps for glTF scenes are not supported yet)",
        );
    }
    Ok(())
}

/// What storing `baked`'s transfer as half floats cost: bytes, and the relit error.
fn report_f16_error(baked: &bake::BakedMesh) -> Result<()> {
    let rounded = glb::rounded_to_f16(&baked.transfer);
    let light = light::preview_light(baked.transfer.bands)?;
    let exact = render::relight(&baked.transfer, &light)?;
    let stored = render::relight(&rounded, &light)?;
    let worst = baked
        .transfer
        .coeffs
        .iter()
        .zip(&rounded.coeffs)
        .filter(|(x, _)| x.abs() >= 1e-4)
        .map(|(x, r)| ((r - x) / x).abs())
        .fold(0f32, f32::max);
    eprintln!(
        "precision f16: transfer {} bytes instead of {}; relit error {:.1e} under the preview \
         light, worst coefficient {:.1e} relative (of those above 1e-4)",
        baked.transfer.coeffs.len() * 2,
        baked.transfer.coeffs.len() * 4,
        compress::radiance_error(&exact, &stored),
        worst
    );
    Ok(())
}

/// `--bands auto`: the baked mesh cut to the bands the threshold asks for, said; returns them.
fn choose_auto_bands(baked: &mut bake::BakedMesh, threshold: f64) -> u32 {
    let (bands, beyond) = bake::choose_bands(&baked.transfer, threshold);
    bake::truncate_baked(baked, bands);
    eprintln!(
        "bands auto: {bands} ({:.2}% of the transfer's energy lies in bands {bands} to {}, \
         below --bands-threshold {threshold})",
        100.0 * beyond,
        AUTO_MAX_BANDS - 1,
    );
    bands
}

/// What `bake`'s arguments ask of the bake.
fn bake_options(args: &BakeArgs) -> Result<BakeOptions> {
    if !(args.bands_threshold > 0.0 && args.bands_threshold < 1.0) {
        return Err(Error::Options(format!(
            "--bands-threshold {} must lie in (0, 1)",
            args.bands_threshold
        )));
    }
    Ok(BakeOptions {
        seed: args.seed,
        albedo: args.albedo,
        bounces: args.bounces,
        bounce_tolerance: args.bounce_tolerance,
        fit: args.fit,
        lightmap: args.lightmap,
        storage: args.storage,
        target_error: args.target_error.map(|relative| TargetError {
            relative,
            max_samples: args.max_samples,
        }),
        point_density: PointDensity {
            per_vertex: args.fit_points,
            ..PointDensity::default()
        },
        ..args.transfer.options()
    })
}

/// The baked transfer compressed to `(clusters, components)` and rounded as a file at
/// `precision` stores it, with its sizes and errors (those of the stored form) said. The
/// assignment steps run on `gpu` where it pays (`GpuAssigner::where_it_pays`).
fn compress_transfer(
    baked: &bake::BakedMesh,
    compression: Compression,
    precision: Precision,
    gpu: Option<&prt_gpu::device::GpuContext>,
) -> Result<Cpca> {
    let started = std::time::Instant::now();
    let transfer = &baked.transfer;
    let points = compress::Points {
        data: &transfer.coeffs,
        dimension: transfer.channels as usize * transfer.coeffs_per_channel(),
    };
    let most_components = match compression {
        Compression::Shape(_, components) => components as usize,
        Compression::Target(_) => points.dimension,
    };
    let gpu_assigner = match gpu {
        Some(context) => {
            let (assigner, why_not) =
                compress::gpu::GpuAssigner::where_it_pays(context, points, most_components)?;
            if let Some(why) = why_not {
                eprintln!("note: {why}; clustering on the CPU");
            }
            assigner
        }
        None => None,
    };
    let (assigner, ran_on): (&dyn compress::Assigner, String) = match &gpu_assigner {
        Some(assigner) => (assigner, format!("gpu: {}", assigner.label())),
        None => (&compress::CpuAssigner, "cpu".into()),
    };
    let (cpca, options) = match compression {
        Compression::Shape(clusters, components) => {
            let options = CpcaOptions {
                clusters,
                components,
                ..CpcaOptions::default()
            };
            (
                compress::compress_with(transfer, &options, assigner)?,
                options,
            )
        }
        Compression::Target(error) => {
            compress::choose_with(transfer, error, CpcaOptions::default().seed, assigner)?
        }
    };
    let cpca = cpca.rounded(precision);
    let (clusters, components) = (options.clusters, options.components);
    let seconds = started.elapsed().as_secs_f64();
    let before = compress::uncompressed_bytes(&baked.transfer);
    let after = cpca.byte_size(precision);
    let light = light::preview_light(baked.transfer.bands)?;
    let half = match precision {
        Precision::F32 => "",
        Precision::F16 => " as half floats",
    };
    eprintln!(
        "compressed: {clusters} clusters x {components} components in {seconds:.2} s \
         ({ran_on}), {after} bytes{half} of {before} ({:.1}x smaller); coefficient error \
         {:.2}%, relit error {:.2}% under the preview light",
        before as f64 / after as f64,
        100.0 * compress::relative_error(&baked.transfer, &cpca),
        100.0 * compress::relit_error(&baked.transfer, &cpca, &light)?
    );
    Ok(cpca)
}

/// The GPU baker a bake with `options` uses, or `None` for the CPU backend (error-targeted
/// bakes always run there).
fn bake_backend(
    options: &BakeOptions,
    device: DeviceChoice,
    adapter: Option<&str>,
) -> Result<Option<GpuBaker>> {
    if options.target_error.is_some() {
        if device == DeviceChoice::Gpu {
            eprintln!("note: error-targeted bakes run on the CPU backend");
        }
        return Ok(None);
    }
    open_backend(device, adapter)
}

/// What `bake` bakes: the mesh named on the command line (a glTF scene keeps its document,
/// to be written back with its transfer), or the built-in scene; and a name for messages.
fn load_bake_input(
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
fn naming_the_mesh(error: Error, mesh: &str) -> Error {
    match error {
        Error::Geometry(_) => Error::mesh(mesh, error.to_string()),
        other => other,
    }
}

/// Renders `baked` under the default sky and sun to `path`.
fn write_preview(context: &GpuContext, baked: &bake::BakedMesh, path: &Path) -> Result<()> {
    let (width, height) = (640, 480);
    let light = light::preview_light(baked.metadata.bands)?;
    let image = render::preview(context, baked, &light, None, width, height)?;
    render::write_image(path, &image, width, height, ToneMap::Reinhard, 0.0)?;
    eprintln!("preview -> {}", path.display());
    Ok(())
}

/// The bounces, the gather matrix and the one summary line of a finished bake.
/// What baking a glTF scene in place did.
fn print_in_place_report(written: &glb::scene::SceneWrite, seconds_load: f64, seconds_write: f64) {
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

fn print_bake_report(
    name: &str,
    options: &BakeOptions,
    report: &BakeReport,
    output: &Path,
    merged_from: MergedFrom,
) {
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
        options.bands,
        match &report.adaptive {
            Some(adaptive) => format!("{:.0} (mean)", adaptive.samples_mean),
            None => report.samples_used.to_string(),
        },
        options.sampling.name(),
        options.mode.name(),
        seconds,
        report.backend,
        output.display()
    );
}

/// The GPU baker for `choice`, or `None` for the CPU backend (saying why when it was not asked
/// for). `bake`, `chart` and `bench` all open their backend here.
fn open_backend(choice: DeviceChoice, adapter: Option<&str>) -> Result<Option<GpuBaker>> {
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
fn load_scene(mesh: &Option<PathBuf>) -> Result<(scene::Scene, String)> {
    match mesh {
        Some(path) => Ok((scene::load(path)?, stem(path))),
        None => Ok((scene::builtin::default_scene(), "default-scene".to_string())),
    }
}

fn run_chart(args: ChartArgs) -> Result<()> {
    chart::check_chart_path(&args.output)?;
    let csv_path = args.output.with_extension("csv");
    fs::check_destination(&args.output)?;
    let options = sweep_options(&args)?;
    let light = match &args.light {
        Some(path) => light::load(path, args.bands, None, false)?.light,
        None => light::preview_light(args.bands)?,
    };
    let (scene, name) = load_scene(&args.mesh)?;
    let baker = open_backend(args.device, args.adapter.as_deref())?;
    let mut backends = vec![("cpu".to_string(), Backend::Cpu)];
    if let Some(baker) = &baker {
        eprintln!("gpu: {}", baker.context.adapter.label());
        backends.push((
            "gpu".to_string(),
            Backend::Gpu {
                baker,
                chunking: Chunking::default(),
            },
        ));
    }
    let started = std::time::Instant::now();
    let progress = BarProgress::default();
    let result = sweep::run(&scene, &options, &backends, &light, &progress)?;
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
    sweep::write_csv(&csv_path, &result)?;
    for p in &result.points {
        eprintln!(
            "{:>16} {:>13} {:>3} {:>6} samples: {:>8.3} s, transfer rms {:.3e}, radiance rms \
             {:.3e}, surface {:.2}%",
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
            100.0 * p.surface_rms / result.surface.rms.max(1e-30)
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
        target_errors: args.target_error.clone(),
    };
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

fn run_bench(args: BenchArgs) -> Result<()> {
    if args.transfer.bands == Bands::Auto {
        return Err(Error::Options(
            "--bands auto chooses the bands of a bake; bench needs a number".into(),
        ));
    }
    let options = args.transfer.options();
    options.validate()?;
    if args.repeats == 0 {
        return Err(Error::Options("--repeats must be at least 1".into()));
    }
    let (scene, name) = load_scene(&args.mesh)?;
    let (scene, _) = scene::prepare::prepare(scene).map_err(|e| naming_the_mesh(e, &name))?;
    let owned = bake::BakeInputs::for_options(&scene, &options);
    let inputs = owned.view();
    let baker = open_backend(args.device, args.adapter.as_deref()).unwrap_or_else(|e| {
        eprintln!("note: no GPU entry: {e}");
        None
    });
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
        println!("gpu / cpu throughput: {:.2}", cpu_seconds / gpu_seconds);
    }
    Ok(())
}

fn run_devices() -> Result<()> {
    let adapters = device::list_adapters();
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

fn run_light(args: LightArgs) -> Result<()> {
    let bands = args.bands;
    if bands == 0 || bands > MAX_BANDS {
        return Err(Error::Options(format!(
            "--bands {bands} is out of range (1 to {MAX_BANDS})"
        )));
    }
    fs::check_destination(&args.output)?;
    let mut total = ShLight::constant(bands, [0.0; 3]);
    let mut parts = Vec::new();
    if let Some(path) = &args.envmap {
        let loaded = light::load(path, bands, args.mapping, args.skip_invalid)?;
        note_skipped_pixels(loaded.skipped_pixels);
        if let Some(mapping) = loaded.mapping {
            parts.push(format!("{} ({mapping:?})", path.display()));
        }
        total = total.plus(&loaded.light)?;
    }
    if !args.faces.is_empty() {
        let loaded = light::load_faces(&args.faces, bands, args.skip_invalid)?;
        note_skipped_pixels(loaded.skipped_pixels);
        total = total.plus(&loaded.light)?;
        parts.push("six cube faces".into());
    }
    if let Some(direction) = args.directional {
        let light = analytic::directional(
            bands,
            direction.as_dvec3(),
            args.directional_intensity.to_array(),
        )?;
        total = total.plus(&light)?;
        parts.push("directional".into());
    }
    if let Some(direction) = args.sun {
        let sun = analytic::sun_disk(
            bands,
            direction.as_dvec3(),
            args.sun_angle.to_radians(),
            args.sun_irradiance.to_array(),
        )?;
        total = total.plus(&sun)?;
        parts.push("sun".into());
    }
    if let Some(sky) = args.sky {
        total = total.plus(&analytic::hemisphere(
            bands,
            sky.to_array(),
            args.ground.to_array(),
        )?)?;
        parts.push("sky".into());
    }
    if let Some(ambient) = args.ambient {
        total = total.plus(&ShLight::constant(bands, ambient.to_array()))?;
        parts.push("ambient".into());
    }
    if args.tutorial {
        total = total.plus(&analytic::tutorial_two_lights(bands)?)?;
        parts.push("tutorial two lights".into());
    }
    if parts.is_empty() {
        return Err(Error::Options(
            "give an environment map (or --faces) or at least one of --directional, --sun, \
             --sky, --ambient, --tutorial"
                .into(),
        ));
    }
    let light = shape(total, &args.shaping);
    light::write_json(&args.output, &light)?;
    println!(
        "projected {} onto {bands} bands (DC {:.4} {:.4} {:.4}) -> {}",
        parts.join(" + "),
        light.coeffs[0][0],
        light.coeffs[0][1],
        light.coeffs[0][2],
        args.output.display()
    );
    Ok(())
}

fn note_skipped_pixels(skipped: usize) {
    if skipped > 0 {
        eprintln!("note: skipped {skipped} NaN or infinite pixels");
    }
}

/// Rotation first, then windowing, so the window sees the light as it will be used.
fn shape(light: ShLight, shaping: &LightShaping) -> ShLight {
    let light = match shaping.rotate {
        Some(r) => light.rotated(r.x as f64, r.y as f64, r.z as f64),
        None => light,
    };
    light.windowed(shaping.window)
}

fn run_render(args: RenderArgs) -> Result<()> {
    fs::check_destination(&args.output)?;
    if let [only] = &args.baked[..] {
        if glb::local::is_local_file(&std::fs::read(only).map_err(|e| Error::io(only, e))?) {
            return run_local_render(&args, only);
        }
    }
    let local_only = !args.point_light.is_empty()
        || !args.spot_light.is_empty()
        || args.frames.is_some()
        || args.orbit.is_some()
        || args.device != DeviceChoice::Auto;
    if local_only {
        return Err(Error::Options(
            "--point-light, --spot-light, --frames, --orbit and --device relight one \
             local-lights bake (bake --mode local); a distant-light render rasterizes on \
             --adapter"
                .into(),
        ));
    }
    if is_glb(&args.output) {
        return write_relit_distant(&args);
    }
    let context = open_render_device(args.adapter.as_deref())?;
    let mut panels = Vec::new();
    for path in &args.baked {
        let (baked, cpca) = glb::read_glb_compressed(path)?;
        let bands = baked.metadata.bands;
        let light = match &args.light {
            Some(light_path) => light::load(light_path, bands, args.mapping, false)?.light,
            None => light::preview_light(bands)?,
        };
        let light = shape(light, &args.shaping);
        let camera = args
            .camera
            .unwrap_or_else(|| Camera::framing_scene(&baked.scene));
        let mut panel = match &cpca {
            // As a run-time would: the light dotted into each cluster once, then per vertex.
            Some(cpca) => render::render(
                &context,
                &baked.scene,
                &render::apply_albedo(&baked, cpca.relight(&light)?),
                &camera,
                args.width,
                args.height,
            )?,
            None => render::preview(
                &context,
                &baked,
                &light,
                Some(&camera),
                args.width,
                args.height,
            )?,
        };
        if args.sky {
            render::draw_sky(&mut panel, args.width, args.height, &camera, &light);
        }
        panels.push(panel);
    }
    let image = render::side_by_side(&panels, args.width, args.height)?;
    let width = args.width * panels.len() as u32;
    render::write_image(
        &args.output,
        &image,
        width,
        args.height,
        args.tone_map,
        args.exposure,
    )?;
    println!(
        "rendered {} panel(s) of {}x{} on {} -> {}",
        panels.len(),
        args.width,
        args.height,
        context.adapter.label(),
        args.output.display()
    );
    Ok(())
}

fn run_view(args: ViewArgs) -> Result<()> {
    fs::check_destination(&args.output)?;
    let mut bakes = Vec::new();
    for path in &args.baked {
        bakes.push((path.display().to_string(), glb::read_glb(path)?));
    }
    let bands = bakes
        .iter()
        .map(|(_, b)| b.metadata.bands)
        .max()
        .unwrap_or(1);
    let (light, map) = view_light(&args, bands)?;
    let rotation = args.shaping.rotate.unwrap_or(Vec3::ZERO);
    let sky = map.as_ref().map(|(image, mapping)| view::ViewerSky {
        image,
        mapping: *mapping,
        yaw_pitch_roll: [rotation.x as f64, rotation.y as f64, rotation.z as f64],
    });
    let inputs: Vec<view::ViewerBake> = bakes
        .iter()
        .map(|(name, baked)| view::ViewerBake {
            name: stem_name(name),
            baked,
        })
        .collect();
    view::write_viewer(&args.output, &inputs, &light, sky.as_ref())?;
    let size = std::fs::metadata(&args.output)
        .map(|m| m.len())
        .unwrap_or(0);
    println!(
        "viewer of {} file(s), light of {} bands{}, {:.1} MB -> {}",
        inputs.len(),
        light.bands,
        if sky.is_some() {
            ", the map as the sky"
        } else {
            ""
        },
        size as f64 / 1e6,
        args.output.display()
    );
    Ok(())
}

/// The viewer's light, shaped, and the environment map it was projected from (if it was).
fn view_light(args: &ViewArgs, bands: u32) -> Result<(ShLight, Option<(EnvImage, Mapping)>)> {
    let (light, map) = match &args.light {
        Some(light_path) => {
            let (loaded, image) = light::load_with_image(light_path, bands, args.mapping, false)?;
            (loaded.light, image.zip(loaded.mapping))
        }
        None => (light::preview_light(bands)?, None),
    };
    Ok((shape(light, &args.shaping), map))
}

fn run_export_x3d(args: X3dArgs) -> Result<()> {
    fs::check_destination(&args.output)?;
    let baked = glb::read_glb(&args.baked)?;
    let bands = baked.metadata.bands;
    let light = match &args.light {
        Some(light_path) => light::load(light_path, bands, args.mapping, false)?.light,
        None => light::preview_light(bands)?,
    };
    let light = shape(light, &args.shaping);
    let options = x3d::X3dOptions {
        camera: args
            .camera
            .unwrap_or_else(|| Camera::framing_scene(&baked.scene)),
        exposure_stops: args.exposure,
        tone_map: args.tone_map,
    };
    x3d::write_x3d(&args.output, &baked, &light, &options)?;
    println!(
        "exported {} vertices, {} bands x {} channel(s) in {} vertex attributes -> {}",
        baked.scene.vertex_count(),
        bands,
        baked.transfer.channels,
        x3d::transfer_attributes(&baked),
        args.output.display()
    );
    Ok(())
}

/// The file name the page lists a bake by.
fn stem_name(path: &str) -> String {
    Path::new(path)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.to_string())
}

fn is_glb(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
}

/// `render FILE --light ... -o relit.glb`: the file's relit radiance as COLOR_0 of a copy.
fn write_relit_distant(args: &RenderArgs) -> Result<()> {
    let [path] = &args.baked[..] else {
        return Err(Error::Options(
            "-o .glb writes the relit radiance of one baked file; give one".into(),
        ));
    };
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if glb::is_scene_file(&bytes) {
        return Err(Error::Options(
            "-o .glb: a glTF scene baked in place keeps its own vertex colours (not supported yet)"
                .into(),
        ));
    }
    let (baked, cpca) = glb::read_glb_compressed(path)?;
    let bands = baked.metadata.bands;
    let (light, name) = match &args.light {
        Some(light_path) => (
            light::load(light_path, bands, args.mapping, false)?.light,
            light_path.display().to_string(),
        ),
        None => (
            light::preview_light(bands)?,
            "the preview sky and sun".to_string(),
        ),
    };
    let light = shape(light, &args.shaping);
    let radiance = match &cpca {
        Some(cpca) => render::apply_albedo(&baked, cpca.relight(&light)?),
        None => render::relight_baked(&baked, &light)?,
    };
    glb::relit::write_relit_copy(path, &args.output, &radiance, &name)?;
    println!(
        "relit {} vertices under {name} -> {} (COLOR_0 = exit radiance)",
        radiance.len(),
        args.output.display()
    );
    Ok(())
}

fn run_local_bake(args: BakeArgs) -> Result<()> {
    check_local_flags(&args)?;
    let options = local_options(&args);
    options.validate()?;
    let (scene, name) = match args.meshes.first() {
        Some(path) => (scene::load(path)?, stem(path)),
        None => (scene::builtin::interior_scene(), "interior".to_string()),
    };
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{name}.prt.glb")));
    fs::check_destination(&output)?;
    let mut scene = scene;
    if let Some(albedo) = args.albedo {
        scene.albedo.iter_mut().for_each(|a| *a = albedo);
    }
    let baker = bake_backend(
        &BakeOptions::default(),
        args.device,
        args.adapter.as_deref(),
    )?;
    let backend = match &baker {
        Some(baker) => Backend::Gpu {
            baker,
            chunking: Chunking::default(),
        },
        None => Backend::Cpu,
    };
    let progress = BarProgress::default();
    let (baked, report) = local::bake_local(scene, &options, &backend, &progress)?;
    progress.finish();
    glb::local::write_local_glb(&output, &baked)?;
    print_local_report(&name, &report, &output);
    Ok(())
}

/// Refuses the transfer bake's options that mean nothing for local lights.
fn check_local_flags(args: &BakeArgs) -> Result<()> {
    let refused = [
        (args.compress.is_some(), "--compress"),
        (args.lightmap.is_some(), "--lightmap"),
        (args.fit != Fit::Point, "--fit"),
        (args.target_error.is_some(), "--target-error"),
        (args.storage != Storage::Rgb, "--storage"),
        (args.preview.is_some(), "--preview"),
        (args.transfer.bands != Bands::Fixed(4), "--bands"),
        (args.precision != Precision::F32, "--precision"),
        (args.shard.is_some(), "--shard"),
        (
            args.out_dir.is_some() || args.meshes.len() > 1,
            "a batch (--out-dir)",
        ),
    ];
    match refused.iter().find(|(given, _)| *given) {
        Some((_, flag)) => Err(Error::Options(format!(
            "{flag} is for SH transfer; --mode local bakes depth maps and a direct-to-indirect \
             operator (see --depth-grid, --depth-compress, --operator-compress)"
        ))),
        None => Ok(()),
    }
}

fn local_options(args: &BakeArgs) -> LocalOptions {
    let local = &args.local;
    LocalOptions {
        samples: args
            .transfer
            .samples
            .unwrap_or(LocalOptions::default().samples),
        seed: args.seed,
        bounces: args.bounces,
        grid_side: local.depth_grid,
        depth_clusters: local.depth_compress.0,
        depth_components: local.depth_compress.1,
        operator: OperatorShape {
            clusters: local.operator_compress.0,
            components: local.operator_compress.1,
            sparsity: local.sparsity,
            seed: args.seed,
        },
        example_lights: local.example_lights,
    }
}

fn print_local_report(name: &str, report: &local::LocalReport, output: &Path) {
    let mb = |bytes: usize| bytes as f64 / 1e6;
    println!(
        "local lights: {} receivers, {} triangles; gather matrix {} entries ({:.2} s); depth maps \
         {:.2} s, compressed {:.1} -> {:.1} MB, depth error {:.2}% ({:.2} s); {} example lights \
         ({:.2} s); operator {:.1} MB, {:.0}% of terms kept, error {:.2}% against the \
         sparse bounces ({:.2} s)",
        report.receivers,
        report.triangles,
        report.gather_entries,
        report.seconds_gather,
        report.seconds_depth,
        mb(report.depth_bytes_uncompressed),
        mb(report.depth_bytes),
        100.0 * report.depth_error,
        report.seconds_depth_compress,
        report.example_lights,
        report.seconds_examples,
        mb(report.operator_bytes),
        100.0 * report.operator_kept,
        100.0 * report.operator_error,
        report.seconds_operator
    );
    println!(
        "baked {name} for local lights: {} rays, {:.2} s on {} -> {}",
        report.rays_cast,
        report.seconds(),
        report.backend,
        output.display()
    );
}

/// The lights given on the command line (at least one).
fn parsed_lights(args: &RenderArgs) -> Result<Vec<LocalLight>> {
    let mut lights = Vec::new();
    for text in &args.point_light {
        lights.push(local_lights::parse_point_light(text)?);
    }
    for text in &args.spot_light {
        lights.push(local_lights::parse_spot_light(text)?);
    }
    if lights.is_empty() {
        return Err(Error::Options(
            "a local-lights bake needs --point-light or --spot-light".into(),
        ));
    }
    Ok(lights)
}

/// `info` of a local-lights bake.
fn print_local_info(path: &Path) -> Result<()> {
    let baked = glb::local::read_local_glb(path)?;
    let options = &baked.options;
    let op = &baked.operator;
    println!("file:         {}", path.display());
    println!("vertices:     {}", baked.scene.positions.len());
    println!("triangles:    {}", baked.scene.triangles.len());
    println!("mode:         local (point and spot lights inside the scene)");
    println!(
        "gather:       {} entries from {} rays per receiver, {} bounces",
        baked.matrix.columns.len(),
        options.samples,
        options.bounces
    );
    println!(
        "depth maps:   {}x{} directions, {} clusters x {} components",
        baked.grid.side,
        baked.grid.side,
        baked.depth.cluster_count(),
        baked.depth.components
    );
    println!(
        "operator:     {} clusters x {} components from {} example lights, {} of {} terms \
         (sender cluster, component) kept over all receiver clusters, {:.1} MB",
        op.clusters(),
        op.components,
        options.example_lights,
        op.terms.len(),
        op.clusters() * op.clusters() * op.components,
        op.byte_size() as f64 / 1e6
    );
    Ok(())
}

/// `render` of a local-lights bake: one image, a sequence (`--frames`), or a relit copy.
fn run_local_render(args: &RenderArgs, path: &Path) -> Result<()> {
    if args.light.is_some() || args.sky {
        return Err(Error::Options(
            "--light and --sky are distant light; a local-lights bake takes --point-light and \
             --spot-light"
                .into(),
        ));
    }
    let lights = parsed_lights(args)?;
    let baked = glb::local::read_local_glb(path)?;
    let relighter = local::Relighter::new(&baked);
    if is_glb(&args.output) {
        if args.frames.is_some() {
            return Err(Error::Options("--frames writes images, not .glb".into()));
        }
        let frame = relighter.frame(&lights, args.operator);
        let name = local_lights::describe(&lights);
        glb::relit::write_relit_copy(path, &args.output, &frame.total(), &name)?;
        println!(
            "relit {} vertices under {name} -> {}",
            frame.direct.len(),
            args.output.display()
        );
        return Ok(());
    }
    let frames = args.frames.unwrap_or(1);
    if frames == 0 {
        return Err(Error::Options("--frames must be at least 1".into()));
    }
    let camera = args
        .camera
        .unwrap_or_else(|| Camera::framing_scene(&baked.scene));
    let context = open_render_device(args.adapter.as_deref())?;
    let gpu = match args.device {
        DeviceChoice::Cpu => None,
        DeviceChoice::Gpu => GpuBaker::open(DeviceChoice::Gpu, args.adapter.as_deref())?,
        DeviceChoice::Auto => GpuBaker::open(DeviceChoice::Auto, args.adapter.as_deref())
            .ok()
            .flatten(),
    };
    let gpu_paths = match &gpu {
        Some(baker) => Some(local::GpuPaths::new(baker, &baked)?),
        None => None,
    };
    if let Some(Err(why)) = gpu_paths.as_ref().map(|paths| &paths.compressed) {
        eprintln!("the compressed operator is not timed on the GPU: {why}");
    }
    let (lo, hi) = render::bounds(&baked.scene.positions);
    let centre = args.orbit.unwrap_or((lo + hi) * 0.5);
    let mut timing = local::FrameTimes::default();
    for f in 0..frames {
        let lights = local_lights::on_circle(&lights, centre, f, frames);
        let frame = local::time_frame(
            &relighter,
            &lights,
            args.operator,
            gpu_paths.as_ref(),
            &mut timing,
        )?;
        let image = render::render(
            &context,
            &baked.scene,
            &frame.total(),
            &camera,
            args.width,
            args.height,
        )?;
        let output = local::frame_path(&args.output, f, frames);
        render::write_image(
            &output,
            &image,
            args.width,
            args.height,
            args.tone_map,
            args.exposure,
        )?;
    }
    println!(
        "rendered {frames} frame(s) of {}x{} -> {}",
        args.width,
        args.height,
        local::frame_path(&args.output, 0, frames).display()
    );
    println!(
        "{}",
        timing.report(
            baked.scene.positions.len(),
            gpu.as_ref().map(|g| g.context.adapter.label())
        )
    );
    Ok(())
}

/// Any adapter, software ones included: rasterising a preview is cheap anywhere.
fn open_render_device(adapter: Option<&str>) -> Result<GpuContext> {
    device::open(DeviceChoice::Gpu, adapter)?
        .ok_or_else(|| Error::Gpu("no adapter to render with".into()))
}

/// Prints a baked file's description; a reader that stops early (`| head`) ends it quietly.
fn run_info(path: &Path) -> Result<()> {
    use std::io::Write;
    if glb::local::is_local_file(&std::fs::read(path).map_err(|e| Error::io(path, e))?) {
        return print_local_info(path);
    }
    let mut lines: Vec<String> = Vec::new();
    let (metadata, vertices, triangles) = glb::read_metadata(path)?;
    lines.push(format!("file:         {}", path.display()));
    lines.push(format!("vertices:     {vertices}"));
    lines.push(format!("triangles:    {triangles}"));
    lines.push(format!("mode:         {}", metadata.mode.name()));
    lines.push(format!(
        "bands:        {} ({} coefficients per channel)",
        metadata.bands,
        metadata.bands * metadata.bands
    ));
    lines.push(format!(
        "channels:     {}{}",
        metadata.channels,
        if metadata.albedo_free {
            " (albedo-free: radiance = COLOR_0 x transfer . light)"
        } else {
            ""
        }
    ));
    lines.push(format!(
        "samples:      {} ({})",
        metadata.samples, metadata.sampling
    ));
    lines.push(format!("seed:         {}", metadata.seed));
    lines.push(format!("bounces:      {}", metadata.bounces));
    match metadata.fit_points {
        Some(points) => lines.push(format!(
            "fit:          {} ({points} surface points)",
            metadata.fit.name()
        )),
        None => lines.push(format!("fit:          {}", metadata.fit.name())),
    }
    let references = glb::read_references(path)?;
    if references.precision == Precision::F16 {
        lines.push("precision:    f16 (IEEE half floats, named by extras.prt)".to_string());
    }
    if let Some(lightmap) = references.lightmap {
        lines.push(format!(
            "lightmap:     {}x{} texels in {} (TEXCOORD_{})",
            lightmap.width, lightmap.height, lightmap.uri, lightmap.texcoord
        ));
    }
    if let Some(cpca) = references.cpca {
        lines.push(format!(
            "compressed:   CPCA, {} clusters x {} components",
            cpca.clusters, cpca.components
        ));
    }
    lines.push(format!("backend:      {}", metadata.backend));
    lines.push(format!(
        "made by:      {} {}",
        metadata.tool, metadata.tool_version
    ));
    lines.push(format!("sh basis:     {}", metadata.sh_convention));
    lines.push(format!("radiometry:   {}", metadata.radiometry));
    let mut out = std::io::stdout().lock();
    for line in lines {
        if writeln!(out, "{line}").is_err() {
            break;
        }
    }
    Ok(())
}

fn stem(path: &Path) -> String {
    scene::batch::mesh_name(path)
}

/// The bar over a whole batch, above each mesh's stage bars: its length is the meshes' work
/// (`scene::batch::work_weights`), so its rate and eta follow the bytes baked, not the count.
fn batch_bar(total: u64) -> ProgressBar {
    let bar = bars().add(ProgressBar::new(total));
    bar.set_style(
        ProgressStyle::with_template("{msg:>10} [{bar:40}] {percent}%, eta {eta}")
            .expect("static template")
            .progress_chars("=> "),
    );
    bar
}

/// A progress bar on stderr; indicatif hides it when stderr is not a terminal.
#[derive(Default)]
struct BarProgress {
    bar: Mutex<Option<ProgressBar>>,
    /// In a batch, which mesh of how many: "[2/5] bunny".
    prefix: String,
}

impl Progress for BarProgress {
    fn stage(&self, name: &str, total: u64) {
        let bar =
            bars().add(ProgressBar::new(total).with_message(format!("{}{name}", self.prefix)));
        bar.set_style(
            ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len}, eta {eta}")
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
    fn in_batch(position: usize, count: usize, mesh: &str) -> BarProgress {
        BarProgress {
            prefix: format!("[{position}/{count}] {mesh} "),
            ..BarProgress::default()
        }
    }

    fn finish(&self) {
        if let Some(bar) = self.bar.lock().unwrap().take() {
            bar.finish_and_clear();
        }
    }
}
