//! `prt-gpu bake`: one mesh or a batch, for distant light or lights inside the scene. Arguments
//! become a spec ([`bake_spec`]), the pipeline bakes it ([`bake_one`]), the report is printed:
//! the arguments in `args.rs`, the spec they ask for in `spec_args.rs`, the device in
//! `backend.rs`, the files read and written in `files.rs`, the printed lines in `report.rs`,
//! batches in `batch.rs`.

use std::path::{Path, PathBuf};

use glam::Vec3;

use super::args::{
    parse_compression, parse_cpca_shape, parse_rgb, parse_shard, parse_size, Bands, TransferArgs,
};
use super::progress::{batch_bar, BarProgress};
use prt_gpu::bake::adaptive::TargetError;
use prt_gpu::bake::gpu::{Chunking, GpuBaker};
use prt_gpu::bake::{self, backend_for, BakeOptions, BakeReport, Fit, Storage};
use prt_gpu::device::{self, DeviceChoice, GpuContext};
use prt_gpu::local::build::OperatorShape;
use prt_gpu::local::{self, LocalOptions};
use prt_gpu::precision::Precision;
use prt_gpu::probes::ProbeForm;
use prt_gpu::receivers::PointDensity;
use prt_gpu::render::{self, ToneMap};
use prt_gpu::shard;
use prt_gpu::spec::{
    self, BakeSpec, Compression, Container, Layout, ReceiverSpec, StorageSpec, TransferSpec,
};
use prt_gpu::{fs, glb, light, pipeline, scene, Error, Result};

mod args;
mod backend;
mod batch;
mod files;
mod report;
mod spec_args;

// The command's parts, one step each; the other commands use them too.
pub(crate) use args::*;
pub(crate) use backend::*;
pub(crate) use batch::*;
pub(crate) use files::*;
pub(crate) use report::*;
pub(crate) use spec_args::*;

/// One mesh (or the built-in scene) baked to one file.
pub(crate) fn run_one(args: &BakeArgs, mesh: Option<PathBuf>) -> Result<()> {
    let spec = bake_spec(args, &mesh)?;
    spec.validate()?;
    check_chunking(args)?;
    let device = Device::new(|| open_backend(args.device, args.adapter.as_deref()));
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

/// Where the direct pass comes from: computed here, or the merged parts' (whose fingerprint
/// must be this mesh's and spec's), read as the bake needs them.
fn direct_source(
    spec: &BakeSpec,
    scene: &scene::Scene,
    mesh: &Option<PathBuf>,
    merged: Option<shard::PartSet>,
) -> Result<bake::DirectSource> {
    let Some(parts) = merged else {
        return Ok(bake::DirectSource::Compute);
    };
    if shard::fingerprint(scene, &spec.fingerprint_text()) != parts.header().fingerprint {
        return Err(Error::Merge(format!(
            "{} is not the mesh the parts were baked from (it changed since)",
            mesh_shown(mesh)
        )));
    }
    Ok(bake::DirectSource::Given(Box::new(parts)))
}

/// How the bake fits its memory (`pipeline::plan_memory`; a merge's, whose direct pass its
/// parts give, `pipeline::plan_merge_memory`), its note or warning printed.
fn memory_plan(
    spec: &BakeSpec,
    (planned, gltf): (&pipeline::Planned, Option<&prt_gpu::scene::gltf::GltfScene>),
    execution: &Execution,
    merging: Option<&shard::PartSet>,
) -> Result<pipeline::MemoryPlan> {
    let available = device::available_memory();
    let limit = execution.memory_limit;
    let scene_and_document = (planned.scene(), gltf);
    let plan = match merging {
        Some(parts) => {
            let part = parts.largest_part_bytes();
            pipeline::plan_merge_memory(spec, scene_and_document, part, limit, available)?
        }
        None => pipeline::plan_memory(spec, scene_and_document, limit, available)?,
    };
    if let Some(message) = &plan.message {
        eprintln!("{message}");
    }
    Ok(plan)
}

/// One bake of `mesh` to `output` as `spec` says, in any mode, its direct pass computed on the
/// device (the CPU without one) or, merging, joined from the parts of a sharded bake of the same
/// mesh and spec.
pub(crate) fn bake_one(
    spec: &BakeSpec,
    execution: &Execution,
    mesh: &Option<PathBuf>,
    output: Option<PathBuf>,
    device: &Device,
    merged: Option<shard::PartSet>,
    progress: &BarProgress,
) -> Result<()> {
    spec.validate()?;
    let output_path = output.unwrap_or_else(|| default_output(spec, mesh));
    // Fail before the long part (and before reading the mesh), not after it.
    check_bake_outputs(spec, execution.preview.as_deref(), mesh, &output_path, &[])?;
    let loading = std::time::Instant::now();
    let (scene, gltf, name) = load_bake_input(spec, mesh)?;
    let seconds_load = loading.elapsed().as_secs_f64();
    let naming = |e| naming_the_mesh(e, &mesh_shown(mesh));
    let mut planned = pipeline::plan(spec, scene, gltf.as_ref()).map_err(naming)?;
    if spec.local.is_none() {
        note_samples_rounded(&spec.options());
    }
    let plan = memory_plan(spec, (&planned, gltf.as_ref()), execution, merged.as_ref())?;
    let baker = device.get()?;
    let backend = backend_for(baker.as_ref(), execution.chunking);
    if let Some(chunk) = plan.point_chunk {
        planned = planned.with_point_chunk(chunk);
    }
    if let Some(groups) = plan.texel_groups {
        planned = planned.with_texel_groups(groups);
    }
    let merged_from = merged
        .as_ref()
        .map(|parts| (parts.header().shard_count, parts.header().backend.clone()));
    let source = direct_source(spec, planned.scene(), mesh, merged)?;
    if let Some(chunk) = plan.chunk {
        let preview = execution.preview.is_some();
        let streamed = planned
            .run_streamed(
                (backend.as_ref(), source),
                chunk,
                (&output_path, gltf.as_ref()),
                preview,
                progress,
            )
            .map_err(naming)?;
        progress.finish();
        let said = (name.as_str(), seconds_load);
        report_streamed(
            spec,
            (execution, merged_from),
            &streamed,
            (&output_path, baker.as_ref()),
            said,
        )?;
        return Ok(());
    }
    let bake = planned
        .run(backend.as_ref(), source, progress)
        .map_err(naming)?;
    progress.finish();
    let baked = match &bake {
        pipeline::Bake::Transfer(baked) => baked,
        pipeline::Bake::Local(local) => {
            pipeline::write(spec, &bake, None, &output_path)?;
            print_local_report(&name, local, &output_path);
            return Ok(());
        }
    };
    print_shaping_lines(baked);
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
    let written = pipeline::write(spec, &bake, gltf.as_ref(), &output_path)?;
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
    let bands = baked.mesh.transfer.bands();
    print_bake_report(&name, spec, bands, &baked.report, &output_path, merged_from);
    Ok(())
}

/// What a streamed bake (of merged parts, where `merged_from` says) says when it is done, and
/// its preview drawn (the file removed where the preview cannot be made, as a whole bake leaves
/// none).
fn report_streamed(
    spec: &BakeSpec,
    (execution, merged_from): (&Execution, Option<(u32, String)>),
    streamed: &pipeline::Streamed,
    (output_path, baker): (&Path, Option<&GpuBaker>),
    (name, seconds_load): (&str, f64),
) -> Result<()> {
    if let Some(chosen) = &streamed.bands_chosen {
        eprintln!("{chosen}");
    }
    for note in &streamed.notes {
        eprintln!("note: {note}");
    }
    if let Some(compressed) = &streamed.compressed {
        eprintln!("{compressed}");
    }
    if let Some(cost) = &streamed.half_float {
        eprintln!("{cost}");
    }
    if let Some(fit) = &streamed.zonal {
        eprintln!("{fit}");
    }
    print_probes_line(streamed.probes.as_ref(), streamed.probe_seconds);
    if let (Some(path), Some((scene, radiance))) = (&execution.preview, &streamed.preview) {
        let image = match baker {
            Some(baker) => render_radiance_preview(&baker.context, scene, radiance),
            None => open_render_device(None)
                .and_then(|context| render_radiance_preview(&context, scene, radiance)),
        };
        // A bake is whole or not at all: no file without the preview asked for.
        let image = image.inspect_err(|_| {
            let _ = std::fs::remove_file(output_path);
        })?;
        write_preview_or_undo(path, &image, output_path, false)?;
    }
    if let Some((written, seconds_write)) = &streamed.scene_write {
        print_in_place_report(written, seconds_load, *seconds_write);
    }
    let report = &streamed.report;
    let bands = streamed
        .bands_chosen
        .map_or(spec.options().bands, |chosen| chosen.bands);
    print_bake_report(name, spec, bands, report, output_path, merged_from);
    Ok(())
}
