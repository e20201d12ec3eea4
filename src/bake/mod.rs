//! The bake: options in, one [`Transfer`] out, whichever backend computes it.

pub mod cpu;
pub mod gpu;

use std::time::Instant;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::bvh::Bvh;
use crate::error::{Error, Result};
use crate::output::BakedMesh;
use crate::ray::offset_ray_origin;
use crate::sampling::{nearest_square, stratified_sphere, SampleSet, MAX_SAMPLES};
use crate::scene::prepare::{prepare, PrepareReport};
use crate::scene::Scene;
use crate::sh::{coeff_count, ShTable, CONVENTION, MAX_BANDS};

/// Which light transport the transfer vectors capture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Clamped cosine only: every direction above the horizon is assumed visible.
    Unshadowed,
    /// Clamped cosine times binary visibility against the whole scene.
    Shadowed,
}

impl Mode {
    pub fn name(self) -> &'static str {
        match self {
            Mode::Unshadowed => "unshadowed",
            Mode::Shadowed => "shadowed",
        }
    }
}

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

/// Everything a baked file records about how it was made (glTF mesh extras `prt`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BakeMetadata {
    pub tool: String,
    pub tool_version: String,
    pub bands: u32,
    pub channels: u32,
    pub mode: Mode,
    /// Sample directions actually used (a square number for stratified sampling).
    pub samples: u32,
    pub sampling: String,
    pub seed: u64,
    pub backend: String,
    /// One line describing the SH basis; see `sh::CONVENTION`.
    pub sh_convention: String,
    /// One line describing the radiometric meaning of the coefficients.
    pub radiometry: String,
}

/// What the user asks of a bake.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeOptions {
    pub bands: u32,
    /// Requested sample directions; stratified sampling uses the nearest square.
    pub samples: u32,
    pub seed: u64,
    pub mode: Mode,
    /// Replaces every material's albedo when set.
    pub albedo: Option<Vec3>,
}

impl Default for BakeOptions {
    fn default() -> Self {
        BakeOptions {
            bands: 4,
            samples: 1024,
            seed: 1,
            mode: Mode::Shadowed,
            albedo: None,
        }
    }
}

impl BakeOptions {
    pub fn validate(&self) -> Result<()> {
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

    /// The sample count actually used: the nearest square.
    pub fn samples_used(&self) -> u32 {
        nearest_square(self.samples)
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
    /// Ray origins: vertex positions moved off the surface (`ray::offset_ray_origin`).
    pub origins: &'a [Vec3],
    pub normals: &'a [Vec3],
    pub bvh: &'a Bvh,
    pub samples: &'a SampleSet,
    pub table: &'a ShTable,
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
    pub samples_used: u32,
    pub rays_cast: u64,
    pub bvh_nodes: usize,
    pub seconds_prepare: f64,
    pub seconds_transfer: f64,
    pub backend: String,
}

/// The whole bake: prepare the mesh, build the BVH, draw samples, compute transfer.
pub fn bake(
    scene: Scene,
    options: &BakeOptions,
    backend: &Backend,
    progress: &dyn Progress,
) -> Result<(BakedMesh, BakeReport)> {
    options.validate()?;
    let started = Instant::now();
    let (mut scene, prepare_report) = prepare(scene)?;
    if let Some(albedo) = options.albedo {
        scene.albedo.iter_mut().for_each(|a| *a = albedo);
    }
    let owned = BakeInputs::new(&scene, options.bands, options.samples_used(), options.seed);
    let inputs = owned.view();
    let seconds_prepare = started.elapsed().as_secs_f64();

    let started = Instant::now();
    progress.stage("transfer", scene.vertex_count() as u64);
    let (scalar, rays_cast) = match backend {
        Backend::Cpu => cpu::direct_transfer(&inputs, options.mode, progress),
        Backend::Gpu { baker, chunking } => {
            let (scalar, run) =
                gpu::direct_transfer(baker, &inputs, options.mode, *chunking, progress)?;
            (scalar, run.rays_cast)
        }
    };
    let seconds_transfer = started.elapsed().as_secs_f64();

    let transfer = tint_by_albedo(&scalar, &scene.albedo, options.bands);
    let metadata = BakeMetadata {
        tool: env!("CARGO_PKG_NAME").to_string(),
        tool_version: env!("CARGO_PKG_VERSION").to_string(),
        bands: options.bands,
        channels: transfer.channels,
        mode: options.mode,
        samples: inputs.samples.len() as u32,
        sampling: "stratified-sphere".to_string(),
        seed: options.seed,
        backend: backend.describe(),
        sh_convention: CONVENTION.to_string(),
        radiometry: RADIOMETRY.to_string(),
    };
    let report = BakeReport {
        prepare: prepare_report,
        samples_used: inputs.samples.len() as u32,
        rays_cast,
        bvh_nodes: inputs.bvh.nodes.len(),
        seconds_prepare,
        seconds_transfer,
        backend: backend.describe(),
    };
    Ok((
        BakedMesh {
            scene,
            transfer,
            metadata,
        },
        report,
    ))
}

/// The arrays [`DirectInputs`] borrows, built from a prepared scene: what both backends read.
pub struct BakeInputs {
    pub origins: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub bvh: Bvh,
    pub samples: SampleSet,
    pub table: ShTable,
}

impl BakeInputs {
    /// `scene` must be prepared (normals present); `samples` must be a square.
    pub fn new(scene: &Scene, bands: u32, samples: u32, seed: u64) -> Self {
        let normals = scene.normals.clone().expect("a prepared scene has normals");
        let bvh = Bvh::build(&scene.positions, &scene.triangles);
        let origins = ray_origins(&scene.positions, &normals, &bvh);
        let samples = stratified_sphere(samples, seed);
        let table = ShTable::new(bands, &samples.directions);
        BakeInputs {
            origins,
            normals,
            bvh,
            samples,
            table,
        }
    }

    pub fn view(&self) -> DirectInputs<'_> {
        DirectInputs {
            origins: &self.origins,
            normals: &self.normals,
            bvh: &self.bvh,
            samples: &self.samples,
            table: &self.table,
        }
    }
}

/// Every vertex moved off its surface along its normal, where its rays start.
pub fn ray_origins(positions: &[Vec3], normals: &[Vec3], bvh: &Bvh) -> Vec<Vec3> {
    let extent = bvh.extent();
    positions
        .iter()
        .zip(normals)
        .map(|(&p, &n)| offset_ray_origin(p, n, extent))
        .collect()
}

/// The meaning of the coefficients, for file metadata.
pub const RADIOMETRY: &str = "exit radiance L_o = sum_k l_k t_k per channel, \
l_k = integral L_in(w) y_k(w) dw, t_k = (albedo/pi) integral V(w) max(0, n.w) y_k(w) dw";

/// RGB transfer from albedo-free scalar transfer: channel c of vertex v is albedo[v][c] times it.
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
