//! Lean storage: one channel where one suffices relights to the radiance of RGB storage, goes
//! through the file and its readers intact, and is refused where it does not apply.

mod common;

use glam::Vec3;
use prt_gpu::bake::{bake, BakeOptions, BakedMesh, CpuBackend, Mode, NoProgress, Storage};
use prt_gpu::glb::{read_glb, write_glb, Stored};
use prt_gpu::light::preview_light;
use prt_gpu::render::relight_baked;
use prt_gpu::scene::builtin;

fn baked(mode: Mode, storage: Storage, albedo: Option<Vec3>) -> BakedMesh {
    let options = BakeOptions {
        samples: 64,
        mode,
        storage,
        albedo,
        bounces: 2,
        ..BakeOptions::default()
    };
    bake(builtin::default_scene(), &options, &CpuBackend, &NoProgress)
        .unwrap()
        .0
}

/// Radiance of both under the preview light agrees to float rounding (the albedo multiplies
/// before or after the sum).
fn assert_same_radiance(rgb: &BakedMesh, lean: &BakedMesh, what: &str) {
    let light = preview_light(4).unwrap();
    let (a, b) = (
        relight_baked(rgb, &light).unwrap(),
        relight_baked(lean, &light).unwrap(),
    );
    assert_eq!(a.len(), b.len());
    let scale = a.iter().flatten().fold(0.0f32, |m, x| m.max(x.abs()));
    for (v, (x, y)) in a.iter().zip(&b).enumerate() {
        for c in 0..3 {
            assert!(
                (x[c] - y[c]).abs() <= 1e-5 * scale,
                "{what}: vertex {v}, channel {c}: rgb {}, lean {}",
                x[c],
                y[c]
            );
        }
    }
}

#[test]
fn direct_transfer_stored_once_relights_as_rgb_does() {
    // The built-in scene has a red wall: coloured albedo.
    for mode in [Mode::Shadowed, Mode::Unshadowed] {
        let (rgb, lean) = (
            baked(mode, Storage::Rgb, None),
            baked(mode, Storage::Lean, None),
        );
        assert_eq!((lean.transfer.channels(), lean.metadata.channels), (1, 1));
        assert!(lean.metadata.albedo_free && !rgb.metadata.albedo_free);
        assert_eq!(
            3 * lean.transfer.coeffs().len(),
            rgb.transfer.coeffs().len()
        );
        assert_same_radiance(&rgb, &lean, mode.name());
    }
}

#[test]
fn interreflected_transfer_drops_to_one_channel_only_when_every_albedo_is_grey() {
    let grey = Some(Vec3::splat(0.6));
    let (rgb, lean) = (
        baked(Mode::Interreflected, Storage::Rgb, grey),
        baked(Mode::Interreflected, Storage::Lean, grey),
    );
    assert_eq!(lean.transfer.channels(), 1);
    assert!(
        !lean.metadata.albedo_free,
        "bounced light is not one albedo times anything"
    );
    assert_same_radiance(&rgb, &lean, "interreflected, grey");
    // Colours bleed between surfaces: RGB stays.
    let coloured = baked(Mode::Interreflected, Storage::Lean, None);
    assert_eq!(coloured.transfer.channels(), 3);
}

#[test]
fn lean_files_round_trip_and_validate() {
    let lean = baked(Mode::Shadowed, Storage::Lean, None);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lean.glb");
    Stored::plain(&lean)
        .and_then(|stored| write_glb(&path, stored))
        .unwrap();
    let read = read_glb(&path).unwrap();
    assert_eq!(read, lean);
    if let Some(report) = common::validate_gltf(&path) {
        assert_eq!(report.num_errors, 0, "{}", report.listing());
    }
    // The README's numpy reader reads one channel.
    if let Some(out) = prt_gpu::testing::numpy_reader_output(&path) {
        assert_eq!(
            out["transfer"],
            serde_json::json!([lean.scene.vertex_count(), 1, 16])
        );
    }
    dir.close().unwrap();
}

#[test]
fn lean_storage_is_refused_where_it_does_not_apply() {
    let options = BakeOptions {
        storage: Storage::Lean,
        lightmap: Some(512),
        ..BakeOptions::default()
    };
    let error = options.validate().unwrap_err();
    assert!(error.to_string().contains("--storage lean"), "{error}");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_prt-gpu"))
        .args([
            "bake",
            concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/tests/data/gltf/BoxTextured.glb"
            ),
            "--storage",
            "lean",
            "--albedo",
            "0.5,0.5,0.5",
            "-o",
        ])
        .arg(std::env::temp_dir().join("never-written-lean.glb"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("--albedo with --storage lean"),
        "{stderr}"
    );
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
}

/// A glTF scene baked in place with lean storage, half floats or both: one `_PRT_*` channel
/// per primitive with the albedo left to the scene's materials, or the transfer as a half-float
/// view named in each primitive's `extras.prt`. Read back by `read_scene_glb`, lean relights to
/// the RGB bake's radiance and half floats hold the RGB bake's coefficients rounded to f16,
/// exactly; the Khronos validator passes every file and `info` says how it is stored.
#[test]
fn gltf_scenes_baked_in_place_store_lean_and_half_float_transfer() {
    use prt_gpu::glb::{rounded_to_f16, scene::read_scene_glb};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/gltf");
    for scene in ["BoxTextured.glb", "2CylinderEngine.glb"] {
        let input = format!("{data}/{scene}");
        let bake = |storage: &str, precision: &str| {
            let output = d.join(format!("{storage}-{precision}-{scene}"));
            let output_arg = output.display().to_string();
            let args = [
                "bake",
                &input,
                "--samples",
                "64",
                "--device",
                "cpu",
                "--storage",
                storage,
                "--precision",
                precision,
                "-o",
                &output_arg,
            ];
            let out = common::prt_gpu(&args, d);
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            if let Some(report) = common::validate_gltf(&output) {
                assert_eq!(report.num_errors, 0, "{}", report.listing());
            }
            let info = common::prt_gpu(&["info", &output_arg], d);
            let info = String::from_utf8_lossy(&info.stdout).to_string();
            assert_eq!(
                info.contains("precision:    f16"),
                precision == "f16",
                "{info}"
            );
            assert_eq!(
                info.contains("radiance = the material's base colour x"),
                storage == "lean",
                "{info}"
            );
            let bytes = std::fs::metadata(&output).unwrap().len();
            (read_scene_glb(&output).unwrap(), bytes)
        };
        let (rgb, rgb_bytes) = bake("rgb", "f32");
        let (lean, lean_bytes) = bake("lean", "f32");
        let (half, half_bytes) = bake("rgb", "f16");
        let (lean_half, lean_half_bytes) = bake("lean", "f16");
        assert_eq!((lean.transfer.channels(), rgb.transfer.channels()), (1, 3));
        assert!(lean.metadata.albedo_free);
        assert!(
            lean.scene.albedo.iter().any(|a| a.x != a.z),
            "{scene}: coloured"
        );
        assert_same_radiance(&rgb, &lean, scene);
        assert_eq!(half.transfer, rounded_to_f16(&rgb.transfer), "{scene}");
        assert_eq!(
            lean_half.transfer,
            rounded_to_f16(&lean.transfer),
            "{scene}"
        );
        assert!(
            lean_half_bytes < half_bytes && half_bytes < rgb_bytes,
            "{scene}"
        );
        assert!(
            lean_half_bytes < lean_bytes && lean_bytes < rgb_bytes,
            "{scene}"
        );
    }
}

/// Half-float files (`--precision f16`) hold every coefficient rounded to the nearest f16 and
/// nothing else: read back exactly so, by the library and by numpy; each coefficient within
/// 2^-11 of its value relative (above f16's normal range's floor), relit radiance within the
/// bound that implies; the Khronos validator passes the file; half the transfer's bytes.
#[test]
fn half_float_files_hold_the_rounded_transfer_within_its_bound() {
    use prt_gpu::glb::{rounded_to_f16, write_glb, Precision, Stored};
    let dir = tempfile::tempdir().unwrap();
    for (storage, mode) in [
        (Storage::Rgb, Mode::Interreflected),
        (Storage::Lean, Mode::Shadowed),
    ] {
        let baked = baked(mode, storage, None);
        let (full, half) = (dir.path().join("f32.glb"), dir.path().join("f16.glb"));
        Stored::plain(&baked)
            .and_then(|stored| write_glb(&full, stored))
            .unwrap();
        write_glb(&half, Stored::new(&baked, None, Precision::F16).unwrap()).unwrap();
        let read = read_glb(&half).unwrap();
        let rounded = rounded_to_f16(&baked.transfer);
        assert_eq!(
            read.transfer, rounded,
            "{storage:?}: not the rounded transfer"
        );
        assert_eq!(read.scene, baked.scene);
        for (x, r) in baked.transfer.coeffs().iter().zip(rounded.coeffs()) {
            // 2^-11 relative above the smallest normal half (2^-14); 2^-25 absolute below it.
            let bound = (x.abs() * 2f32.powi(-11)).max(2f32.powi(-25));
            assert!((r - x).abs() <= bound, "{x} stored as {r}");
        }
        // Relit, the error is at most 2^-11 of sum |t_k| |l_k| per vertex and channel.
        let light = preview_light(4).unwrap();
        let exact = relight_baked(&baked, &light).unwrap();
        let stored = relight_baked(&read, &light).unwrap();
        let n = 16;
        for (v, (e, s)) in exact.iter().zip(&stored).enumerate() {
            for c in 0..3 {
                let channel = if baked.transfer.channels() == 1 { 0 } else { c };
                let t = baked.transfer.vertex_channel(v, channel);
                let albedo = if storage == Storage::Lean {
                    baked.scene.albedo[v][c]
                } else {
                    1.0
                };
                let scale: f32 = (0..n).map(|k| t[k].abs() * light.coeffs[k][c].abs()).sum();
                let bound = albedo * (scale * 2f32.powi(-11) + 1e-6) + 1e-6;
                assert!(
                    (e[c] - s[c]).abs() <= bound,
                    "vertex {v}: {} against {}",
                    s[c],
                    e[c]
                );
            }
        }
        let bytes = |p: &std::path::Path| std::fs::metadata(p).unwrap().len() as usize;
        let transfer_bytes =
            baked.transfer.vertex_count() * baked.transfer.channels() as usize * 64;
        assert_eq!(
            bytes(&full) - bytes(&half),
            transfer_bytes / 2 + json_difference(&full, &half)
        );
        if let Some(report) = common::validate_gltf(&half) {
            assert_eq!(report.num_errors, 0, "{storage:?}: {report:?}");
        }
        if let Some(numpy) = prt_gpu::testing::numpy_reader_output(&half) {
            let last: Vec<f64> = numpy["last_vertex"]
                .as_array()
                .unwrap()
                .iter()
                .flat_map(|c| c.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()))
                .collect();
            let expected: Vec<f64> = (0..read.transfer.channels() as usize)
                .flat_map(|c| {
                    read.transfer
                        .vertex_channel(read.transfer.vertex_count() - 1, c)
                })
                .map(|&x| x as f64)
                .collect();
            assert_eq!(last.len(), expected.len());
            for (a, b) in last.iter().zip(&expected) {
                // The same float, printed by Python and parsed back.
                assert!(
                    (a - b).abs() <= 1e-12 * b.abs(),
                    "{storage:?}: numpy reads {a}, not {b}"
                );
            }
        }
    }
}

/// How much longer the f32 file's JSON chunk is (its transfer accessors) than the f16 file's.
fn json_difference(full: &std::path::Path, half: &std::path::Path) -> usize {
    let json_len = |p: &std::path::Path| {
        let bytes = std::fs::read(p).unwrap();
        u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize
    };
    json_len(full) - json_len(half)
}

#[test]
fn half_floats_are_refused_where_the_transfer_has_other_storage() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [&[&str]; 1] = [&["bake", "--precision", "f16", "--lightmap", "64"]];
    for args in cases {
        let mut all = args.to_vec();
        all.extend(["--device", "cpu", "--samples", "16", "-o", "out.glb"]);
        let out = common::prt_gpu(&all, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} baked");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains("--precision f16"), "{args:?}: {stderr}");
        assert!(prt_gpu::testing::entries(dir.path()).is_empty());
    }
}

/// `info` says a file's transfer is half floats.
#[test]
fn info_names_half_float_transfer() {
    let dir = tempfile::tempdir().unwrap();
    let bake = [
        "bake",
        "--device",
        "cpu",
        "--samples",
        "16",
        "--precision",
        "f16",
        "-o",
        "h.glb",
    ];
    assert!(common::prt_gpu(&bake, dir.path()).status.success());
    let info = common::prt_gpu(&["info", "h.glb"], dir.path());
    let stdout = String::from_utf8_lossy(&info.stdout);
    assert!(
        info.status.success(),
        "{}",
        String::from_utf8_lossy(&info.stderr)
    );
    assert!(stdout.contains("precision:    f16"), "{stdout}");
    let bake = ["bake", "--device", "cpu", "--samples", "16", "-o", "f.glb"];
    assert!(common::prt_gpu(&bake, dir.path()).status.success());
    let info = common::prt_gpu(&["info", "f.glb"], dir.path());
    assert!(!String::from_utf8_lossy(&info.stdout).contains("precision"));
}

/// A glTF scene baked in place with `--compress`: the clusters' means and bases once, each
/// primitive's clusters and weights in views its `extras.prt.cpca` names (the mesh's
/// `extras.prt.cpca` repeating its first primitive's, as the single-mesh recipe reads it). Read
/// back, every vertex holds the compressed form's reconstruction exactly, in float32 and half
/// floats, lean or RGB; numpy reads the first primitive alike; the Khronos validator passes.
#[test]
fn gltf_scenes_baked_in_place_store_compressed_transfer() {
    use prt_gpu::bake::DirectSource;
    use prt_gpu::glb::scene::read_scene_glb;
    use prt_gpu::precision::Precision;
    use prt_gpu::spec::{BakeSpec, Compression, Container, Layout};
    let dir = tempfile::tempdir().unwrap();
    let input = common::ENGINE_GLB;
    let (gltf, scene) = prt_gpu::scene::gltf::load(std::path::Path::new(input)).unwrap();
    let mut sizes = Vec::new();
    for (storage, precision) in [
        (Storage::Rgb, Precision::F32),
        (Storage::Lean, Precision::F16),
        (Storage::Rgb, Precision::F16),
    ] {
        let mut spec = BakeSpec {
            container: Container::GltfInPlace,
            ..BakeSpec::default()
        };
        spec.transfer.samples = 32;
        spec.storage.channels = storage;
        spec.storage.precision = precision;
        spec.storage.layout = Layout::Cpca(Compression::Shape {
            clusters: 16,
            components: 4,
        });
        let what = format!("{storage:?} {precision:?}");
        let source = DirectSource::Compute;
        let baked = prt_gpu::pipeline::run(
            &spec,
            scene.clone(),
            Some(&gltf),
            &CpuBackend,
            source,
            &NoProgress,
        )
        .unwrap();
        let path = dir.path().join(format!("{storage:?}-{precision:?}.glb"));
        prt_gpu::pipeline::write(&spec, &baked, Some(&gltf), &path).unwrap();
        let baked = baked.into_transfer().unwrap();
        sizes.push(std::fs::metadata(&path).unwrap().len());
        if let Some(report) = common::validate_gltf(&path) {
            assert_eq!(report.num_errors, 0, "{what}: {}", report.listing());
        }
        let info = common::prt_gpu(&["info", path.to_str().unwrap()], dir.path());
        let info = String::from_utf8_lossy(&info.stdout).to_string();
        assert!(
            info.contains("compressed:   CPCA, 16 clusters x 4 components"),
            "{what}: {info}"
        );
        let back = read_scene_glb(&path).unwrap();
        let reconstructed = baked.cpca.as_ref().expect("compressed").reconstruct();
        let map = &baked.report.vertex_map;
        for (v, &prepared) in map.iter().enumerate() {
            if prepared == prt_gpu::scene::prepare::DROPPED {
                continue;
            }
            for c in 0..back.transfer.channels() as usize {
                assert_eq!(
                    back.transfer.vertex_channel(v, c),
                    reconstructed.vertex_channel(prepared as usize, c),
                    "{what}: vertex {v}, channel {c}"
                );
            }
        }
        // numpy's recipe reads the first primitive: its vertices, reconstructed alike.
        if let Some(read) = prt_gpu::testing::compressed_reader_output(&path) {
            // Mesh 0's extras describe its first placement's first primitive.
            let shown = gltf.instances.iter().find(|i| i.mesh == 0).unwrap();
            let first = shown.primitives[0];
            let channels = back.transfer.channels() as usize;
            assert_eq!(
                read["transfer"],
                serde_json::json!([first.count, channels, 16])
            );
            let last = first.first + first.count - 1;
            for c in 0..channels {
                for (k, &ours) in back.transfer.vertex_channel(last, c).iter().enumerate() {
                    let theirs = read["last_vertex"][c][k].as_f64().unwrap();
                    assert!((theirs - ours as f64).abs() <= 1e-5 * (ours.abs() as f64).max(1.0));
                }
            }
        }
    }
    // Lean half floats are the smallest; every form is well under the plain RGB transfer's 18 MB.
    assert!(sizes[1] < sizes[2] && sizes[2] < sizes[0], "{sizes:?}");
}
