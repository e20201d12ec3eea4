//! `prt-gpu info` and `prt-gpu devices`: what a file holds, which adapters there are.

use std::path::Path;

use super::local::print_local_info;
use prt_gpu::bake::BakeMetadata;
use prt_gpu::device;
use prt_gpu::glb::Precision;
use prt_gpu::{glb, Error, Result};

pub(crate) fn run_devices() -> Result<()> {
    device::check_backend_variable()?;
    let adapters = device::list_adapters();
    if adapters.is_empty() {
        println!("no GPU adapters (bakes run on the CPU backend)");
        return Ok(());
    }
    for (i, a) in adapters.iter().enumerate() {
        println!("{i}: {}", a.name);
        println!(
            "   backend {:?}, type {:?}{}",
            a.backend,
            a.device_type,
            if a.is_software() { " (software)" } else { "" }
        );
        println!("   driver {}", a.driver);
        println!(
            "   max storage binding {} MiB, max buffer {} MiB, max workgroups per dimension {}, \
             max invocations per workgroup {}",
            a.max_storage_buffer_binding_size >> 20,
            a.max_buffer_size >> 20,
            a.max_compute_workgroups_per_dimension,
            a.max_compute_invocations_per_workgroup
        );
    }
    Ok(())
}

/// Prints a baked file's description; a reader that stops early (`| head`) ends it quietly.
/// What a baked file (`read`) holds beside its transfer, one line each: probes, the subsurface
/// medium its transfer was baked in, zonal transfer.
fn beside_the_transfer(read: &glb::ReadBack, metadata: &BakeMetadata) -> Vec<String> {
    let mut lines = Vec::new();
    if let Some(probes) = &read.probes {
        lines.push(format!("probes:       {}", probes.describe()));
    }
    if let Some(subsurface) = &metadata.subsurface {
        lines.push(format!(
            "subsurface:   {}; followed {:.4} units",
            subsurface.describe(),
            subsurface.reach
        ));
    }
    if let Some(zonal) = &read.zonal {
        lines.push(format!(
            "zonal:        {} bands x {} channel(s) about the {} axis (_PRT_ZH_*)",
            zonal.bands(),
            zonal.channels(),
            zonal.axis().name()
        ));
    }
    lines
}

pub(crate) fn run_info(path: &Path) -> Result<()> {
    use std::io::Write;
    let (local, scene) = {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        (
            glb::local::is_local_file(&bytes),
            glb::is_scene_file(&bytes),
        )
    };
    if local {
        return print_local_info(path);
    }
    let albedo = match scene {
        true => "the material's base colour",
        false => "COLOR_0",
    };
    // Read whole, as render and view read it, so that a file they would refuse is refused
    // here too rather than described.
    let read = glb::read_back(path)?;
    let mut lines: Vec<String> = Vec::new();
    let (metadata, vertices, triangles) = glb::read_metadata(path)?;
    lines.push(format!("file:         {}", path.display()));
    lines.push(format!("vertices:     {vertices}"));
    lines.push(format!("triangles:    {triangles}"));
    lines.push(format!("mode:         {}", metadata.mode.name()));
    lines.push(format!(
        "bands:        {} ({} coefficients per channel)",
        metadata.bands,
        metadata.bands * metadata.bands
    ));
    lines.push(format!(
        "channels:     {}{}",
        metadata.channels,
        if metadata.albedo_free {
            format!(" (albedo-free: radiance = {albedo} x transfer . light)")
        } else {
            String::new()
        }
    ));
    lines.push(format!(
        "samples:      {} ({})",
        metadata.samples, metadata.sampling
    ));
    lines.push(format!("seed:         {}", metadata.seed));
    lines.push(format!("bounces:      {}", metadata.bounces));
    match metadata.fit_points {
        Some(points) => lines.push(format!(
            "fit:          {} ({points} surface points)",
            metadata.fit.name()
        )),
        None => lines.push(format!("fit:          {}", metadata.fit.name())),
    }
    let references = glb::read_references(path)?;
    if references.precision == Precision::F16 {
        lines.push("precision:    f16 (IEEE half floats, named by extras.prt)".to_string());
    }
    if let Some(lightmap) = references.lightmap {
        lines.push(format!(
            "lightmap:     {}x{} texels in {} (TEXCOORD_{})",
            lightmap.width, lightmap.height, lightmap.uri, lightmap.texcoord
        ));
    }
    if let Some(cpca) = references.cpca {
        lines.push(format!(
            "compressed:   CPCA, {} clusters x {} components",
            cpca.clusters, cpca.components
        ));
    }
    lines.extend(beside_the_transfer(&read, &metadata));
    lines.push(format!("backend:      {}", metadata.backend));
    lines.push(format!(
        "made by:      {} {}",
        metadata.tool, metadata.tool_version
    ));
    lines.push(format!("sh basis:     {}", metadata.sh_convention));
    lines.push(format!("radiometry:   {}", metadata.radiometry));
    let mut out = std::io::stdout().lock();
    for line in lines {
        if writeln!(out, "{line}").is_err() {
            break;
        }
    }
    Ok(())
}
