//! Size against error of clustered-PCA compression (docs/performance.md): bakes a mesh once,
//! compresses its transfer at a grid of cluster and component counts, and prints for each the
//! bytes (against float32 RGB), the time, the coefficient error and the relit-radiance error
//! under every environment map in tests/data.
//!
//! `cargo run --release --example cpca_curve [MESH]` (default: dragon_vrip_res3).

use std::path::PathBuf;
use std::time::Instant;

use prt_gpu::bake::{bake, Backend, BakeOptions, NoProgress};
use prt_gpu::compress::{compress, relative_error, relit_error, uncompressed_bytes, CpcaOptions};

fn main() -> prt_gpu::Result<()> {
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let mesh = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| data.join("dragon_vrip_res3.ply.gz"));
    let (baked, _) = bake(
        prt_gpu::scene::load(&mesh)?,
        &BakeOptions::default(),
        &Backend::Cpu,
        &NoProgress,
    )?;
    let maps = ["studio.exr", "sunrise.exr"];
    let lights = maps
        .iter()
        .map(|m| prt_gpu::light::load(&data.join(m), baked.transfer.bands, None, false))
        .collect::<prt_gpu::Result<Vec<_>>>()?;
    let full = uncompressed_bytes(&baked.transfer);
    println!(
        "{}: {} vertices, {} bands, {} channels, {full} bytes as float32",
        mesh.file_name()
            .map_or("mesh".into(), |n| n.to_string_lossy()),
        baked.transfer.vertex_count,
        baked.transfer.bands,
        baked.transfer.channels
    );
    println!(
        "| clusters x components | bytes | smaller | seconds | coefficient error | {} |",
        maps.join(" | ")
    );
    println!("|---|---|---|---|---|{}", "---|".repeat(maps.len()));
    for (clusters, components) in [
        (16, 4),
        (64, 4),
        (256, 4),
        (16, 8),
        (64, 8),
        (256, 8),
        (64, 16),
    ] {
        let started = Instant::now();
        let options = CpcaOptions {
            clusters,
            components,
            ..CpcaOptions::default()
        };
        let cpca = compress(&baked.transfer, &options)?;
        let seconds = started.elapsed().as_secs_f64();
        let relit: Vec<String> = lights
            .iter()
            .map(|l| {
                relit_error(&baked.transfer, &cpca, &l.light).map(|e| format!("{:.2}%", 100.0 * e))
            })
            .collect::<prt_gpu::Result<_>>()?;
        println!(
            "| {clusters} x {components} | {} | {:.1}x | {seconds:.2} | {:.2}% | {} |",
            cpca.byte_size(),
            full as f64 / cpca.byte_size() as f64,
            100.0 * relative_error(&baked.transfer, &cpca),
            relit.join(" | ")
        );
    }
    Ok(())
}
