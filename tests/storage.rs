//! Lean storage: one channel where one suffices relights to the radiance of RGB storage, goes
//! through the file and its readers intact, and is refused where it does not apply.

mod common;

use glam::Vec3;
use prt_gpu::bake::{bake, Backend, BakeOptions, BakedMesh, Mode, NoProgress, Storage};
use prt_gpu::glb::{read_glb, write_glb};
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
    bake(
        builtin::default_scene(),
        &options,
        &Backend::Cpu,
        &NoProgress,
    )
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
        assert_eq!((lean.transfer.channels, lean.metadata.channels), (1, 1));
        assert!(lean.metadata.albedo_free && !rgb.metadata.albedo_free);
        assert_eq!(3 * lean.transfer.coeffs.len(), rgb.transfer.coeffs.len());
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
    assert_eq!(lean.transfer.channels, 1);
    assert!(
        !lean.metadata.albedo_free,
        "bounced light is not one albedo times anything"
    );
    assert_same_radiance(&rgb, &lean, "interreflected, grey");
    // Colours bleed between surfaces: RGB stays.
    let coloured = baked(Mode::Interreflected, Storage::Lean, None);
    assert_eq!(coloured.transfer.channels, 3);
}

#[test]
fn lean_files_round_trip_and_validate() {
    let lean = baked(Mode::Shadowed, Storage::Lean, None);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lean.glb");
    write_glb(&path, &lean).unwrap();
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
            "-o",
        ])
        .arg(std::env::temp_dir().join("never-written-lean.glb"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("--storage lean"),
        "{stderr}"
    );
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
}
