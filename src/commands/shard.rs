//! `prt-gpu bake --shard I/N` and `prt-gpu merge`: a bake in parts, joined byte for byte.

use std::path::{Path, PathBuf};

use prt_gpu::bake::gpu::{Chunking, GpuBaker};
use prt_gpu::bake::{self, backend_for, Backend, BakeOptions, CpuBackend, Mode};
use prt_gpu::device::{self, DeviceChoice};
use prt_gpu::shard::{self, Part};
use prt_gpu::spec::BakeSpec;
use prt_gpu::{fs, pipeline, scene, Error, Result};

use super::bake::{
    bake_name, bake_one, bake_spec, check_chunking, check_preview, load_bake_input, mesh_shown,
    naming_the_mesh, note_samples_rounded, open_backend, BakeArgs, Device, Execution,
};
use super::progress::BarProgress;

#[derive(clap::Args)]
pub(crate) struct MergeArgs {
    /// Part files written by `prt-gpu bake … --shard I/N`, in any order, one per shard.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output file (.glb). Default: <mesh name>.prt.glb in the current directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Also render a preview of the result under a default sky and sun (.png or .exr).
    #[arg(long)]
    preview: Option<PathBuf>,
    /// Most memory the merge may use, e.g. 512M or 8G (binary units): a merge at the vertices
    /// that would need more streams, its parts read a chunk at a time, and a lightmap holds its
    /// texels in a scratch file; a least-squares fit's merge is refused below its need.
    #[arg(long, value_name = "SIZE", value_parser = super::args::parse_size)]
    memory_limit: Option<u64>,
}

/// `bake … --shard I/N`: the direct pass of one shard's receivers, written as a part file.
pub(crate) fn run_shard(args: &BakeArgs, mesh: &Option<PathBuf>, shard: bake::Shard) -> Result<()> {
    let spec = bake_spec(args, mesh)?;
    spec.validate()?;
    let options = spec.options();
    if args.preview.is_some() {
        return Err(Error::Options(
            "--preview renders a whole bake: give it to `prt-gpu merge`, not to a shard".into(),
        ));
    }
    let output = args.output.clone().unwrap_or_else(|| {
        PathBuf::from(format!(
            "{}.prt.{}-of-{}.part",
            bake_name(&spec, mesh),
            shard.index,
            shard.count
        ))
    });
    check_part_output(mesh, &output)?;
    let (scene, _, name) = load_bake_input(&spec, mesh)?;
    check_shard_memory(args, &spec, &scene, shard)?;
    note_samples_rounded(&options);
    check_chunking(args)?;
    let fingerprint = shard::fingerprint(&scene, &spec.fingerprint_text());
    let baker = open_backend(args.device, args.adapter.as_deref())?;
    let backend = backend_for(baker.as_ref(), Execution::of(args).chunking);
    let progress = BarProgress::default();
    let started = std::time::Instant::now();
    let pass = bake::bake_shard(scene, &options, backend.as_ref(), shard, &progress)
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
        (spec, mesh.clone()),
        fingerprint,
        (command, directory),
    );
    shard::write_part(&output, &part)?;
    if range.is_empty() {
        eprintln!(
            "note: shard {}/{} holds none of the {total} receivers (more shards than \
             receivers); its part is still one the merge needs",
            shard.index, shard.count
        );
    }
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

/// A shard's part file, checked before any work: not the mesh, named `.part`, in a directory
/// that exists.
fn check_part_output(mesh: &Option<PathBuf>, output: &Path) -> Result<()> {
    let part = fs::Output {
        option: "-o",
        path: output,
    };
    let inputs: Vec<&Path> = mesh.iter().map(PathBuf::as_path).collect();
    fs::check_output(
        part,
        &inputs,
        &[shard::PART_EXTENSION],
        "a shard is written as a part file for `prt-gpu merge`",
    )
}

/// `merge`: the parts checked, then the rest of the bake their command asks for, their direct
/// pass read from them whole or, streamed, a chunk at a time.
pub(crate) fn run_merge(args: MergeArgs) -> Result<()> {
    check_merge_outputs(&args)?;
    let parts = shard::PartSet::read(&args.parts)?;
    if let Some(differences) = parts.command_differences() {
        eprintln!("warning: {differences}");
    }
    let header = parts.header();
    let spec: BakeSpec = header.spec.clone();
    let mesh = header.mesh.as_ref().map(|mesh| header.directory.join(mesh));
    let execution = Execution {
        preview: args.preview,
        memory_limit: args.memory_limit,
        chunking: Chunking::default(),
    };
    let backend = header.backend.clone();
    let options = spec.options();
    let device = Device::new(|| merge_backend(&options, &backend));
    let progress = BarProgress::default();
    let merged = Some(parts);
    bake_one(
        &spec,
        &execution,
        &mesh,
        args.output,
        &device,
        merged,
        &progress,
    )
}

/// What `merge` was told to write, checked before any part is read: neither is a part, nor the
/// other; `-o` names a .glb and `--preview` an image, in directories that exist. (The mesh the
/// parts name is checked against them once the parts are read, as every bake checks it.)
fn check_merge_outputs(args: &MergeArgs) -> Result<()> {
    let mut outputs = Vec::new();
    if let Some(output) = &args.output {
        outputs.push(fs::Output {
            option: "-o",
            path: output,
        });
    }
    if let Some(preview) = &args.preview {
        outputs.push(fs::Output {
            option: "--preview",
            path: preview,
        });
    }
    let parts: Vec<&Path> = args.parts.iter().map(PathBuf::as_path).collect();
    fs::check_outputs(&outputs, &parts)?;
    if let Some(output) = &args.output {
        let glb = fs::Output {
            option: "-o",
            path: output,
        };
        fs::check_extension(glb, &["glb"], "a merge is written as binary glTF")?;
        fs::check_destination(output)?;
    }
    if let Some(preview) = &args.preview {
        check_preview(preview)?;
    }
    Ok(())
}

/// A shard is not streamed: its share of the receivers and the mesh must fit at once. Over an
/// explicit `--memory-limit` it is refused, naming the fewest shards that would fit; over the
/// memory this machine has, it goes ahead with a warning.
fn check_shard_memory(
    args: &BakeArgs,
    spec: &BakeSpec,
    scene: &scene::Scene,
    shard: bake::Shard,
) -> Result<()> {
    use bake::stream::format_bytes;
    let need = pipeline::memory_need(spec, (scene, None));
    let Some(limit) = args.memory_limit.or_else(device::available_memory) else {
        return Ok(());
    };
    let shard_need = need.shard(shard.count);
    if shard_need <= limit {
        return Ok(());
    }
    let advice = match need.shards_within(limit) {
        Some(count) => format!("{count} or more shards would each fit"),
        None => format!(
            "a shard of one receiver needs about {} (the mesh and its BVH, and a fit's \
             points), so no shard count fits",
            format_bytes(need.shard(u32::MAX))
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

/// The device a merge runs the rest of the bake on: the CPU for parts baked there; a GPU for
/// parts baked on one, where bounces or texels run on it (so that the bytes match).
fn merge_backend(options: &BakeOptions, parts_backend: &str) -> Result<Option<GpuBaker>> {
    let needs_device = options.mode == Mode::Interreflected || options.lightmap.is_some();
    if parts_backend == CpuBackend.describe() || !needs_device {
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
