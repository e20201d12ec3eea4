//! `prt-gpu bake --mode local`: direct-to-indirect transfer for lights inside the scene.

use std::path::{Path, PathBuf};

use super::bake::{
    bake_spec, check_bake_outputs, load_mesh, open_backend, run_batch, stem, BakeArgs, Device,
    MeshBake,
};
use super::progress::BarProgress;
use prt_gpu::bake::backend_for;
use prt_gpu::bake::gpu::Chunking;
use prt_gpu::bake::stream::format_bytes;
use prt_gpu::local::build::OperatorShape;
use prt_gpu::local::{self, LocalOptions};
use prt_gpu::spec::{BakeSpec, Container};
use prt_gpu::{glb, pipeline, scene, Error, Result};

pub(crate) fn run_local_bake(args: BakeArgs) -> Result<()> {
    check_local_flags(&args)?;
    let meshes = scene::batch::mesh_files(&args.meshes)?;
    if meshes.len() > 1 || args.out_dir.is_some() {
        return run_batch(&args, &meshes, &LocalBake { args: &args });
    }
    let mesh = meshes.first().cloned();
    let spec = local_spec(&args, &mesh)?;
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{}.prt.glb", local_name(&mesh))));
    let device = Device::new(|| open_backend(args.device, args.adapter.as_deref()));
    bake_local_one(&spec, &mesh, &output, &device, &BarProgress::default())
}

/// The spec of a local-lights bake of `mesh`: any mesh, a glTF scene's too, bakes for local
/// lights into a local-lights file.
fn local_spec(args: &BakeArgs, mesh: &Option<PathBuf>) -> Result<BakeSpec> {
    let spec = BakeSpec {
        container: Container::Mesh,
        local: Some(local_options(args)),
        ..bake_spec(args, mesh)?
    };
    spec.validate()?;
    Ok(spec)
}

/// `mesh` (the built-in interior without one) baked for local lights as `spec` asks, written to
/// `output` and reported; one bake, or one of a batch.
fn bake_local_one(
    spec: &BakeSpec,
    mesh: &Option<PathBuf>,
    output: &Path,
    device: &Device,
    progress: &BarProgress,
) -> Result<()> {
    // --lightmap and --preview are refused above, so this checks the .glb alone.
    check_bake_outputs(spec, None, mesh, output, &[])?;
    let scene = match mesh {
        Some(path) => load_mesh(path)?,
        None => scene::builtin::interior_scene(),
    };
    let baker = device.get()?;
    let backend = backend_for(baker.as_ref(), Chunking::default());
    let (baked, report) = pipeline::run_local(spec, scene, backend.as_ref(), progress)?;
    progress.finish();
    glb::local::write_local_glb(output, &baked)?;
    print_local_report(&local_name(mesh), &report, output);
    if report.depth_bytes > report.depth_bytes_uncompressed {
        eprintln!("{}", depth_maps_note(&report, &baked.options));
    }
    Ok(())
}

/// What to tell a user whose compressed depth maps take more than the maps: how many clusters
/// would take no more.
fn depth_maps_note(report: &local::LocalReport, options: &LocalOptions) -> String {
    let mb = |bytes: usize| bytes as f64 / 1e6;
    let (clusters, components) = (options.depth_clusters, options.depth_components);
    let cells = (options.grid_side * options.grid_side) as usize;
    let fewer =
        match local::depth_clusters_within_maps(report.receivers, cells, components as usize) {
            Some(fit) => format!("--depth-compress {fit}x{components} or fewer clusters take less"),
            None => "fewer components take less".to_string(),
        };
    format!(
        "note: the compressed depth maps take {:.1} MB, more than the {:.1} MB of the maps: \
         {} receivers are few for {clusters} clusters of {components} components ({fewer})",
        mb(report.depth_bytes),
        mb(report.depth_bytes_uncompressed),
        report.receivers
    )
}

/// Local lights, [`bake_local_one`] of each mesh of a batch.
struct LocalBake<'a> {
    args: &'a BakeArgs,
}

impl MeshBake for LocalBake<'_> {
    fn spec(&self, mesh: &Option<PathBuf>) -> Result<BakeSpec> {
        local_spec(self.args, mesh)
    }

    fn bake(
        &self,
        spec: &BakeSpec,
        mesh: &Option<PathBuf>,
        output: PathBuf,
        device: &Device,
        progress: &BarProgress,
    ) -> Result<()> {
        bake_local_one(spec, mesh, &output, device, progress)
    }
}

fn local_name(mesh: &Option<PathBuf>) -> String {
    match mesh {
        Some(path) => stem(path),
        None => "interior".to_string(),
    }
}

/// Refuses what a local-lights bake cannot run as (the spec refuses what it cannot compute).
fn check_local_flags(args: &BakeArgs) -> Result<()> {
    if let Some(limit) = args.memory_limit {
        // Measured under a counting allocator: 51 MB for the bunny's 1,839 receivers, 301 MB
        // for the built-in interior's 13,118, 422 MB for dragon_vrip_res3's 22,982.
        return Err(Error::Options(format!(
            "--memory-limit {}: a local-lights bake holds the example lights' bounced light, \
             its gather matrix and depth maps for every receiver at once (about 20 kB a \
             receiver at the defaults), so it does not stream; bake without a limit",
            format_bytes(limit)
        )));
    }
    let refused = [
        (args.preview.is_some(), "--preview"),
        (args.shard.is_some(), "--shard"),
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

/// `info` of a local-lights bake.
pub(crate) fn print_local_info(path: &Path) -> Result<()> {
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
