//! `bake` of several meshes: one device, one line per mesh and a total.

use super::*;

/// The checked spec of `mesh`'s bake (`None`: the rules that hold for any mesh).
fn checked_spec(args: &BakeArgs, mesh: &Option<PathBuf>) -> Result<BakeSpec> {
    let spec = bake_spec(args, mesh)?;
    spec.validate()?;
    Ok(spec)
}

/// `bake` of several meshes, each as [`bake_one`] bakes it alone: one device, one line per mesh
/// and a total; a mesh that fails is reported and the others still bake, the exit failing at
/// the end.
pub(crate) fn run_batch(args: &BakeArgs, meshes: &[PathBuf]) -> Result<()> {
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
    let inputs: Vec<&Path> = meshes.iter().map(PathBuf::as_path).collect();
    for output in &outputs {
        let output = fs::Output {
            option: "--out-dir",
            path: output,
        };
        fs::check_outputs(&[output], &inputs)?;
    }
    // The rules that hold for any mesh, checked once; each mesh's container is checked as it
    // bakes.
    checked_spec(args, &None)?;
    check_chunking(args)?;
    std::fs::create_dir_all(&out_dir).map_err(|e| Error::io(&out_dir, e))?;
    let device = Device::new(|| open_backend(args.device, args.adapter.as_deref()));
    let execution = Execution::of(args);
    let started = std::time::Instant::now();
    let mut failed = Vec::new();
    let weights = scene::batch::work_weights(meshes);
    let overall = batch_bar(weights.iter().sum());
    for (k, (mesh, output)) in meshes.iter().zip(outputs).enumerate() {
        overall.set_message(format!("batch {}/{}", k + 1, meshes.len()));
        let progress = BarProgress::in_batch(k + 1, meshes.len(), &stem(mesh));
        let mesh = Some(mesh.clone());
        let output = Some(output);
        let baked = checked_spec(args, &mesh)
            .and_then(|spec| bake_one(&spec, &execution, &mesh, output, &device, None, &progress));
        if let Err(error) = baked {
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
