//! Size against error of clustered-PCA compression (docs/performance.md): bakes a mesh once
//! with RGB transfer and once lean (one albedo-free channel), compresses each at a grid of
//! cluster and component counts, and prints for each the bytes the baked file stores (against
//! float32 RGB), the time, the coefficient error (against the transfer compressed) and the
//! relit-radiance error under every environment map in tests/data against the uncompressed
//! float32 RGB transfer (lean rows relit, then times the vertex albedo, as `render` does).
//! RGB rows store float32; lean rows store half floats (`--precision f16`), their errors those
//! of the rounded form.
//!
//! `cargo run --release --example cpca_curve [MESH]` (default: dragon_vrip_res3).

use std::path::PathBuf;
use std::time::Instant;

use prt_gpu::bake::{bake, BakeOptions, BakedMesh, CpuBackend, NoProgress, Storage};
use prt_gpu::compress::{
    compress, radiance_error, relative_error, uncompressed_bytes, CpcaOptions, Points,
};
use prt_gpu::light::ShLight;
use prt_gpu::precision::Precision;
use prt_gpu::render::{apply_albedo, relight};

fn main() -> prt_gpu::Result<()> {
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let mesh = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| data.join("dragon_vrip_res3.ply.gz"));
    let baked = |storage| {
        let options = BakeOptions {
            storage,
            ..BakeOptions::default()
        };
        let scene = prt_gpu::scene::load(&mesh)?;
        bake(scene, &options, &CpuBackend, &NoProgress).map(|(baked, _)| baked)
    };
    let rgb_baked = baked(Storage::Rgb)?;
    let rgb = &rgb_baked.transfer;
    let maps = ["studio.exr", "sunrise.exr"];
    let lights = maps
        .iter()
        .map(|m| prt_gpu::light::load(&data.join(m), rgb.bands(), None, false).map(|l| l.light))
        .collect::<prt_gpu::Result<Vec<_>>>()?;
    let full = uncompressed_bytes(&Points::of_transfer(rgb));
    let references = lights
        .iter()
        .map(|l| relight(rgb, l))
        .collect::<prt_gpu::Result<Vec<_>>>()?;
    println!(
        "{}: {} vertices, {} bands, {full} bytes as float32 RGB",
        mesh.file_name()
            .map_or("mesh".into(), |n| n.to_string_lossy()),
        rgb.vertex_count(),
        rgb.bands(),
    );
    println!(
        "| storage | clusters x components | bytes | smaller | seconds | coefficient error | {} |",
        maps.join(" | ")
    );
    println!("|---|---|---|---|---|---|{}", "---|".repeat(maps.len()));
    let rgb_shapes = [
        (16, 4),
        (64, 4),
        (256, 4),
        (16, 8),
        (64, 8),
        (256, 8),
        (64, 16),
    ];
    for shape in rgb_shapes {
        row(
            &rgb_baked,
            shape,
            Precision::F32,
            full,
            (&lights, &references),
        )?;
    }
    let lean = baked(Storage::Lean)?;
    let lean_shapes = [(64, 8), (256, 6), (256, 8), (384, 8), (512, 7), (512, 8)];
    for shape in lean_shapes {
        row(&lean, shape, Precision::F16, full, (&lights, &references))?;
    }
    Ok(())
}

/// One row of the table: `baked`'s transfer compressed to `shape` and stored at `precision`;
/// `references` is the float32 RGB radiance under each of `lights`.
fn row(
    baked: &BakedMesh,
    (clusters, components): (u32, u32),
    precision: Precision,
    full: usize,
    (lights, references): (&[ShLight], &[Vec<[f32; 3]>]),
) -> prt_gpu::Result<()> {
    let transfer = &baked.transfer;
    let started = Instant::now();
    let options = CpcaOptions {
        clusters,
        components,
        ..CpcaOptions::default()
    };
    let cpca = compress(transfer, &options)?.rounded(precision);
    let seconds = started.elapsed().as_secs_f64();
    let relit: Vec<String> = lights
        .iter()
        .zip(references)
        .map(|(l, reference)| {
            let radiance = apply_albedo(baked, cpca.relight(l)?);
            Ok(format!(
                "{:.2}%",
                100.0 * radiance_error(reference, &radiance)
            ))
        })
        .collect::<prt_gpu::Result<_>>()?;
    let storage = match (transfer.channels(), precision) {
        (1, Precision::F16) => "lean, f16",
        (1, Precision::F32) => "lean, f32",
        (_, Precision::F16) => "RGB, f16",
        (_, Precision::F32) => "RGB, f32",
    };
    let bytes = cpca.byte_size(precision);
    println!(
        "| {storage} | {clusters} x {components} | {bytes} | {:.1}x | {seconds:.2} | {:.2}% | {} |",
        full as f64 / bytes as f64,
        100.0 * relative_error(transfer, &cpca),
        relit.join(" | ")
    );
    Ok(())
}
