//! `bake`'s arguments: what the command line says of a bake and how it runs.

use super::*;

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
    /// `--fit-points` times the vertices' rays per sample. With `--lightmap`, the texels too:
    /// fitted so that bilinear lookups match four points a texel (about five times the texels'
    /// rays).
    #[arg(long, value_enum, default_value_t = Fit::Point)]
    pub(crate) fit: Fit,
    /// Least-squares fit: surface points baked per vertex of the mesh, on average (every
    /// triangle gets at least three).
    #[arg(long, default_value_t = PointDensity::default().per_vertex)]
    pub(crate) fit_points: f32,
    /// Bake to an error target instead of a fixed sample count: each receiver casts batches of
    /// 128 samples (at least 4) until the standard error of its transfer, relative to
    /// unoccluded transfer's norm, is below E. Shadowed and unshadowed modes, either backend.
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
    /// With --lightmap: each texel casts its samples turned by its own angle, and an
    /// edge-aware filter (guided by position, normal, chart and each texel's noise; the same
    /// weights for every coefficient) averages each texel with those of its chart within 2
    /// texels. Off by default (docs/performance.md, "Denoised lightmaps", shows where it pays).
    #[arg(long)]
    pub(crate) denoise: bool,
    /// Relightable probes for what moves through the scene: a grid this far apart (scene
    /// units) over its bounds. Each probe maps the light's SH to the SH of the radiance
    /// arriving there, shadowed by the scene and, when interreflected, with its bounced light;
    /// they go into the .glb (README, "Probes").
    #[arg(long, value_name = "SPACING", conflicts_with = "probe_points")]
    pub(crate) probes: Option<f32>,
    /// Probes at the points of a text file, one `x y z` per line (`#` starts a comment).
    #[arg(long, value_name = "FILE")]
    pub(crate) probe_points: Option<PathBuf>,
    /// What a probe stores: the incident radiance (bands^2 x bands^2 per channel) or only what
    /// irradiance needs (the first three bands, cosine-convolved). Default: radiance.
    #[arg(long, value_enum, value_name = "FORM")]
    pub(crate) probe_form: Option<ProbeForm>,
    /// Also store local, deformable transfer (LDPRT; Sloan, Luna & Snyder 2005): per vertex
    /// and channel, BANDS zonal-harmonic coefficients about one axis that best fit its SH
    /// transfer, for meshes that bend or are skinned: a runtime turns the axis with the
    /// surface (README, "Zonal transfer"). The fit's energy left out and relit error are
    /// reported.
    #[arg(long, value_name = "BANDS")]
    pub(crate) zonal: Option<u32>,
    /// With --zonal: the axis each lobe is about, the shading `normal` (nothing more stored)
    /// or the `fitted` axis that keeps most of the transfer (stored per vertex; turn it as
    /// normals are turned). Default: normal.
    #[arg(long, value_enum, value_name = "AXIS")]
    pub(crate) zonal_axis: Option<spec::ZonalAxis>,
    /// Translucent: subsurface scattering (the dipole of Jensen et al. 2001) replaces the
    /// diffuse reflection, light entering the surface leaving it elsewhere. A measured medium
    /// (apple, chicken1, chicken2, cream, ketchup, marble, potato, skim-milk, skin1, skin2,
    /// spectralon, whole-milk; coefficients per mm from the paper) or `custom` with
    /// --sss-absorption and --sss-scattering, for the whole scene. It scatters the direct light
    /// and every bounce; RGB. Without it, a glTF scene's materials with a scattering volume
    /// (KHR_materials_volume_scatter) scatter in their own media; `none` bakes them opaque
    /// (README, "Subsurface scattering").
    #[arg(long, value_name = "MEDIUM")]
    pub(crate) subsurface: Option<String>,
    /// With --subsurface: the absorption coefficient per mm, R,G,B (replaces the medium's).
    #[arg(long, value_name = "R,G,B", value_parser = parse_rgb)]
    pub(crate) sss_absorption: Option<Vec3>,
    /// With --subsurface: the reduced scattering coefficient per mm, R,G,B.
    #[arg(long, value_name = "R,G,B", value_parser = parse_rgb)]
    pub(crate) sss_scattering: Option<Vec3>,
    /// With --subsurface: the index of refraction relative to the outside (default: the
    /// medium's; 1.3 for custom).
    #[arg(long, value_name = "ETA")]
    pub(crate) sss_ior: Option<f32>,
    /// With --subsurface: millimetres per scene unit (default 1000: the scene is in metres).
    #[arg(long, value_name = "MM")]
    pub(crate) sss_mm_per_unit: Option<f32>,
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
    /// Most memory the bake may use, e.g. 512M or 8G (binary units). A bake that would need
    /// more streams its per-vertex transfer to the file in chunks that fit, bakes a
    /// least-squares fit's points in runs, or holds a lightmap's texels in a scratch file; one
    /// that cannot fit says so before it starts. Default: the memory this machine has
    /// available (when that is too little, a warning). A local-lights bake (`--mode local`)
    /// holds every receiver at once: a limit below its need is refused.
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
