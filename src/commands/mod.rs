//! The commands of the `prt-gpu` command line, a file each: their options, the calls into the
//! library, and the lines they report.

use std::path::PathBuf;

use prt_gpu::bake::Mode;
use prt_gpu::{scene, Error, Result};

mod args;
mod bake;
mod chart;
mod info;
mod light;
mod local;
mod progress;
mod render;
mod shard;
mod view;

pub(crate) use bake::BakeArgs;
pub(crate) use chart::{run_bench, run_chart, BenchArgs, ChartArgs};
pub(crate) use info::{run_devices, run_info};
pub(crate) use light::{run_light, LightArgs};
pub(crate) use progress::bars;
pub(crate) use render::{run_render, RenderArgs};
pub(crate) use shard::{run_merge, MergeArgs};
pub(crate) use view::{run_export_x3d, run_view, ExportCommand, ViewArgs};

/// `prt-gpu bake`: a shard, a batch, or one mesh, for distant light or lights inside the scene.
pub(crate) fn run_bake(args: BakeArgs) -> Result<()> {
    if args.transfer.mode == Mode::Local {
        local::check_local_flags(&args)?;
    }
    let meshes: Vec<PathBuf> = scene::batch::mesh_files(&args.meshes)?;
    if let Some(shard) = args.shard {
        return match meshes.as_slice() {
            [_, _, ..] => Err(Error::Options("--shard bakes one mesh, not a batch".into())),
            _ => shard::run_shard(&args, &meshes.first().cloned(), shard),
        };
    }
    if meshes.len() > 1 || args.out_dir.is_some() {
        return bake::run_batch(&args, &meshes);
    }
    bake::run_one(&args, meshes.first().cloned())
}
