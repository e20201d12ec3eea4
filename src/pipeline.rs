//! A bake from its spec to its file: the transfer (`bake`), then the stages that shape what is
//! stored — bands chosen, clustered PCA, half-float rounding — then the writer the container
//! asks for. The command line, library callers and `merge` all run it, so a stage that exists
//! for one of them exists for all.

use std::fmt;
use std::path::Path;
use std::time::Instant;

use crate::bake::{self, Backend, BakeReport, BakedMesh, DirectSource, Progress};
use crate::compress::{self, Cpca, CpcaOptions};
use crate::device::GpuContext;
use crate::precision::Precision;
use crate::scene::gltf::GltfScene;
use crate::scene::Scene;
use crate::spec::{BakeSpec, Bands, Compression, AUTO_MAX_BANDS};
use crate::{glb, light, render, Result};

/// A bake done and shaped as its spec stores it, not yet written.
pub struct Baked {
    pub mesh: BakedMesh,
    /// The compressed transfer, rounded as the file stores it, when the spec compresses.
    pub cpca: Option<Cpca>,
    pub report: BakeReport,
    /// The bands `--bands auto` chose.
    pub bands_chosen: Option<BandsChosen>,
    pub compressed: Option<Compressed>,
    /// What storing per-vertex transfer as half floats costs.
    pub half_float: Option<HalfFloatCost>,
    /// Side notes of the stages (where a stage ran and why), one line each.
    pub notes: Vec<String>,
}

/// Bakes `scene` as `spec` asks, its direct pass from `source`, on `backend`.
pub fn run(
    spec: &BakeSpec,
    scene: Scene,
    backend: &Backend,
    source: DirectSource,
    progress: &dyn Progress,
) -> Result<Baked> {
    spec.validate()?;
    let (mut mesh, report) = bake::bake_from(scene, &spec.options(), backend, source, progress)?;
    let bands_chosen = match spec.transfer.bands {
        Bands::Auto { threshold } => Some(choose_auto_bands(&mut mesh, threshold)),
        Bands::Fixed(_) => None,
    };
    let mut notes = Vec::new();
    let compressed = match spec.compression() {
        Some(compression) => Some(compress_transfer(
            &mesh,
            compression,
            spec.storage.precision,
            gpu_context(backend),
            &mut notes,
        )?),
        None => None,
    };
    let half_float = match (spec.storage.precision, &compressed) {
        (Precision::F16, None) => Some(half_float_cost(&mesh)?),
        _ => None,
    };
    let (cpca, compressed) = compressed.unzip();
    Ok(Baked {
        mesh,
        cpca,
        report,
        bands_chosen,
        compressed,
        half_float,
        notes,
    })
}

/// Writes `baked` to `path` in the spec's container: a baked mesh, or `gltf` written back with
/// its transfer (what that repaired and copied is returned).
pub fn write(
    spec: &BakeSpec,
    baked: &Baked,
    gltf: Option<&GltfScene>,
    path: &Path,
) -> Result<Option<glb::scene::SceneWrite>> {
    match gltf {
        Some(gltf) => Ok(Some(glb::scene::write_scene_glb(
            path,
            gltf,
            &baked.mesh,
            &baked.report.vertex_map,
            spec.storage.precision,
        )?)),
        None => {
            glb::write_glb_as(
                path,
                &baked.mesh,
                baked.cpca.as_ref(),
                spec.storage.precision,
            )?;
            Ok(None)
        }
    }
}

/// The device of a GPU backend, for stages that can use it.
fn gpu_context<'a>(backend: &Backend<'a>) -> Option<&'a GpuContext> {
    match backend {
        Backend::Gpu { baker, .. } => Some(&baker.context),
        Backend::Cpu => None,
    }
}

/// What `--bands auto` chose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BandsChosen {
    pub bands: u32,
    /// The fraction of the transfer's energy in the bands left out.
    pub beyond: f64,
    pub threshold: f64,
}

impl fmt::Display for BandsChosen {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        let BandsChosen {
            bands,
            beyond,
            threshold,
        } = *self;
        write!(
            f,
            "bands auto: {bands} ({:.2}% of the transfer's energy lies in bands {bands} to {}, \
             below --bands-threshold {threshold})",
            100.0 * beyond,
            AUTO_MAX_BANDS - 1,
        )
    }
}

/// `--bands auto`: the baked mesh cut to the bands the threshold asks for.
fn choose_auto_bands(baked: &mut BakedMesh, threshold: f64) -> BandsChosen {
    let (bands, beyond) = bake::choose_bands(&baked.transfer, threshold);
    bake::truncate_baked(baked, bands);
    BandsChosen {
        bands,
        beyond,
        threshold,
    }
}

/// What clustered PCA made of the transfer: its shape, where and how fast it ran, the sizes
/// and the errors of the stored form.
#[derive(Clone, Debug, PartialEq)]
pub struct Compressed {
    pub clusters: u32,
    pub components: u32,
    pub seconds: f64,
    pub ran_on: String,
    pub precision: Precision,
    pub bytes: usize,
    pub bytes_uncompressed: usize,
    pub coefficient_error: f64,
    /// Under the preview light.
    pub relit_error: f64,
}

impl fmt::Display for Compressed {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        let half = match self.precision {
            Precision::F32 => "",
            Precision::F16 => " as half floats",
        };
        write!(
            f,
            "compressed: {} clusters x {} components in {:.2} s ({}), {} bytes{half} of {} \
             ({:.1}x smaller); coefficient error {:.2}%, relit error {:.2}% under the preview \
             light",
            self.clusters,
            self.components,
            self.seconds,
            self.ran_on,
            self.bytes,
            self.bytes_uncompressed,
            self.bytes_uncompressed as f64 / self.bytes as f64,
            100.0 * self.coefficient_error,
            100.0 * self.relit_error
        )
    }
}

/// The baked transfer compressed as `compression` asks and rounded as a file at `precision`
/// stores it. The assignment steps run on `gpu` where it pays
/// (`GpuAssigner::where_it_pays`; where it does not for a reason, a note says so).
fn compress_transfer(
    baked: &BakedMesh,
    compression: Compression,
    precision: Precision,
    gpu: Option<&GpuContext>,
    notes: &mut Vec<String>,
) -> Result<(Cpca, Compressed)> {
    let started = Instant::now();
    let transfer = &baked.transfer;
    let points = compress::Points {
        data: &transfer.coeffs,
        dimension: transfer.channels as usize * transfer.coeffs_per_channel(),
    };
    let most_components = match compression {
        Compression::Shape { components, .. } => components as usize,
        Compression::Target { .. } => points.dimension,
    };
    let gpu_assigner = match gpu {
        Some(context) => {
            let (assigner, why_not) =
                compress::gpu::GpuAssigner::where_it_pays(context, points, most_components)?;
            if let Some(why) = why_not {
                notes.push(format!("{why}; clustering on the CPU"));
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
        Compression::Shape {
            clusters,
            components,
        } => {
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
        Compression::Target { error } => {
            compress::choose_with(transfer, error, CpcaOptions::default().seed, assigner)?
        }
    };
    let cpca = cpca.rounded(precision);
    let seconds = started.elapsed().as_secs_f64();
    let light = light::preview_light(transfer.bands)?;
    let compressed = Compressed {
        clusters: options.clusters,
        components: options.components,
        seconds,
        ran_on,
        precision,
        bytes: cpca.byte_size(precision),
        bytes_uncompressed: compress::uncompressed_bytes(transfer),
        coefficient_error: compress::relative_error(transfer, &cpca),
        relit_error: compress::relit_error(transfer, &cpca, &light)?,
    };
    Ok((cpca, compressed))
}

/// What storing per-vertex transfer as half floats costs: bytes, and the relit error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfFloatCost {
    pub bytes: usize,
    pub bytes_f32: usize,
    /// Under the preview light.
    pub relit_error: f64,
    /// The largest relative rounding of a coefficient of magnitude 1e-4 or more.
    pub worst_coefficient: f32,
}

impl fmt::Display for HalfFloatCost {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(
            f,
            "precision f16: transfer {} bytes instead of {}; relit error {:.1e} under the preview \
             light, worst coefficient {:.1e} relative (of those above 1e-4)",
            self.bytes, self.bytes_f32, self.relit_error, self.worst_coefficient
        )
    }
}

fn half_float_cost(baked: &BakedMesh) -> Result<HalfFloatCost> {
    let rounded = glb::rounded_to_f16(&baked.transfer);
    let light = light::preview_light(baked.transfer.bands)?;
    let exact = render::relight(&baked.transfer, &light)?;
    let stored = render::relight(&rounded, &light)?;
    let worst_coefficient = baked
        .transfer
        .coeffs
        .iter()
        .zip(&rounded.coeffs)
        .filter(|(x, _)| x.abs() >= 1e-4)
        .map(|(x, r)| ((r - x) / x).abs())
        .fold(0f32, f32::max);
    let values = baked.transfer.coeffs.len();
    Ok(HalfFloatCost {
        bytes: values * Precision::F16.bytes(),
        bytes_f32: values * Precision::F32.bytes(),
        relit_error: compress::radiance_error(&exact, &stored),
        worst_coefficient,
    })
}
