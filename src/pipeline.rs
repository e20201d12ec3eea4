//! A bake from its spec to its file: the transfer (`bake`), then the stages that shape what is
//! stored — bands chosen, clustered PCA, half-float rounding — then the writer the container
//! asks for. The command line, library callers and `merge` all run it, so a stage that exists
//! for one of them exists for all.

use std::fmt;
use std::path::Path;
use std::time::Instant;

use glam::Vec3;

use crate::bake::subsurface::SceneMedia;
use crate::bake::StagePosition;
use crate::bake::{self, Backend, BakeOptions, BakeReport, BakedMesh, DirectSource, Progress};
use crate::compress::{self, Cpca, CpcaOptions};
use crate::device::GpuContext;
use crate::error::Error;
use crate::local::{self, LocalBake, LocalReport};
use crate::precision::Precision;
use crate::probes::{self, ProbeSet};
use crate::receivers::uv_set::{self, UvSet};
use crate::scene::gltf::volume::scattering_volumes;
use crate::scene::gltf::GltfScene;
use crate::scene::Scene;
use crate::spec::{BakeSpec, Bands, Compression, Container, AUTO_MAX_BANDS};
use crate::zonal::{ZonalFit, ZonalTransfer};
use crate::{glb, light, render, Result};

mod memory;

pub use memory::{memory_need, plan_memory, plan_merge_memory, MemoryPlan};

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
    /// The probes the spec asks for, baked around the scene, and the seconds they took.
    pub probes: Option<ProbeSet>,
    pub probe_seconds: f64,
    /// The zonal transfer the spec asks for, fitted to the stored bands, and what it costs.
    pub zonal: Option<(ZonalTransfer, ZonalFit)>,
}

/// Bakes `scene` as `spec` asks, its direct pass from `source`, on `backend`; `gltf` is the
/// document of a glTF scene (`scene` as `gltf::load` made it), which a spec whose container is
/// the scene in place needs. ([`plan`], then [`Planned::run`].)
pub fn run(
    spec: &BakeSpec,
    scene: Scene,
    gltf: Option<&GltfScene>,
    backend: &dyn Backend,
    source: DirectSource,
    progress: &dyn Progress,
) -> Result<Baked> {
    plan(spec, scene, gltf)?.run(backend, source, progress)
}

/// Bakes `scene` for local lights as `spec` asks (its mode local): the gather matrix, depth
/// maps and the compressed direct-to-indirect operator of `local::bake_local`, on `backend`,
/// the spec's albedo replacing the materials' where it gives one. What it computes is not SH
/// transfer, so it has a run of its own and its own file (`glb::local`).
pub fn run_local(
    spec: &BakeSpec,
    mut scene: Scene,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<(LocalBake, LocalReport)> {
    spec.validate()?;
    let Some(options) = &spec.local else {
        return Err(Error::Options(format!(
            "the spec's mode is {}; local lights bake a spec whose mode is local",
            spec.transfer.mode.name()
        )));
    };
    if let Some(albedo) = spec.transfer.albedo {
        scene
            .albedo
            .iter_mut()
            .for_each(|a| *a = Vec3::from(albedo));
    }
    local::bake_local(scene, options, backend, progress)
}

/// A bake checked before any device is opened or ray cast: its spec valid and fit for its
/// container, its lightmap's UV set chosen.
pub struct Planned<'s> {
    spec: &'s BakeSpec,
    scene: Scene,
    uv_set: Option<UvSet>,
    /// The media of a glTF scene's translucent materials, where the spec bakes them.
    scene_media: Option<SceneMedia>,
    notes: Vec<String>,
    /// A least-squares fit's points baked this many at a time (a plan of [`plan_memory`]).
    point_chunk: Option<usize>,
    /// A lightmap's texels held in a scratch file (a plan of [`plan_memory`]).
    texel_groups: Option<bake::texels::TexelGroups>,
}

/// Checks the bake of `scene` as `spec` asks (see [`run`]) and chooses what it can before any
/// ray: a glTF scene's lightmap UV set.
pub fn plan<'s>(spec: &'s BakeSpec, scene: Scene, gltf: Option<&GltfScene>) -> Result<Planned<'s>> {
    spec.validate()?;
    if spec.local.is_some() {
        return Err(Error::Options(
            "a local-lights spec bakes through pipeline::run_local (depth maps and an operator, \
             not SH transfer)"
                .into(),
        ));
    }
    check_container(spec, gltf)?;
    let mut notes = Vec::new();
    let uv_set = match (spec.receivers.lightmap, gltf) {
        (Some(size), Some(gltf)) => {
            let named = spec.receivers.lightmap_uv;
            let (set, note) = uv_set::lightmap_set(gltf, &scene.triangles, named, size)?;
            notes.extend(note);
            Some(set)
        }
        _ => None,
    };
    let scene_media = gltf.and_then(|gltf| scene_media(spec, (&scene, gltf), &mut notes));
    Ok(Planned {
        spec,
        scene,
        uv_set,
        scene_media,
        notes,
        point_chunk: None,
        texel_groups: None,
    })
}

impl Planned<'_> {
    /// The scene to bake, as given.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The bake with its least-squares fit's points baked about `chunk` at a time (a plan of
    /// [`plan_memory`]): the same bytes in less memory.
    pub fn with_point_chunk(self, chunk: usize) -> Self {
        Planned {
            point_chunk: Some(chunk),
            ..self
        }
    }

    /// The bake with its lightmap's texels held in a scratch file and cleaned up a group of
    /// coefficients at a time (a plan of [`plan_memory`]): the same bytes in less memory.
    pub fn with_texel_groups(self, groups: bake::texels::TexelGroups) -> Self {
        Planned {
            texel_groups: Some(groups),
            ..self
        }
    }

    /// Bakes it: the transfer, then the stages that shape what is stored.
    pub fn run(
        self,
        backend: &dyn Backend,
        source: DirectSource,
        progress: &dyn Progress,
    ) -> Result<Baked> {
        let Planned {
            spec,
            scene,
            uv_set,
            scene_media,
            mut notes,
            point_chunk,
            texel_groups,
        } = self;
        let options = BakeOptions {
            scene_media,
            point_chunk,
            texel_groups,
            ..spec.options()
        };
        let (mut mesh, report) =
            bake::bake_from(scene, &options, backend, source, uv_set.as_ref(), progress)?;
        let bands_chosen = match spec.transfer.bands {
            Bands::Auto { threshold } => Some(choose_auto_bands(&mut mesh, threshold)),
            Bands::Fixed(_) => None,
        };
        let zonal = match spec.storage.zonal {
            Some(zonal) => {
                let normals = mesh.scene.normals.as_deref().unwrap_or_default();
                Some(crate::zonal::fit_and_measure(
                    &mesh.transfer,
                    normals,
                    zonal,
                )?)
            }
            None => None,
        };
        let probes_started = Instant::now();
        let probes = match &spec.probes {
            Some(probes) => {
                let sampling = (spec.transfer.samples, spec.transfer.seed);
                Some(probes::bake_probes(
                    &mesh, probes, sampling, backend, progress,
                )?)
            }
            None => None,
        };
        let probe_seconds = probes_started.elapsed().as_secs_f64();
        let compressed = match spec.compression() {
            Some(compression) => Some(compress_transfer(
                &mut compress::Points::of_transfer(&mesh.transfer),
                (mesh.transfer.bands(), mesh.transfer.channels()),
                (compression, spec.storage.precision),
                backend.gpu_context(),
                &mut notes,
                progress,
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
            probes,
            probe_seconds,
            zonal,
        })
    }

    /// Bakes it streamed to `path` in chunks of `chunk` receivers (a plan of [`plan_memory`]),
    /// `gltf` written in place where the container is the scene: the file equals the whole
    /// bake's, byte for byte, and so does what storing it as half floats costs. With
    /// `preview`, the radiance the preview draws is summed chunk by chunk.
    pub fn run_streamed(
        self,
        backend: &dyn Backend,
        chunk: usize,
        (path, gltf): (&Path, Option<&GltfScene>),
        preview: bool,
        progress: &dyn Progress,
    ) -> Result<Streamed> {
        check_container(self.spec, gltf)?;
        let streamed = bake::stream::StreamedBake::plan(self.scene, &self.spec.options())?;
        let precision = self.spec.storage.precision;
        // Compressed, what half floats cost is in the compression's errors.
        let tally_half_floats = precision == Precision::F16 && self.spec.compression().is_none();
        // Built at the first chunk, of its bands (with --bands auto, those chosen).
        let mut half_float: Option<HalfFloatTally> = None;
        let albedo_free = streamed.metadata(backend, 0).albedo_free;
        let mut previewed = PreviewTally {
            light: None,
            radiance: Vec::new(),
            albedo: albedo_free.then_some(&streamed.scene().albedo[..]),
        };
        let mut each_chunk = |transfer: &bake::Transfer| {
            if tally_half_floats {
                if half_float.is_none() {
                    half_float = Some(HalfFloatTally::new(transfer.bands())?);
                }
                half_float.as_mut().expect("built above").add(transfer)?;
            }
            match preview {
                true => previewed.add(transfer),
                false => Ok(()),
            }
        };
        let bands_auto = match self.spec.transfer.bands {
            Bands::Auto { threshold } => Some(threshold),
            Bands::Fixed(_) => None,
        };
        // Probes, once the transfer is known: an interreflected bake's exit light read back
        // from its scratch file a chunk at a time.
        let sampling = (self.spec.transfer.samples, self.spec.transfer.seed);
        let mut bake_probes = |interreflected: Option<&mut bake::stream::Interreflected>,
                               bands: u32| {
            let spec = self.spec.probes.as_ref().expect("asked for");
            let scene = streamed.scene();
            let exit = interreflected
                .map(|baked| probes::ExitLight::of_streamed(baked, scene, bands, chunk))
                .transpose()?;
            let around = (scene, bands, exit.as_ref());
            probes::bake_probes_around(around, spec, sampling, backend, progress)
        };
        let sink = glb::stream::StreamSink {
            path,
            scene: gltf,
            precision,
            bands_auto,
            each_chunk: &mut each_chunk,
            probes: match self.spec.probes {
                Some(_) => Some(&mut bake_probes),
                None => None,
            },
            zonal: self.spec.storage.zonal,
            compressed: self.spec.compression().is_some(),
        };
        let mut written = glb::stream::bake_streamed(&streamed, backend, chunk, sink, progress)?;
        let PreviewTally { radiance, .. } = previewed;
        let mut notes = self.notes;
        let (compressed, scene_write, scene) = match written.held.take() {
            Some(held) => {
                let compression = self.spec.compression().expect("held to be compressed");
                let (made, scene_write, scene) = compress_held(
                    held,
                    (compression, precision),
                    (streamed.into_scene(), written.probes.as_ref()),
                    (path, gltf, &written.report.vertex_map),
                    (backend.gpu_context(), &mut notes, progress),
                )?;
                (Some(made), scene_write, scene)
            }
            None => (None, written.scene_write.take(), streamed.into_scene()),
        };
        Ok(Streamed {
            report: written.report,
            scene_write,
            bands_chosen: written.bands_chosen.zip(bands_auto).map(
                |((bands, beyond), threshold)| BandsChosen {
                    bands,
                    beyond,
                    threshold,
                },
            ),
            half_float: half_float.map(|tally| tally.cost()),
            preview: preview.then_some((scene, radiance)),
            probes: written.probes,
            probe_seconds: written.probe_seconds,
            zonal: written.zonal,
            compressed,
            notes,
        })
    }
}

/// The radiance a streamed bake's preview draws, summed a chunk at a time: each vertex's under
/// the preview light, times its `albedo` where the transfer leaves the albedo out.
struct PreviewTally<'s> {
    /// Built at the first chunk, of its bands.
    light: Option<light::ShLight>,
    radiance: Vec<[f32; 3]>,
    albedo: Option<&'s [Vec3]>,
}

impl PreviewTally<'_> {
    /// Adds the next chunk's vertices.
    fn add(&mut self, transfer: &bake::Transfer) -> Result<()> {
        if self.light.is_none() {
            self.light = Some(light::preview_light(transfer.bands())?);
        }
        let first = self.radiance.len();
        let light = self.light.as_ref().expect("built above");
        let mut relit = render::relight(transfer, light)?;
        if let Some(albedo) = self.albedo {
            render::tint_by(&mut relit, &albedo[first..]);
        }
        self.radiance.extend(relit);
        Ok(())
    }
}

/// A streamed bake's `held` transfer compressed as `compression` asks (its rows read from the
/// scratch file a chunk at a time) and written at `precision` to `path` with the prepared
/// `scene` and its `probes`: a baked mesh, or `gltf` in place (`vertex_map` its vertices'
/// places). The bytes are those of the whole bake's file. Gives back what the compression
/// made, what writing a scene did with its seconds, and the scene.
fn compress_held(
    mut held: glb::stream::HeldTransfer,
    (compression, precision): (Compression, Precision),
    (scene, probes): (Scene, Option<&ProbeSet>),
    (path, gltf, vertex_map): (&Path, Option<&GltfScene>, &[u32]),
    (gpu, notes, progress): (Option<&GpuContext>, &mut Vec<String>, &dyn Progress),
) -> Result<(Compressed, SceneWritten, Scene)> {
    let (bands, channels) = held.shape();
    let shaping = (compression, precision);
    let (cpca, compressed) =
        compress_transfer(&mut held, (bands, channels), shaping, gpu, notes, progress)?;
    let baked = BakedMesh {
        scene,
        transfer: bake::Transfer::zeros(bands, channels, 0),
        metadata: held.metadata.clone(),
        lightmap: None,
    };
    let stored = glb::Stored::compressed(&baked, &cpca, precision)?
        .with_probes(probes)?
        .with_zonal(held.zonal.as_ref())?;
    let writing = Instant::now();
    let written = match gltf {
        Some(gltf) => {
            let write = glb::scene::write_scene_glb(path, gltf, stored, vertex_map)?;
            Some((write, writing.elapsed().as_secs_f64()))
        }
        None => {
            glb::write_glb(path, stored)?;
            None
        }
    };
    Ok((compressed, written, baked.scene))
}

/// What writing a glTF scene in place did, and its seconds (`None` for a baked mesh).
pub type SceneWritten = Option<(glb::scene::SceneWrite, f64)>;

/// What a streamed bake gives besides its file.
pub struct Streamed {
    pub report: BakeReport,
    /// What writing a glTF scene in place did, and its seconds.
    pub scene_write: SceneWritten,
    /// The bands `--bands auto` chose.
    pub bands_chosen: Option<BandsChosen>,
    pub half_float: Option<HalfFloatCost>,
    /// The prepared scene and its radiance at the vertices under the preview light (albedo
    /// applied), when asked for: what [`render::preview`] would draw of the whole bake.
    pub preview: Option<(Scene, Vec<[f32; 3]>)>,
    /// The probes in the file, and the seconds they took.
    pub probes: Option<ProbeSet>,
    pub probe_seconds: f64,
    /// What the zonal transfer's fit cost, when the file holds one.
    pub zonal: Option<ZonalFit>,
    /// What clustered PCA made of the transfer, where the file stores it compressed.
    pub compressed: Option<Compressed>,
    /// Side notes of the stages, one line each.
    pub notes: Vec<String>,
}

/// The media of `gltf`'s scattering volumes (`scene` as `gltf::load` made it), where `spec`
/// bakes subsurface transfer from them: not where `--subsurface` gives the whole scene one
/// medium or says `none`, nor in one channel (the materials' own media are then left out,
/// with a note). `notes` also get a line for each volume that describes no medium.
fn scene_media(
    spec: &BakeSpec,
    (scene, gltf): (&Scene, &GltfScene),
    notes: &mut Vec<String>,
) -> Option<SceneMedia> {
    let volumes = scattering_volumes(gltf, scene.vertex_count())?;
    notes.extend(volumes.notes.iter().cloned());
    let (media, opaque) = SceneMedia::of_volumes(&volumes);
    notes.extend(opaque);
    let media = media?;
    let why_not = if spec.transfer.subsurface.is_some() {
        Some("--subsurface puts the whole scene in its medium")
    } else if !spec.transfer.materials_scatter {
        Some("--subsurface none")
    } else if spec.storage.channels == bake::Storage::Lean {
        Some("--storage lean keeps one channel, and each colour scatters as far as its own")
    } else {
        None
    };
    let labels: Vec<&str> = volumes
        .volumes
        .iter()
        .filter(|v| media.media.iter().any(|m| m.material == v.material))
        .map(|v| v.label.as_str())
        .collect();
    match why_not {
        Some(why) => {
            let left = match spec.transfer.subsurface {
                Some(_) => ": their own media left out,",
                None => " baked opaque:",
            };
            notes.push(format!(
                "translucent material(s) {}{left} {why}",
                labels.join(", ")
            ));
            None
        }
        None => {
            notes.push(format!(
                "material(s) {} scatter light under the surface (KHR_materials_volume_scatter): \
                 baked with subsurface transfer",
                labels.join(", ")
            ));
            Some(media)
        }
    }
}

/// Refuses a container without what it needs: the scene in place needs its document, and a
/// mesh has none.
fn check_container(spec: &BakeSpec, gltf: Option<&GltfScene>) -> Result<()> {
    match (spec.container, gltf.is_some()) {
        (Container::GltfInPlace, false) => Err(Error::Options(
            "the spec writes a glTF scene in place, and no glTF scene was given".into(),
        )),
        (Container::Mesh, true) => Err(Error::Options(
            "the spec writes a baked mesh, and a glTF scene was given (its container is the \
             scene in place)"
                .into(),
        )),
        _ => Ok(()),
    }
}

/// Writes `baked` to `path` in the spec's container: a baked mesh, or `gltf` written back with
/// its transfer (what that repaired and copied is returned). The lightmap, if any, goes beside
/// the file.
pub fn write(
    spec: &BakeSpec,
    baked: &Baked,
    gltf: Option<&GltfScene>,
    path: &Path,
) -> Result<Option<glb::scene::SceneWrite>> {
    check_container(spec, gltf)?;
    let stored = glb::Stored::new(&baked.mesh, baked.cpca.as_ref(), spec.storage.precision)?
        .with_probes(baked.probes.as_ref())?
        .with_zonal(baked.zonal.as_ref().map(|(zonal, _)| zonal))?;
    match gltf {
        Some(gltf) => Ok(Some(glb::scene::write_scene_glb(
            path,
            gltf,
            stored,
            &baked.report.vertex_map,
        )?)),
        None => {
            glb::write_glb(path, stored)?;
            Ok(None)
        }
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

/// The baked transfer, rows of `(bands, channels)` read from `rows` (in memory, or a streamed
/// bake's scratch file), compressed as `compression` asks and rounded as a file at `precision`
/// stores it. The assignment steps run on `gpu` where it pays
/// (`GpuAssigner::where_it_pays`; where it does not for a reason, a note says so). A search
/// for the shape that meets an error is a stage, a step a shape.
fn compress_transfer(
    rows: &mut dyn compress::Rows,
    (bands, channels): (u32, u32),
    (compression, precision): (Compression, Precision),
    gpu: Option<&GpuContext>,
    notes: &mut Vec<String>,
    progress: &dyn Progress,
) -> Result<(Cpca, Compressed)> {
    let started = Instant::now();
    let (dimension, vertices) = (rows.dimension(), rows.len());
    let most_components = match compression {
        Compression::Shape { components, .. } => components as usize,
        Compression::Target { .. } => dimension,
    };
    let gpu_assigner = match gpu {
        Some(context) => {
            let (assigner, why_not) =
                compress::gpu::GpuAssigner::where_it_pays(context, rows, most_components)?;
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
            progress.stage("compress", compress::compress_steps(&options));
            let mut position = StagePosition::new(progress);
            let watch = &mut |step: u64| position.move_to(step);
            let shape = (bands, channels);
            let cpca = compress::compress_watched(rows, shape, &options, (assigner, watch))?;
            (cpca, options)
        }
        Compression::Target { error } => {
            let steps = compress::choose_steps(dimension, vertices);
            progress.stage("compress", steps as u64);
            let mut position = StagePosition::new(progress);
            let trying = &mut |step: usize, options: &CpcaOptions| {
                position.move_to(step as u64);
                let (k, m) = (options.clusters, options.components);
                progress.detail(&format!("({k} clusters x {m} components)"));
            };
            let seed = CpcaOptions::default().seed;
            let searching = (seed, assigner);
            compress::choose_from(rows, (bands, channels), error, searching, trying)?
        }
    };
    let cpca = cpca.rounded(precision);
    let seconds = started.elapsed().as_secs_f64();
    let light = light::preview_light(bands)?;
    let compressed = Compressed {
        clusters: options.clusters,
        components: options.components,
        seconds,
        ran_on,
        precision,
        bytes: cpca.byte_size(precision),
        bytes_uncompressed: compress::uncompressed_bytes(rows),
        coefficient_error: compress::relative_error_of(rows, &cpca)?,
        relit_error: compress::relit_error_of(rows, channels, &cpca, &light)?,
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
    let mut tally = HalfFloatTally::new(baked.transfer.bands())?;
    tally.add(&baked.transfer)?;
    Ok(tally.cost())
}

/// [`HalfFloatCost`] summed over runs of vertices in order: the whole transfer at once, or the
/// chunks of a streamed bake, give the same figures.
struct HalfFloatTally {
    light: light::ShLight,
    relit: compress::RelativeRms,
    worst_coefficient: f32,
    values: usize,
}

impl HalfFloatTally {
    fn new(bands: u32) -> Result<HalfFloatTally> {
        Ok(HalfFloatTally {
            light: light::preview_light(bands)?,
            relit: compress::RelativeRms::default(),
            worst_coefficient: 0.0,
            values: 0,
        })
    }

    fn add(&mut self, transfer: &bake::Transfer) -> Result<()> {
        let rounded = glb::rounded_to_f16(transfer);
        let exact = render::relight(transfer, &self.light)?;
        let stored = render::relight(&rounded, &self.light)?;
        self.relit.add_radiance(&exact, &stored);
        self.worst_coefficient = transfer
            .coeffs()
            .iter()
            .zip(rounded.coeffs())
            .filter(|(x, _)| x.abs() >= 1e-4)
            .map(|(x, r)| ((r - x) / x).abs())
            .fold(self.worst_coefficient, f32::max);
        self.values += transfer.coeffs().len();
        Ok(())
    }

    fn cost(&self) -> HalfFloatCost {
        HalfFloatCost {
            bytes: self.values * Precision::F16.bytes(),
            bytes_f32: self.values * Precision::F32.bytes(),
            relit_error: self.relit.value(),
            worst_coefficient: self.worst_coefficient,
        }
    }
}
