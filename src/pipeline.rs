//! A bake from its spec to its file: the transfer (`bake`), then the stages that shape what is
//! stored — bands chosen, clustered PCA, half-float rounding — then the writer the container
//! asks for; or, where the spec's mode is local, the local-lights bake (`local`) and its file.
//! The command line, library callers and `merge` all run it, so a stage that exists for one of
//! them exists for all.

use std::path::Path;
use std::time::Instant;

use glam::Vec3;

use crate::bake::subsurface::SceneMedia;
use crate::bake::{self, Backend, BakeOptions, BakeReport, BakedMesh, DirectSource, Progress};
use crate::compress::{self, Cpca};
use crate::device::GpuContext;
use crate::error::Error;
use crate::local::{self, LocalBake, LocalReport};
use crate::precision::Precision;
use crate::probes::{self, ProbeSet};
use crate::receivers::uv_set::{self, UvSet};
use crate::scene::gltf::volume::scattering_volumes;
use crate::scene::gltf::GltfScene;
use crate::scene::Scene;
use crate::spec::{BakeSpec, Bands, Compression, Container};
use crate::zonal::{ZonalFit, ZonalTransfer};
use crate::{glb, light, render, Result};

mod memory;
mod shape;

pub use memory::{local_memory_need, memory_need, plan_memory, plan_merge_memory, MemoryPlan};
use shape::{choose_auto_bands, compress_transfer, half_float_cost, HalfFloatTally};
pub use shape::{BandsChosen, Compressed, HalfFloatCost};

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

/// What a bake made, by its mode: SH transfer shaped as its spec stores it, or, for lights
/// inside the scene, depth maps and a direct-to-indirect operator ([`local::bake_local`]).
pub enum Bake {
    Transfer(Box<Baked>),
    Local(Box<LocalBaked>),
}

/// A local-lights bake and what it did.
pub struct LocalBaked {
    pub bake: LocalBake,
    pub report: LocalReport,
}

impl Bake {
    /// The SH transfer, or why there is none: a local-lights bake computes none.
    pub fn into_transfer(self) -> Result<Baked> {
        match self {
            Bake::Transfer(baked) => Ok(*baked),
            Bake::Local(_) => Err(Error::Options(
                "the spec's mode is local: its bake is depth maps and an operator, not SH \
                 transfer"
                    .into(),
            )),
        }
    }

    /// The SH transfer, where the bake is one.
    pub fn transfer(&self) -> Option<&Baked> {
        match self {
            Bake::Transfer(baked) => Some(baked),
            Bake::Local(_) => None,
        }
    }

    /// The local-lights bake, or why there is none: an SH transfer bake is not one.
    pub fn into_local(self) -> Result<LocalBaked> {
        match self {
            Bake::Local(baked) => Ok(*baked),
            Bake::Transfer(baked) => Err(Error::Options(format!(
                "the spec's mode is {}: its bake is SH transfer, not local lights",
                baked.mesh.metadata.mode.name()
            ))),
        }
    }
}

/// Bakes `scene` as `spec` asks, its direct pass from `source`, on `backend`; `gltf` is the
/// document of a glTF scene (`scene` as `gltf::load` made it), which a spec whose container is
/// the scene in place needs. Every mode runs here, local lights too. ([`plan`], then
/// [`Planned::run`].)
pub fn run(
    spec: &BakeSpec,
    scene: Scene,
    gltf: Option<&GltfScene>,
    backend: &dyn Backend,
    source: DirectSource,
    progress: &dyn Progress,
) -> Result<Bake> {
    plan(spec, scene, gltf)?.run(backend, source, progress)
}

/// Bakes `scene` for local lights (`options`, the spec's local section): the gather matrix,
/// depth maps and the compressed direct-to-indirect operator, the spec's albedo replacing the
/// materials' where it gives one. Its direct pass is its own: a sharded bake's is SH transfer.
fn bake_local(
    (spec, options): (&BakeSpec, &local::LocalOptions),
    mut scene: Scene,
    backend: &dyn Backend,
    source: DirectSource,
    progress: &dyn Progress,
) -> Result<Bake> {
    if let DirectSource::Given(_) = source {
        return Err(Error::Options(
            "a local-lights bake computes its own light; a merged direct pass is SH transfer"
                .into(),
        ));
    }
    if let Some(albedo) = spec.transfer.albedo {
        scene
            .albedo
            .iter_mut()
            .for_each(|a| *a = Vec3::from(albedo));
    }
    let (bake, report) = local::bake_local(scene, options, backend, progress)?;
    Ok(Bake::Local(Box::new(LocalBaked { bake, report })))
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

    /// Bakes it: the transfer, then the stages that shape what is stored; or, for local
    /// lights, their depth maps and operator.
    pub fn run(
        self,
        backend: &dyn Backend,
        source: DirectSource,
        progress: &dyn Progress,
    ) -> Result<Bake> {
        if let Some(options) = &self.spec.local {
            return bake_local((self.spec, options), self.scene, backend, source, progress);
        }
        self.run_transfer(backend, source, progress)
            .map(|baked| Bake::Transfer(Box::new(baked)))
    }

    /// The SH transfer bake.
    fn run_transfer(
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
    /// `preview`, the radiance the preview draws is summed chunk by chunk. The direct pass comes
    /// from `source`: cast on `backend`, or given (a merge's parts), read a chunk at a time.
    pub fn run_streamed(
        self,
        (backend, source): (&dyn Backend, DirectSource),
        chunk: usize,
        (path, gltf): (&Path, Option<&GltfScene>),
        preview: bool,
        progress: &dyn Progress,
    ) -> Result<Streamed> {
        check_container(self.spec, gltf)?;
        let streamed = streamed_bake(self.scene, self.spec, source)?;
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

/// The streamed bake of `scene` as `spec` asks, its direct pass from `source`.
fn streamed_bake(
    scene: Scene,
    spec: &BakeSpec,
    source: DirectSource,
) -> Result<bake::stream::StreamedBake> {
    let streamed = bake::stream::StreamedBake::plan(scene, &spec.options())?;
    match source {
        DirectSource::Compute => Ok(streamed),
        DirectSource::Given(given) => streamed.with_given(given),
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

/// Writes `bake` to `path` in the spec's container: a baked mesh, or `gltf` written back with
/// its transfer (what that repaired and copied is returned); a local-lights bake to its own
/// file (`glb::local`). The lightmap, if any, goes beside the file.
pub fn write(
    spec: &BakeSpec,
    bake: &Bake,
    gltf: Option<&GltfScene>,
    path: &Path,
) -> Result<Option<glb::scene::SceneWrite>> {
    check_container(spec, gltf)?;
    let baked = match bake {
        Bake::Transfer(baked) => baked,
        Bake::Local(local) => {
            glb::local::write_local_glb(path, &local.bake)?;
            return Ok(None);
        }
    };
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
