//! `prt-gpu bake --mode local`: what it refuses before the spec does, and `info` of its file.
//! The bake and its report are `bake`'s, like every mode's.

use std::path::Path;

use super::bake::BakeArgs;
use prt_gpu::{glb, Error, Result};

/// Refuses what a local-lights bake cannot run as (the spec refuses what it cannot compute,
/// and `pipeline::plan_memory` a memory limit).
pub(crate) fn check_local_flags(args: &BakeArgs) -> Result<()> {
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
