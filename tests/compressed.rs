//! Compressed transfer in the baked file: written, validated by the Khronos validator, read back
//! bit for bit, smaller, deterministic, and refused cleanly where it does not apply.

mod common;

use std::path::Path;

use common::prt_gpu;
use prt_gpu::bake::{bake, BakeOptions, CpuBackend, NoProgress};
use prt_gpu::compress::{compress, CpcaOptions};
use prt_gpu::glb::{read_glb, read_glb_compressed, write_glb, Stored};
use prt_gpu::precision::Precision;
use prt_gpu::testing::entries;

fn bunny() -> prt_gpu::scene::Scene {
    prt_gpu::scene::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/bunny.obj"
    )))
    .unwrap()
}

#[test]
fn compressed_files_round_trip_and_validate() {
    let options = BakeOptions {
        samples: 64,
        ..BakeOptions::default()
    };
    let (baked, _) = bake(bunny(), &options, &CpuBackend, &NoProgress).unwrap();
    let cpca = compress(
        &baked.transfer,
        &CpcaOptions {
            clusters: 16,
            components: 4,
            ..CpcaOptions::default()
        },
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (small, full) = (dir.path().join("small.glb"), dir.path().join("full.glb"));
    write_glb(
        &small,
        Stored::new(&baked, Some(&cpca), Precision::F32).unwrap(),
    )
    .unwrap();
    Stored::plain(&baked)
        .and_then(|stored| write_glb(&full, stored))
        .unwrap();
    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    // The mesh itself (positions, normals, albedo, indices) is the same in both.
    assert!(
        2 * size(&small) < size(&full),
        "{} vs {}",
        size(&small),
        size(&full)
    );

    let (read, read_cpca) = read_glb_compressed(&small).unwrap();
    assert_eq!(
        read_cpca.as_ref(),
        Some(&cpca),
        "compressed form changed on the way"
    );
    assert_eq!(read.transfer, cpca.reconstruct());
    assert_eq!(read.scene, baked.scene);
    assert_eq!(read.metadata, baked.metadata);
    // Every reader of the file sees the reconstruction.
    assert_eq!(read_glb(&small).unwrap().transfer, cpca.reconstruct());
    if let Some(report) = common::validate_gltf(&small) {
        assert_eq!(report.num_errors, 0, "{}", report.listing());
    }
    // The README's numpy recipe reconstructs the same transfer.
    if let Some(out) = prt_gpu::testing::compressed_reader_output(&small) {
        let v = baked.scene.vertex_count();
        assert_eq!(out["transfer"], serde_json::json!([v, 3, 16]));
        let reconstructed = cpca.reconstruct();
        for c in 0..3 {
            for (k, &x) in reconstructed.vertex_channel(v - 1, c).iter().enumerate() {
                let theirs = out["last_vertex"][c][k].as_f64().unwrap();
                let close = (theirs - x as f64).abs() <= 1e-5 * (x as f64).abs().max(1e-3);
                assert!(close, "channel {c}, k = {k}: numpy {theirs}, ours {x}");
            }
        }
    }
    dir.close().unwrap();
}

/// The length of a .glb's BIN chunk.
fn bin_length(path: &Path) -> i64 {
    let bytes = std::fs::read(path).unwrap();
    let n = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    u32::from_le_bytes(bytes[20 + n..24 + n].try_into().unwrap()) as i64
}

/// The byte length of buffer view `index` of a .glb (JSON chunk only).
fn view_length(path: &Path, index: usize) -> u64 {
    let bytes = std::fs::read(path).unwrap();
    let n = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + n]).unwrap();
    json["bufferViews"][index]["byteLength"].as_u64().unwrap()
}

#[test]
fn half_float_compressed_files_round_trip_validate_and_shrink() {
    let options = BakeOptions {
        samples: 64,
        storage: prt_gpu::bake::Storage::Lean,
        ..BakeOptions::default()
    };
    let (baked, _) = bake(bunny(), &options, &CpuBackend, &NoProgress).unwrap();
    let v = baked.scene.vertex_count();
    let dir = tempfile::tempdir().unwrap();
    // 16 clusters take one byte an index; 300 take two.
    for (clusters, index_width) in [(16u32, 1u64), (300, 2)] {
        let cpca = compress(
            &baked.transfer,
            &CpcaOptions {
                clusters,
                components: 4,
                ..CpcaOptions::default()
            },
        )
        .unwrap();
        let (half, full) = (dir.path().join("half.glb"), dir.path().join("full.glb"));
        write_glb(
            &half,
            Stored::new(&baked, Some(&cpca), Precision::F16).unwrap(),
        )
        .unwrap();
        write_glb(
            &full,
            Stored::new(&baked, Some(&cpca), Precision::F32).unwrap(),
        )
        .unwrap();

        let (read, read_cpca) = read_glb_compressed(&half).unwrap();
        let stored = cpca.rounded(Precision::F16);
        assert_eq!(read_cpca.as_ref(), Some(&stored), "{clusters} clusters");
        assert_eq!(read.transfer, stored.reconstruct());
        assert_eq!(read.metadata, baked.metadata);
        let extras = prt_gpu::glb::read_references(&half).unwrap();
        assert_eq!(extras.precision, Precision::F16);
        let cpca_extras = extras.cpca.unwrap();
        assert_eq!(cpca_extras.assignment_bytes, Some(index_width as usize));
        assert_eq!(
            view_length(&half, cpca_extras.assignment_buffer_view),
            index_width * v as u64
        );
        assert_eq!(
            view_length(&half, cpca_extras.weights_buffer_view),
            2 * 4 * v as u64
        );
        // The transfer's bytes, not the mesh's, shrink: by the stated formula, up to the
        // padding that keeps each view 4-byte aligned.
        let saved = (cpca.byte_size(Precision::F32) - cpca.byte_size(Precision::F16)) as i64;
        let padding = bin_length(&half) - (bin_length(&full) - saved);
        assert!((0..8).contains(&padding), "padding {padding}");

        if let Some(report) = common::validate_gltf(&half) {
            assert_eq!(report.num_errors, 0, "{}", report.listing());
        }
        if let Some(out) = prt_gpu::testing::compressed_reader_output(&half) {
            assert_eq!(out["transfer"], serde_json::json!([v, 1, 16]));
            let reconstructed = stored.reconstruct();
            for (k, &x) in reconstructed.vertex_channel(v - 1, 0).iter().enumerate() {
                let theirs = out["last_vertex"][0][k].as_f64().unwrap();
                let close = (theirs - x as f64).abs() <= 1e-5 * (x as f64).abs().max(1e-3);
                assert!(close, "k = {k}: numpy {theirs}, ours {x}");
            }
        }
    }
    dir.close().unwrap();
}

#[test]
fn bake_compress_reports_writes_and_renders() {
    let dir = tempfile::tempdir().unwrap();
    let bunny_path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");
    // Each precision twice: the same bake compresses to the same bytes.
    for (name, precision) in [("a", "f32"), ("b", "f32"), ("h1", "f16"), ("h2", "f16")] {
        let output = format!("{name}.glb");
        let args = [
            "bake",
            bunny_path,
            "--samples",
            "64",
            "--compress",
            "8x4",
            "--precision",
            precision,
            "--device",
            "cpu",
            "-o",
            &output,
        ];
        let out = prt_gpu(&args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert!(
            stderr.contains("compressed: 8 clusters x 4 components") && stderr.contains("smaller"),
            "{stderr}"
        );
        assert_eq!(
            stderr.contains("bytes as half floats"),
            precision == "f16",
            "{stderr}"
        );
    }
    let read = |n: &str| std::fs::read(dir.path().join(n)).unwrap();
    assert_eq!(read("a.glb"), read("b.glb"));
    assert_eq!(read("h1.glb"), read("h2.glb"));
    assert!(read("h1.glb").len() < read("a.glb").len());
    let info = prt_gpu(&["info", "h1.glb"], dir.path());
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(text.contains("precision:    f16"), "{text}");
    let info = prt_gpu(&["info", "a.glb"], dir.path());
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        text.contains("compressed:   CPCA, 8 clusters x 4 components"),
        "{text}"
    );
    if !prt_gpu::device::list_adapters().is_empty() {
        let out = prt_gpu(
            &[
                "render", "a.glb", "--width", "64", "--height", "48", "-o", "a.png",
            ],
            dir.path(),
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    dir.close().unwrap();
}

#[test]
fn bad_compression_requests_fail_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    for (args, expect) in [
        (vec!["--compress", "8"], "CLUSTERSxCOMPONENTS"),
        (vec!["--compress", "0x4"], "cluster"),
        (vec!["--compress", "8x4", "--lightmap", "512"], "--compress"),
        (vec!["--compress", "auto:-1"], "--compress auto:-1"),
        (vec!["--compress", "auto:x"], "auto:ERROR"),
    ] {
        let mut all = vec!["bake", "--samples", "16", "--device", "cpu", "-o", "o.glb"];
        all.extend(args.iter());
        let out = prt_gpu(&all, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains(expect), "{args:?}: {stderr}");
        assert!(entries(dir.path()).is_empty(), "{args:?} left files");
    }
    dir.close().unwrap();
}

#[test]
fn an_error_target_chooses_a_shape_that_meets_it() {
    let dir = tempfile::tempdir().unwrap();
    let bunny_path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");
    let out = prt_gpu(
        &[
            "bake",
            bunny_path,
            "--samples",
            "64",
            "--compress",
            "auto:0.05",
            "--device",
            "cpu",
            "-o",
            "auto.glb",
        ],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    // "compressed: K clusters x M components ...; coefficient error E%, ..."
    let error: f64 = common::number_after(&stderr, "coefficient error ", '%')
        .unwrap_or_else(|| panic!("no error reported: {stderr}"));
    assert!(error <= 5.0, "{stderr}");
    // Against the same bake uncompressed, the stored form meets the target.
    let out = prt_gpu(
        &[
            "bake",
            bunny_path,
            "--samples",
            "64",
            "--device",
            "cpu",
            "-o",
            "full.glb",
        ],
        dir.path(),
    );
    assert!(out.status.success());
    let full = read_glb(&dir.path().join("full.glb")).unwrap();
    let (_, cpca) = read_glb_compressed(&dir.path().join("auto.glb")).unwrap();
    let cpca = cpca.expect("stored compressed");
    let measured = prt_gpu::compress::relative_error(&full.transfer, &cpca);
    assert!(
        measured <= 0.05,
        "coefficient error {measured} over the 0.05 asked for"
    );
    dir.close().unwrap();
}
