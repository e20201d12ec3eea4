//! The bake: options in, one [`Transfer`] out, whichever backend computes it.

pub mod adaptive;
pub mod bounce;
pub mod cpu;
pub mod gpu;
pub mod spill;
pub mod stream;
pub mod texels;

use std::time::Instant;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::bvh::Bvh;
use crate::error::{Error, Result};
use crate::ray::offset_ray_origin;
use crate::receivers;
use crate::receivers::fit::{fit_vertices, FitOptions, FitReport};
use crate::receivers::uv_set::UvSet;
use crate::receivers::{spread_points, PointDensity, Receivers, SurfacePoint};
use crate::sampling::{Estimator, SampleSet, Sampling, MAX_SAMPLES};
use crate::scene::prepare::{kept_triangles, prepare_mapped, PrepareReport, VertexMap};
use crate::scene::Scene;
use crate::sh::rotation::EulerShRotation;
use crate::sh::{coeff_count, ShTable, CONVENTION, MAX_BANDS};

/// Which light transport the transfer vectors capture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Clamped cosine only: every direction above the horizon is assumed visible.
    Unshadowed,
    /// Clamped cosine times binary visibility against the whole scene.
    Shadowed,
    /// Shadowed transfer plus light reflected between surfaces (`--bounces`).
    Interreflected,
    /// Point and spot lights inside the scene (`crate::local`): depth maps and the
    /// direct-to-indirect operator, not SH transfer; baked by `local::bake_local`.
    Local,
}

impl Mode {
    pub fn name(self) -> &'static str {
        match self {
            Mode::Unshadowed => "unshadowed",
            Mode::Shadowed => "shadowed",
            Mode::Interreflected => "interreflected",
            Mode::Local => "local",
        }
    }
}

/// The most bounces a bake accepts.
pub const MAX_BOUNCES: u32 = 64;

/// Per-vertex transfer vectors, RGB.
///
/// Layout: `coeffs[(vertex * channels + channel) * bands^2 + k]`, `k = l(l+1) + m`.
/// Exit radiance of vertex v in channel c under lighting coefficients `light[c][k]` is
/// `sum_k light[c][k] * coeffs[(v * channels + c) * bands^2 + k]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Transfer {
    pub bands: u32,
    pub channels: u32,
    pub vertex_count: usize,
    pub coeffs: Vec<f32>,
}

impl Transfer {
    pub fn coeffs_per_channel(&self) -> usize {
        (self.bands * self.bands) as usize
    }

    /// The bands^2 coefficients of one vertex and channel.
    pub fn vertex_channel(&self, vertex: usize, channel: usize) -> &[f32] {
        let n = self.coeffs_per_channel();
        let start = (vertex * self.channels as usize + channel) * n;
        &self.coeffs[start..start + n]
    }
}

/// A baked mesh: the prepared scene (normals `Some`), its transfer and how it was made.
#[derive(Clone, Debug, PartialEq)]
pub struct BakedMesh {
    pub scene: Scene,
    pub transfer: Transfer,
    pub metadata: BakeMetadata,
    /// Per-texel transfer, when a lightmap was baked (the scene is then split so that every
    /// triangle corner has its own vertex and lightmap coordinates).
    pub lightmap: Option<TexelBake>,
}

/// Transfer per texel of a lightmap atlas.
#[derive(Clone, Debug, PartialEq)]
pub struct TexelBake {
    pub width: u32,
    pub height: u32,
    /// Lightmap coordinates of every triangle corner of the scene (corner i of triangle t at
    /// `3t + i`), in [0, 1] as glTF's `TEXCOORD_n`: texel (x, y) (row y from the top) has its
    /// centre at `((x + 0.5) / width, (y + 0.5) / height)`. A mesh with a generated atlas is
    /// split at its corners, so these are its vertices' coordinates too.
    pub texcoords: Vec<[f32; 2]>,
    /// The `TEXCOORD_n` set the coordinates are: 0 for a generated atlas, the scene's own
    /// lightmap set otherwise.
    pub set: u32,
    /// The texels' transfer, row-major: `vertex_count` is `width * height`.
    pub transfer: Transfer,
}

/// Everything a baked file records about how it was made (glTF mesh extras `prt`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BakeMetadata {
    pub tool: String,
    pub tool_version: String,
    pub bands: u32,
    pub channels: u32,
    pub mode: Mode,
    /// Sample directions actually used (a square number for the grid strategies).
    pub samples: u32,
    /// The `--sampling` strategy's name.
    pub sampling: String,
    pub seed: u64,
    pub backend: String,
    /// One line describing the SH basis; see `sh::CONVENTION`.
    pub sh_convention: String,
    /// One line describing the radiometric meaning of the coefficients.
    pub radiometry: String,
    /// Interreflection bounces added to the direct transfer (0 for the other modes).
    #[serde(default)]
    pub bounces: u32,
    /// How vertex values were obtained from the baked receivers (absent: `point`).
    #[serde(default, skip_serializing_if = "Fit::is_point")]
    pub fit: Fit,
    /// Least-squares fit: the surface points baked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit_points: Option<u32>,
    /// An error-targeted bake's target (`samples` is then the mean over receivers).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_error: Option<f64>,
    /// The transfer leaves the albedo out: radiance is `albedo * sum_k l_k t_k`, the albedo
    /// being the vertex colour (`COLOR_0`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub albedo_free: bool,
}

/// How a bake turns transfer baked at receivers into the per-vertex values a renderer
/// interpolates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Fit {
    /// Bake at the vertices: exact there, whatever lies between them.
    #[default]
    Point,
    /// Bake at points spread over every triangle and fit the vertex values whose
    /// interpolation matches them best over the surface (Kavan et al. 2011).
    LeastSquares,
}

impl Fit {
    pub fn name(self) -> &'static str {
        match self {
            Fit::Point => "point",
            Fit::LeastSquares => "least-squares",
        }
    }

    fn is_point(&self) -> bool {
        *self == Fit::Point
    }
}

/// The strategy a bake uses when none is asked for; chosen from `prt-gpu chart` (README): the
/// least error per sample, and with fan packets on the CPU as many rays per second as the
/// shared-direction sets.
pub const DEFAULT_SAMPLING: Sampling = Sampling::Cosine;

/// The sample count a bake uses when none is asked for (README: with the default strategy it
/// has a third of the error of the tutorial's 1024 stratified samples, at the same count).
pub const DEFAULT_SAMPLES: u32 = 1024;

/// What the user asks of a bake.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeOptions {
    pub bands: u32,
    /// Requested sample directions; the grid strategies use the nearest square.
    pub samples: u32,
    pub sampling: Sampling,
    pub seed: u64,
    pub mode: Mode,
    /// Replaces every material's albedo when set.
    pub albedo: Option<Vec3>,
    /// Interreflected mode: bounces after the direct pass.
    pub bounces: u32,
    /// Interreflected mode: stop once a bounce adds less than this fraction of the energy.
    pub bounce_tolerance: f64,
    pub fit: Fit,
    /// Least-squares fit: how many surface points to bake.
    pub point_density: PointDensity,
    /// Also bake a lightmap about this many texels on its longer side.
    pub lightmap: Option<u32>,
    /// Cast samples per receiver until this error is reached (instead of `samples` each).
    pub target_error: Option<adaptive::TargetError>,
    pub storage: Storage,
}

/// How the transfer is stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Storage {
    /// Red, green and blue transfer, albedo included.
    #[default]
    Rgb,
    /// One channel where one suffices: shadowed and unshadowed transfer albedo-free (the albedo,
    /// in `COLOR_0`, is applied at relighting); interreflected transfer when every albedo is
    /// grey (its channels are then equal); RGB otherwise.
    Lean,
}

impl Default for BakeOptions {
    fn default() -> Self {
        BakeOptions {
            bands: 4,
            samples: DEFAULT_SAMPLES,
            sampling: DEFAULT_SAMPLING,
            seed: 1,
            mode: Mode::Shadowed,
            albedo: None,
            bounces: 3,
            bounce_tolerance: 0.0,
            fit: Fit::Point,
            point_density: PointDensity::default(),
            lightmap: None,
            target_error: None,
            storage: Storage::Rgb,
        }
    }
}

impl BakeOptions {
    pub fn validate(&self) -> Result<()> {
        if self.mode == Mode::Local {
            return Err(Error::Options(
                "--mode local bakes depth maps and a direct-to-indirect operator, not SH \
                 transfer (local::bake_local)"
                    .into(),
            ));
        }
        if self.bands == 0 || self.bands > MAX_BANDS {
            return Err(Error::Options(format!(
                "--bands {} is out of range (1 to {MAX_BANDS})",
                self.bands
            )));
        }
        if self.samples == 0 || self.samples > MAX_SAMPLES {
            return Err(Error::Options(format!(
                "--samples {} is out of range (1 to {MAX_SAMPLES})",
                self.samples
            )));
        }
        if self.bounces > MAX_BOUNCES {
            return Err(Error::Options(format!(
                "--bounces {} is out of range (0 to {MAX_BOUNCES})",
                self.bounces
            )));
        }
        if !(0.0..1.0).contains(&self.bounce_tolerance) {
            return Err(Error::Options(format!(
                "--bounce-tolerance {} must lie in [0, 1)",
                self.bounce_tolerance
            )));
        }
        if let Some(size) = self.lightmap {
            let max = crate::receivers::atlas::MAX_ATLAS_SIZE;
            if !(1..=max).contains(&size) {
                return Err(Error::Options(format!(
                    "--lightmap {size} is out of range (1 to {max} texels)"
                )));
            }
        }
        if let Some(target) = &self.target_error {
            target.validate()?;
            if self.mode == Mode::Interreflected {
                return Err(Error::Options(
                    "--target-error bakes shadowed and unshadowed transfer, not interreflected"
                        .into(),
                ));
            }
        }
        if self.storage == Storage::Lean && self.lightmap.is_some() {
            return Err(Error::Options(
                "--storage lean stores vertex transfer; lightmaps are stored in RGB".into(),
            ));
        }
        let density = self.point_density;
        if !(density.per_vertex.is_finite()
            && density.per_vertex > 0.0
            && density.per_vertex <= 1e4)
            || density.min_per_triangle == 0
        {
            return Err(Error::Options(format!(
                "--fit-points {} must be a number of points per vertex in (0, 10000]",
                density.per_vertex
            )));
        }
        if let Some(a) = self.albedo {
            if !a.is_finite() || a.min_element() < 0.0 || a.max_element() > 1.0 {
                return Err(Error::Options(format!(
                    "--albedo {},{},{} must lie in [0, 1]",
                    a.x, a.y, a.z
                )));
            }
        }
        Ok(())
    }

    /// The sample count actually used (the nearest square for the grid strategies).
    pub fn samples_used(&self) -> u32 {
        self.sampling.samples_used(self.samples)
    }
}

/// Receives progress from long stages; the CLI draws it, tests ignore it.
pub trait Progress: Sync {
    /// A stage of `total` work items begins.
    fn stage(&self, _name: &str, _total: u64) {}
    /// `done` more items of the current stage are finished.
    fn advance(&self, _done: u64) {}
}

/// Progress that goes nowhere.
pub struct NoProgress;
impl Progress for NoProgress {}

/// The flattened inputs every backend reads: the same arrays the GPU uploads.
pub struct DirectInputs<'a> {
    /// Ray origins, one per receiver: its position moved off the surface
    /// (`ray::offset_ray_origin`).
    pub origins: &'a [Vec3],
    /// The receivers' unit shading normals.
    pub normals: &'a [Vec3],
    /// The scene's triangles (what hit triangles' `source_index` refers to).
    pub triangles: &'a [[u32; 3]],
    /// The scene's vertex normals (for the shading normal at a hit); the same as `normals`
    /// when the receivers are the vertices.
    pub vertex_normals: &'a [Vec3],
    pub bvh: &'a Bvh,
    pub samples: &'a SampleSet,
    /// SH of each sample direction, `[sample][k]` (in the tangent frame for tangent sets).
    pub table: &'a ShTable,
    pub estimator: Estimator,
    /// Turns a tangent set's sums into the world, vertex by vertex (`table.bands` bands).
    pub tangent_to_world: &'a EulerShRotation,
}

/// Where the transfer is computed.
pub enum Backend<'a> {
    Cpu,
    Gpu {
        baker: &'a gpu::GpuBaker,
        chunking: gpu::Chunking,
    },
}

impl Backend<'_> {
    /// "cpu", or "gpu: adapter (backend, type)".
    pub fn describe(&self) -> String {
        match self {
            Backend::Cpu => "cpu".to_string(),
            Backend::Gpu { baker, .. } => format!("gpu: {}", baker.context.adapter.label()),
        }
    }
}

/// What a bake did, for the summary line.
#[derive(Clone, Debug)]
pub struct BakeReport {
    pub prepare: PrepareReport,
    /// For every vertex of the scene as given, its vertex in the baked (prepared) mesh.
    pub vertex_map: VertexMap,
    /// Points the transfer was computed at (the vertices, or the fit's surface points).
    pub receivers: usize,
    pub samples_used: u32,
    pub rays_cast: u64,
    pub bvh_nodes: usize,
    pub seconds_prepare: f64,
    /// The direct pass (and, interreflected, the hits and the gather matrix).
    pub seconds_transfer: f64,
    /// The least-squares fit of the direct pass (zero for point values).
    pub seconds_fit: f64,
    /// The fit's solve, when the vertex values were fitted.
    pub fit: Option<FitReport>,
    /// The lightmap's bake, when one was asked for.
    pub texels: Option<texels::TexelReport>,
    /// The error-targeted direct pass, when a target was given.
    pub adaptive: Option<adaptive::AdaptiveReport>,
    /// One entry per bounce performed (each including its fit).
    pub bounces: Vec<BounceStat>,
    /// Non-zero entries of the gather matrix (interreflected mode).
    pub gather_entries: usize,
    pub backend: String,
}

/// What one bounce added and what it cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BounceStat {
    /// DC energy the bounce added over the DC energy of all transfer before it.
    pub relative_energy: f64,
    pub seconds: f64,
}

/// What a bounce reads: the gather matrix (rows: receivers), the receivers' albedo, and the
/// map from values at the receivers to vertex values (the identity, or the fit).
struct Gather<'a> {
    matrix: &'a bounce::GatherMatrix,
    albedo: &'a [Vec3],
    to_vertices: &'a mut dyn FnMut(Vec<f32>) -> Result<Vec<f32>>,
}

/// Adds `options.bounces` bounces to the vertex `transfer` in place (stopping early below
/// `options.bounce_tolerance`), on the backend's device. Each bounce gathers the previous
/// one's vertex values at the receivers and takes them back to the vertices.
fn add_bounces(
    transfer: &mut Transfer,
    gather: Gather,
    options: &BakeOptions,
    backend: &Backend,
    progress: &dyn Progress,
) -> Result<Vec<BounceStat>> {
    let coeffs = coeff_count(transfer.bands);
    let uploaded = match backend {
        Backend::Gpu { baker, .. } => Some((
            baker,
            baker.upload_gather_matrix(gather.matrix, gather.albedo, transfer.bands)?,
        )),
        Backend::Cpu => None,
    };
    progress.stage("bounces", options.bounces as u64);
    let mut previous = transfer.coeffs.clone();
    let mut stats = Vec::new();
    for _ in 0..options.bounces {
        let started = Instant::now();
        let at_receivers = match &uploaded {
            Some((baker, gpu_matrix)) => baker.bounce(gpu_matrix, &previous)?,
            None => bounce::apply_cpu(gather.matrix, &previous, gather.albedo, coeffs),
        };
        let next = (gather.to_vertices)(at_receivers)?;
        let relative_energy = bounce::relative_energy(&next, &transfer.coeffs, coeffs);
        transfer
            .coeffs
            .iter_mut()
            .zip(&next)
            .for_each(|(t, n)| *t += n);
        stats.push(BounceStat {
            relative_energy,
            seconds: started.elapsed().as_secs_f64(),
        });
        progress.advance(1);
        previous = next;
        if relative_energy < options.bounce_tolerance {
            break;
        }
    }
    Ok(stats)
}

/// The whole bake: prepare the mesh, build the BVH, choose the receivers, draw samples,
/// compute transfer at the receivers and, for the least-squares fit, the vertex values that
/// best match it.
pub fn bake(
    scene: Scene,
    options: &BakeOptions,
    backend: &Backend,
    progress: &dyn Progress,
) -> Result<(BakedMesh, BakeReport)> {
    bake_from(
        scene,
        options,
        backend,
        DirectSource::Compute,
        None,
        progress,
    )
}

/// Where a bake's direct pass comes from.
pub enum DirectSource {
    /// Computed here, on the bake's backend.
    Compute,
    /// Already computed (by the shards of a sharded bake, merged), on the backend `ran_on`
    /// describes: the rest of the bake (fit, bounces, lightmap) runs here.
    Given { direct: DirectPass, ran_on: String },
}

/// A part of a bake's receivers: shard `index` of `count`, each a contiguous run of about
/// the same number of receivers in the prepared (Morton) order, so a shard's rays stay
/// coherent. Which receivers a shard holds depends only on the receiver count, and what
/// each receiver gets only on the receiver, so shards merge to the unsharded bake bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    pub fn new(index: u32, count: u32) -> Result<Shard> {
        if count == 0 || index >= count {
            return Err(Error::Options(format!(
                "--shard {index}/{count}: the shard index must lie in 0 to count - 1"
            )));
        }
        Ok(Shard { index, count })
    }

    /// The receivers of `total` this shard bakes.
    pub fn receivers(&self, total: usize) -> std::ops::Range<usize> {
        let edge = |i: u32| (total as u128 * i as u128 / self.count as u128) as usize;
        edge(self.index)..edge(self.index + 1)
    }
}

/// What a shard bakes: the direct pass of its receivers (gather rows included, for
/// interreflection), which of how many receivers they are, and the backend it ran on.
pub struct ShardPass {
    pub receivers: std::ops::Range<usize>,
    pub receivers_total: usize,
    pub direct: DirectPass,
    pub ran_on: String,
}

/// The direct pass of `shard`'s receivers of the bake of `scene` with `options`: everything a
/// shard computes. Bounces, fits and lightmaps need every receiver and run where the shards
/// are merged ([`bake_from`] with [`DirectSource::Given`]).
pub fn bake_shard(
    scene: Scene,
    options: &BakeOptions,
    backend: &Backend,
    shard: Shard,
    progress: &dyn Progress,
) -> Result<ShardPass> {
    options.validate()?;
    let planned = plan(scene, options)?;
    let range = shard.receivers(planned.receivers.len());
    let direct = direct_or_adaptive(&planned.inputs, range.clone(), options, backend, progress)?;
    Ok(ShardPass {
        receivers: range,
        receivers_total: planned.receivers.len(),
        direct,
        ran_on: direct_pass_ran_on(options, backend),
    })
}

/// The backend a direct pass with `options` runs on: error-targeted passes run on the CPU
/// whatever the backend.
fn direct_pass_ran_on(options: &BakeOptions, backend: &Backend) -> String {
    match options.target_error {
        Some(_) => Backend::Cpu.describe(),
        None => backend.describe(),
    }
}

/// What every bake does before its direct pass: the prepared scene, its receivers, and what
/// the backends read.
struct Planned {
    scene: Scene,
    prepare: PrepareReport,
    vertex_map: VertexMap,
    receivers: Receivers,
    points: Vec<SurfacePoint>,
    inputs: BakeInputs,
    seconds: f64,
}

fn plan(scene: Scene, options: &BakeOptions) -> Result<Planned> {
    let started = Instant::now();
    let (scene, prepare, vertex_map) = prepare_with_albedo(scene, options)?;
    let bvh = Bvh::build(&scene.positions, &scene.triangles);
    let (receivers, points) = choose_receivers(&scene, &bvh, options);
    let inputs = BakeInputs::with_tree(&scene, &receivers, bvh, options);
    Ok(Planned {
        scene,
        prepare,
        vertex_map,
        receivers,
        points,
        inputs,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// [`bake`] with its direct pass from `source`, and its lightmap (when the options ask for one)
/// on `uv_set` (given per triangle of `scene`), or on a generated atlas without one.
pub fn bake_from(
    scene: Scene,
    options: &BakeOptions,
    backend: &Backend,
    source: DirectSource,
    uv_set: Option<&UvSet>,
    progress: &dyn Progress,
) -> Result<(BakedMesh, BakeReport)> {
    options.validate()?;
    let uv_set = uv_set.map(|set| set.kept(&kept_triangles(&scene)));
    let mut planned = plan(scene, options)?;
    // A lightmap that cannot fit fails now, not after the vertices are baked.
    let atlas = match (options.lightmap, &uv_set) {
        (Some(size), Some(set)) => {
            if set.corners.len() != planned.scene.triangles.len() {
                return Err(Error::Geometry(format!(
                    "the lightmap's UV set has {} triangles, the prepared scene {}",
                    set.corners.len(),
                    planned.scene.triangles.len()
                )));
            }
            Some(set.atlas(size))
        }
        (Some(size), None) => Some(texels::plan_atlas(&planned.scene, size)?),
        (None, _) => None,
    };
    // A generated atlas gives every corner its own coordinates, and the mesh is split to
    // carry them; a scene's own set keeps them on its vertices.
    let set = uv_set.as_ref().map(|set| set.set);

    let started = Instant::now();
    let (direct, ran_on) = match source {
        DirectSource::Compute => {
            let all = 0..planned.receivers.len();
            let direct = direct_or_adaptive(&planned.inputs, all, options, backend, progress)?;
            (direct, direct_pass_ran_on(options, backend))
        }
        DirectSource::Given { direct, ran_on } => {
            check_given(&direct, &planned.receivers, options)?;
            (direct, ran_on)
        }
    };
    let adaptive_report = options
        .target_error
        .zip(direct.adaptive.as_ref())
        .map(|(target, receivers)| adaptive::AdaptiveReport::of(receivers, &target));
    let seconds_transfer = started.elapsed().as_secs_f64();

    let (scene, receivers, points) = (&planned.scene, &planned.receivers, &planned.points);
    let fitted = vertex_transfer(
        scene, receivers, points, &direct, options, backend, progress,
    )?;
    let (transfer, bounces, fit_report, seconds_fit) = fitted;
    let (transfer, albedo_free) = stored(transfer, &direct.scalar, scene, points, options)?;
    let scene = std::mem::take(&mut planned.scene);
    let (scene, transfer, lightmap, texel_report) = match &atlas {
        None => (scene, transfer, None, None),
        Some(atlas) => add_lightmap(scene, transfer, atlas, set, options, backend, progress)?,
    };
    let fit_points = (options.fit == Fit::LeastSquares).then_some(planned.points.len() as u32);
    let samples_used = planned.inputs.samples.len();
    // An error-targeted bake records the mean over receivers.
    let samples = adaptive_report
        .as_ref()
        .map_or(samples_used, |r| r.samples_mean.round() as usize);
    let metadata = BakeMetadata {
        channels: transfer.channels,
        albedo_free,
        backend: ran_on,
        ..metadata_for(options, samples, bounces.len(), fit_points)
    };
    let report = BakeReport {
        prepare: planned.prepare,
        vertex_map: planned.vertex_map,
        receivers: planned.receivers.len(),
        samples_used: samples_used as u32,
        rays_cast: direct.rays_cast,
        bvh_nodes: planned.inputs.bvh.nodes.len(),
        seconds_prepare: planned.seconds,
        seconds_transfer,
        seconds_fit,
        fit: fit_report,
        texels: texel_report,
        adaptive: adaptive_report,
        bounces,
        gather_entries: direct.matrix.map_or(0, |m| m.columns.len()),
        backend: backend.describe(),
    };
    Ok((
        BakedMesh {
            scene,
            transfer,
            metadata,
            lightmap,
        },
        report,
    ))
}

/// Refuses a given direct pass that is not one of these receivers' (wrong count, or no
/// gather matrix for interreflection).
fn check_given(direct: &DirectPass, receivers: &Receivers, options: &BakeOptions) -> Result<()> {
    let expected = receivers.len() * coeff_count(options.bands);
    let rows_fit = match (&direct.matrix, options.mode) {
        (Some(matrix), Mode::Interreflected) => matrix.rows() == receivers.len(),
        (None, Mode::Interreflected) => false,
        (_, _) => true,
    };
    let adaptive_fits = match (&direct.adaptive, options.target_error) {
        (Some(receivers_of), Some(_)) => receivers_of.len() == receivers.len(),
        (None, None) => true,
        _ => false,
    };
    if !adaptive_fits {
        return Err(Error::Options(format!(
            "the given direct pass {} each receiver's samples and error, which an error target \
             {} ({} receivers)",
            if direct.adaptive.is_some() {
                "carries"
            } else {
                "lacks"
            },
            if options.target_error.is_some() {
                "needs for all"
            } else {
                "would not give"
            },
            receivers.len()
        )));
    }
    if direct.scalar.len() != expected || !rows_fit {
        return Err(Error::Options(format!(
            "the given direct pass holds {} values for {} receivers of {} coefficients",
            direct.scalar.len(),
            receivers.len(),
            coeff_count(options.bands)
        )));
    }
    Ok(())
}

/// The transfer as `options.storage` stores it, and whether it left the albedo out. Lean: one
/// channel where one suffices: direct transfer becomes the albedo-free scalar (fitted as the RGB was);
/// interreflected transfer keeps its red channel when every albedo is grey.
fn stored(
    rgb: Transfer,
    scalar: &[f32],
    scene: &Scene,
    points: &[SurfacePoint],
    options: &BakeOptions,
) -> Result<(Transfer, bool)> {
    if options.storage == Storage::Rgb {
        return Ok((rgb, false));
    }
    let n = coeff_count(rgb.bands);
    if options.mode != Mode::Interreflected {
        let coeffs = match options.fit {
            Fit::Point => scalar.to_vec(),
            Fit::LeastSquares => fit_vertices(scene, points, scalar, n, &FitOptions::default())?.0,
        };
        let transfer = Transfer {
            channels: 1,
            coeffs,
            ..rgb
        };
        return Ok((transfer, true));
    }
    if scene.albedo.iter().any(|a| a.x != a.y || a.y != a.z) {
        return Ok((rgb, false));
    }
    let coeffs = rgb
        .coeffs
        .chunks_exact(3 * n)
        .flat_map(|v| v[..n].iter().copied())
        .collect();
    let transfer = Transfer {
        channels: 1,
        coeffs,
        ..rgb
    };
    Ok((transfer, false))
}

/// The scene, its transfer and its lightmap's bake: the texels of `atlas` baked, and the mesh
/// split at every corner to carry their coordinates, unless they are the scene's own `set`.
fn add_lightmap(
    scene: Scene,
    transfer: Transfer,
    atlas: &receivers::atlas::Atlas,
    set: Option<u32>,
    options: &BakeOptions,
    backend: &Backend,
    progress: &dyn Progress,
) -> Result<(
    Scene,
    Transfer,
    Option<TexelBake>,
    Option<texels::TexelReport>,
)> {
    let (mut lightmap, report) =
        texels::bake_atlas(&scene, &transfer, options, atlas, backend, progress)?;
    lightmap.set = set.unwrap_or(0);
    let (scene, transfer) = match set {
        None => texels::split_corners(&scene, &transfer),
        Some(_) => (scene, transfer),
    };
    Ok((scene, transfer, Some(lightmap), Some(report)))
}

/// Vertex transfer from the direct pass at the receivers (fitted, for the least-squares fit)
/// and its bounces; what each bounce added, the first fit's report and the direct fit's time.
fn vertex_transfer(
    scene: &Scene,
    receivers: &Receivers,
    points: &[SurfacePoint],
    direct: &DirectPass,
    options: &BakeOptions,
    backend: &Backend,
    progress: &dyn Progress,
) -> Result<(Transfer, Vec<BounceStat>, Option<FitReport>, f64)> {
    let started = Instant::now();
    let columns = 3 * coeff_count(options.bands);
    let mut fit_report = None;
    let mut to_vertices = |values: Vec<f32>| -> Result<Vec<f32>> {
        if options.fit == Fit::Point {
            return Ok(values);
        }
        let (fitted, report) =
            fit_vertices(scene, points, &values, columns, &FitOptions::default())?;
        // The direct pass's solve is the one reported; the bounces' are like it.
        fit_report.get_or_insert(report);
        Ok(fitted)
    };
    let at_receivers = tint_by_albedo(&direct.scalar, &receivers.albedo, options.bands);
    let mut transfer = Transfer {
        bands: options.bands,
        channels: 3,
        vertex_count: scene.vertex_count(),
        coeffs: to_vertices(at_receivers.coeffs)?,
    };
    let seconds_fit = match options.fit {
        Fit::Point => 0.0,
        Fit::LeastSquares => started.elapsed().as_secs_f64(),
    };
    let bounces = match &direct.matrix {
        Some(matrix) => {
            let (albedo, to_vertices) = (&receivers.albedo, &mut to_vertices);
            let gather = Gather {
                matrix,
                albedo,
                to_vertices,
            };
            add_bounces(&mut transfer, gather, options, backend, progress)?
        }
        None => Vec::new(),
    };
    Ok((transfer, bounces, fit_report, seconds_fit))
}

/// The scene prepared for the bake, its albedo replaced where the options say so.
fn prepare_with_albedo(
    scene: Scene,
    options: &BakeOptions,
) -> Result<(Scene, PrepareReport, VertexMap)> {
    let (mut scene, report, map) = prepare_mapped(scene)?;
    if let Some(albedo) = options.albedo {
        scene.albedo.iter_mut().for_each(|a| *a = albedo);
    }
    Ok((scene, report, map))
}

/// The direct pass of the receivers `range` of `owned`: a fixed sample count on the backend,
/// or to the options' error target on the CPU (with each receiver's samples and error).
fn direct_or_adaptive(
    owned: &BakeInputs,
    range: std::ops::Range<usize>,
    options: &BakeOptions,
    backend: &Backend,
    progress: &dyn Progress,
) -> Result<DirectPass> {
    let Some(target) = &options.target_error else {
        let view = owned.view();
        let part = DirectInputs {
            origins: &view.origins[range.clone()],
            normals: &view.normals[range],
            ..view
        };
        return direct_pass(&part, options.mode, backend, progress);
    };
    progress.stage("transfer", range.len() as u64);
    let (scalar, rays_cast, receivers) = adaptive::adaptive_direct_transfer(
        owned,
        range,
        (options.sampling, options.seed, options.mode),
        target,
        progress,
    )?;
    Ok(DirectPass {
        scalar,
        matrix: None,
        rays_cast,
        adaptive: Some(receivers),
    })
}

/// The receivers of a bake: the vertices, or (least-squares fit) the points spread over the
/// triangles, which it also returns.
fn choose_receivers(
    scene: &Scene,
    bvh: &Bvh,
    options: &BakeOptions,
) -> (Receivers, Vec<SurfacePoint>) {
    match options.fit {
        Fit::Point => (Receivers::vertices(scene), Vec::new()),
        Fit::LeastSquares => {
            let spread = spread_points(scene, options.point_density, options.seed);
            // Points inside other geometry are never seen and would pull their vertices dark.
            let candidates = Receivers::at_points(scene, &spread);
            let inside = texels::leaking_receivers_in(scene, bvh, &candidates);
            let points: Vec<SurfacePoint> = spread
                .into_iter()
                .zip(inside)
                .filter(|(_, inside)| !inside)
                .map(|(p, _)| p)
                .collect();
            (Receivers::at_points(scene, &points), points)
        }
    }
}

/// What the baked file records about a bake with `options`.
fn metadata_for(
    options: &BakeOptions,
    samples: usize,
    bounces: usize,
    fit_points: Option<u32>,
) -> BakeMetadata {
    BakeMetadata {
        tool: env!("CARGO_PKG_NAME").to_string(),
        tool_version: env!("CARGO_PKG_VERSION").to_string(),
        bands: options.bands,
        channels: 3,
        mode: options.mode,
        samples: samples as u32,
        sampling: options.sampling.name().to_string(),
        seed: options.seed,
        backend: String::new(),
        sh_convention: CONVENTION.to_string(),
        radiometry: RADIOMETRY.to_string(),
        bounces: bounces as u32,
        fit: options.fit,
        fit_points,
        target_error: options.target_error.map(|t| t.relative),
        albedo_free: false,
    }
}

/// Transfer at `receivers` on a prepared `scene` (RGB, `[receiver][channel][k]`; the
/// receivers' albedo unless `options.albedo` replaces it), and the rays cast. Interreflected
/// mode adds one final gather of `vertex_transfer` (the scene's baked vertex transfer, bounces
/// included) where each receiver's blocked rays land, as lightmappers gather from a coarser
/// solution: the receivers then carry one bounce more than the vertices.
pub fn bake_at(
    scene: &Scene,
    receivers: &Receivers,
    options: &BakeOptions,
    backend: &Backend,
    vertex_transfer: Option<&Transfer>,
    progress: &dyn Progress,
) -> Result<(Transfer, u64)> {
    let bvh = Bvh::build(&scene.positions, &scene.triangles);
    let at = (receivers, bvh);
    bake_at_in(scene, at, options, backend, vertex_transfer, progress)
}

/// [`bake_at`] with the scene's tree already built.
pub fn bake_at_in(
    scene: &Scene,
    (receivers, bvh): (&Receivers, Bvh),
    options: &BakeOptions,
    backend: &Backend,
    vertex_transfer: Option<&Transfer>,
    progress: &dyn Progress,
) -> Result<(Transfer, u64)> {
    options.validate()?;
    let owned = BakeInputs::with_tree(scene, receivers, bvh, options);
    let direct = direct_pass(&owned.view(), options.mode, backend, progress)?;
    let albedo = match options.albedo {
        Some(albedo) => vec![albedo; receivers.len()],
        None => receivers.albedo.clone(),
    };
    let mut transfer = tint_by_albedo(&direct.scalar, &albedo, options.bands);
    if let Some(matrix) = &direct.matrix {
        let vertices = vertex_transfer
            .filter(|t| t.vertex_count == scene.vertex_count() && t.bands == options.bands)
            .ok_or_else(|| {
                Error::Options(
                    "interreflected transfer at surface points gathers from the vertices' \
                     transfer, and none of this scene and band count was given"
                        .into(),
                )
            })?;
        let coeffs = coeff_count(options.bands);
        let gathered = match backend {
            Backend::Gpu { baker, .. } => {
                let uploaded =
                    baker.upload_gather_matrix(matrix, &receivers.albedo, options.bands)?;
                baker.bounce(&uploaded, &vertices.coeffs)?
            }
            Backend::Cpu => bounce::apply_cpu(matrix, &vertices.coeffs, &receivers.albedo, coeffs),
        };
        transfer
            .coeffs
            .iter_mut()
            .zip(gathered)
            .for_each(|(t, g)| *t += g);
    }
    Ok((transfer, direct.rays_cast))
}

/// What the direct pass gives: albedo-free transfer `[receiver][k]`, the gather matrix
/// (interreflected mode: rows are receivers, columns the scene's vertices), the rays cast,
/// and for an error-targeted pass each receiver's samples and error.
pub struct DirectPass {
    pub scalar: Vec<f32>,
    pub matrix: Option<bounce::GatherMatrix>,
    pub rays_cast: u64,
    pub adaptive: Option<adaptive::ReceiverErrors>,
}

/// The direct pass over the receivers of `inputs` on either backend.
pub fn direct_pass(
    inputs: &DirectInputs,
    mode: Mode,
    backend: &Backend,
    progress: &dyn Progress,
) -> Result<DirectPass> {
    progress.stage("transfer", inputs.origins.len() as u64);
    let (scalar, matrix, rays_cast) = match (backend, mode) {
        (Backend::Cpu, Mode::Interreflected) => {
            let (scalar, matrix, rays) =
                bounce::direct_transfer_and_gather_matrix_cpu(inputs, progress);
            (scalar, Some(matrix), rays)
        }
        (Backend::Cpu, mode) => {
            let (scalar, rays) = cpu::direct_transfer(inputs, mode, progress);
            (scalar, None, rays)
        }
        (Backend::Gpu { baker, chunking }, Mode::Interreflected) => {
            let (scalar, matrix, run) =
                gpu::direct_transfer_and_gather_matrix(baker, inputs, *chunking, progress)?;
            (scalar, Some(matrix), run.rays_cast)
        }
        (Backend::Gpu { baker, chunking }, mode) => {
            let (scalar, run) = gpu::direct_transfer(baker, inputs, mode, *chunking, progress)?;
            (scalar, None, run.rays_cast)
        }
    };
    Ok(DirectPass {
        scalar,
        matrix,
        rays_cast,
        adaptive: None,
    })
}

/// The arrays [`DirectInputs`] borrows, built from a prepared scene: what both backends read.
pub struct BakeInputs {
    pub origins: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub vertex_normals: Vec<Vec3>,
    pub bvh: Bvh,
    pub samples: SampleSet,
    pub table: ShTable,
    pub estimator: Estimator,
    pub tangent_to_world: EulerShRotation,
}

impl BakeInputs {
    /// Stratified sampling (the tutorial's); `scene` must be prepared (normals present) and
    /// `samples` a square.
    pub fn new(scene: &Scene, bands: u32, samples: u32, seed: u64) -> Self {
        Self::with_sampling(scene, bands, samples, seed, Sampling::Stratified)
    }

    /// What a bake of the vertices with `options` reads.
    pub fn for_options(scene: &Scene, options: &BakeOptions) -> Self {
        Self::for_receivers(scene, &Receivers::vertices(scene), options)
    }

    /// What a bake with `options` at `receivers` on `scene` reads.
    pub fn for_receivers(scene: &Scene, receivers: &Receivers, options: &BakeOptions) -> Self {
        Self::at_receivers(
            scene,
            receivers,
            options.bands,
            options.samples_used(),
            options.seed,
            options.sampling,
        )
    }

    /// `samples` must come from [`Sampling::samples_used`].
    pub fn with_sampling(
        scene: &Scene,
        bands: u32,
        samples: u32,
        seed: u64,
        sampling: Sampling,
    ) -> Self {
        let receivers = Receivers::vertices(scene);
        Self::at_receivers(scene, &receivers, bands, samples, seed, sampling)
    }

    /// [`BakeInputs::for_receivers`] with the scene's tree already built.
    pub fn with_tree(
        scene: &Scene,
        receivers: &Receivers,
        bvh: Bvh,
        options: &BakeOptions,
    ) -> Self {
        let sampling = (
            options.bands,
            options.samples_used(),
            options.seed,
            options.sampling,
        );
        Self::assemble(scene, receivers, bvh, sampling)
    }

    fn at_receivers(
        scene: &Scene,
        receivers: &Receivers,
        bands: u32,
        samples: u32,
        seed: u64,
        sampling: Sampling,
    ) -> Self {
        let bvh = Bvh::build(&scene.positions, &scene.triangles);
        Self::assemble(scene, receivers, bvh, (bands, samples, seed, sampling))
    }

    fn assemble(
        scene: &Scene,
        receivers: &Receivers,
        bvh: Bvh,
        (bands, samples, seed, sampling): (u32, u32, u64, Sampling),
    ) -> Self {
        let vertex_normals = scene.normals.clone().expect("a prepared scene has normals");
        let origins = ray_origins(&receivers.ray_starts, &receivers.normals, bvh.extent());
        let samples = sampling.directions(samples, seed);
        let table = ShTable::new(bands, &samples.directions);
        BakeInputs {
            origins,
            normals: receivers.normals.clone(),
            triangles: scene.triangles.clone(),
            vertex_normals,
            bvh,
            samples,
            table,
            estimator: sampling.estimator(),
            tangent_to_world: EulerShRotation::new(bands),
        }
    }

    pub fn view(&self) -> DirectInputs<'_> {
        DirectInputs {
            origins: &self.origins,
            normals: &self.normals,
            triangles: &self.triangles,
            vertex_normals: &self.vertex_normals,
            bvh: &self.bvh,
            samples: &self.samples,
            table: &self.table,
            estimator: self.estimator,
            tangent_to_world: &self.tangent_to_world,
        }
    }
}

/// Every receiver's ray start moved off its surface along its normal, where its rays start
/// (`extent`: the scene's, which sets the offset's floor).
pub fn ray_origins(starts: &[Vec3], normals: &[Vec3], extent: f32) -> Vec<Vec3> {
    starts
        .iter()
        .zip(normals)
        .map(|(&p, &n)| offset_ray_origin(p, n, extent))
        .collect()
}

/// The meaning of the coefficients, for file metadata.
pub const RADIOMETRY: &str = "exit radiance L_o = sum_k l_k t_k per channel, \
l_k = integral L_in(w) y_k(w) dw, t_k = (albedo/pi) integral V(w) max(0, n.w) y_k(w) dw";

/// RGB transfer from albedo-free scalar transfer: channel c of vertex v is `albedo[v][c]` times it.
pub fn tint_by_albedo(scalar: &[f32], albedo: &[Vec3], bands: u32) -> Transfer {
    let n = coeff_count(bands);
    let mut coeffs = Vec::with_capacity(scalar.len() * 3);
    for (t, a) in scalar.chunks_exact(n).zip(albedo) {
        for c in 0..3 {
            coeffs.extend(t.iter().map(|x| x * a[c]));
        }
    }
    Transfer {
        bands,
        channels: 3,
        vertex_count: albedo.len(),
        coeffs,
    }
}

/// The fraction of a transfer's energy (sum of squared coefficients over vertices and channels)
/// in each band `l`.
pub fn band_energy_fractions(transfer: &Transfer) -> Vec<f64> {
    let n = transfer.coeffs_per_channel();
    let mut energy = vec![0.0f64; transfer.bands as usize];
    for row in transfer.coeffs.chunks_exact(n) {
        for (k, &t) in row.iter().enumerate() {
            energy[(k as f64).sqrt() as usize] += (t as f64) * (t as f64);
        }
    }
    let total: f64 = energy.iter().sum();
    energy
        .iter()
        .map(|e| e / total.max(f64::MIN_POSITIVE))
        .collect()
}

/// The fewest bands whose transfer leaves less than `threshold` of the energy in the bands
/// above them, and the fraction it leaves.
pub fn choose_bands(transfer: &Transfer, threshold: f64) -> (u32, f64) {
    let fractions = band_energy_fractions(transfer);
    (1..=transfer.bands)
        .map(|bands| (bands, fractions[bands as usize..].iter().sum::<f64>()))
        .find(|&(_, beyond)| beyond < threshold)
        .unwrap_or((transfer.bands, 0.0))
}

/// `transfer` with only its first `bands` bands: the lower bands of SH transfer do not depend on
/// the higher ones, so this is the transfer a bake of `bands` bands computes.
pub fn truncate_bands(transfer: &Transfer, bands: u32) -> Transfer {
    let (n, kept) = (transfer.coeffs_per_channel(), coeff_count(bands));
    Transfer {
        bands,
        channels: transfer.channels,
        vertex_count: transfer.vertex_count,
        coeffs: transfer
            .coeffs
            .chunks_exact(n)
            .flat_map(|row| row[..kept].iter().copied())
            .collect(),
    }
}

/// A baked mesh cut to `bands` bands (its lightmap too), its metadata saying so.
pub fn truncate_baked(baked: &mut BakedMesh, bands: u32) {
    baked.transfer = truncate_bands(&baked.transfer, bands);
    if let Some(texels) = &mut baked.lightmap {
        texels.transfer = truncate_bands(&texels.transfer, bands);
    }
    baked.metadata.bands = bands;
}

#[cfg(test)]
mod band_tests {
    use super::*;

    #[test]
    fn bands_are_chosen_by_the_energy_above_them() {
        // One vertex, one channel, 3 bands: energies 1 (l = 0), 0.09 (l = 1), 0.01 (l = 2).
        let transfer = Transfer {
            bands: 3,
            channels: 1,
            vertex_count: 1,
            coeffs: vec![1.0, 0.3, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0],
        };
        let fractions = band_energy_fractions(&transfer);
        assert!((fractions[2] - 0.01 / 1.1).abs() < 1e-9, "{fractions:?}");
        assert_eq!(choose_bands(&transfer, 0.05).0, 2);
        assert_eq!(choose_bands(&transfer, 0.2).0, 1);
        assert_eq!(choose_bands(&transfer, 0.001).0, 3);
        let cut = truncate_bands(&transfer, 2);
        assert_eq!(cut.coeffs, vec![1.0, 0.3, 0.0, 0.0]);
    }

    #[test]
    fn a_bake_cut_to_fewer_bands_is_the_bake_of_fewer_bands() {
        let scene = crate::scene::builtin::icosphere(Vec3::ZERO, 1.0, 2);
        let plane = crate::scene::builtin::grid_plane(
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::X * 3.0,
            Vec3::NEG_Z * 3.0,
            6,
            Vec3::ONE,
        );
        let scene = crate::scene::builtin::merge(&[scene, plane]);
        let bake_with = |bands| {
            let options = BakeOptions {
                bands,
                samples: 256,
                ..BakeOptions::default()
            };
            bake(scene.clone(), &options, &Backend::Cpu, &NoProgress)
                .unwrap()
                .0
        };
        let (eight, four) = (bake_with(8), bake_with(4));
        let cut = truncate_bands(&eight.transfer, 4);
        for (a, b) in cut.coeffs.iter().zip(&four.transfer.coeffs) {
            // The same sums; only the rotation's rounding differs with the band count.
            assert!((a - b).abs() <= 1e-5 * b.abs().max(1e-2), "{a} vs {b}");
        }
    }
}
